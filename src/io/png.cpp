// 8-bit sRGB previews (see gdr/io/png.h).

#include "gdr/io/png.h"

#include "file_target.h"

#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace gdr {

float linear_to_srgb(float v) {
    // Clamping keeps pow() away from negative inputs (NaN) for callers that
    // pass slightly out-of-range values.
    v = std::clamp(v, 0.f, 1.f);
    return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.f / 2.4f) - 0.055f;
}

float srgb_to_linear(float v) {
    v = std::clamp(v, 0.f, 1.f);
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

namespace {

/// 8-bit code of a value in [0,1]; NaN maps to 0 (std::clamp would keep it).
uint8_t to_byte(float v) {
    if (!(v > 0.f)) return 0;
    if (v >= 1.f) return 255;
    return uint8_t(v * 255.f + 0.5f);
}

}  // namespace

std::vector<uint8_t> preview_bytes(const Image& linear, float exposure) {
    const int w = linear.width(), h = linear.height(), c = linear.channels();
    // 2-channel images (e.g. motion) are shown as R, G with B = 0.
    const int out_c = c == 2 ? 3 : c;
    const float scale = std::exp2(exposure);
    std::vector<uint8_t> bytes(size_t(w) * h * out_c, 0);
    for (size_t p = 0; p < size_t(w) * h; ++p) {
        const float* src = linear.data() + p * c;
        uint8_t* dst = bytes.data() + p * out_c;
        for (int k = 0; k < c; ++k) {
            // Alpha is coverage, not radiance: neither exposed nor encoded.
            const bool alpha = c == 4 && k == 3;
            dst[k] = to_byte(alpha ? src[k] : linear_to_srgb(src[k] * scale));
        }
    }
    return bytes;
}

void write_png_preview(const std::string& path, const Image& linear, float exposure) {
    if (linear.empty()) throw RuntimeFailure("cannot write PNG '" + path + "': the image is empty");
    const int w = linear.width(), h = linear.height(), c = linear.channels();
    const int out_c = c == 2 ? 3 : c;
    const std::vector<uint8_t> bytes = preview_bytes(linear, exposure);

    const io::FileTarget target = io::file_target(path);
    if (!stbi_write_png(target.write_path.c_str(), w, h, out_c, bytes.data(), w * out_c)) {
        io::discard(target);
        throw RuntimeFailure("cannot write PNG '" + path + "'");
    }
    try {
        io::commit(target);
    } catch (const Error& e) {
        throw RuntimeFailure("cannot write PNG '" + path + "': " + e.what());
    }
}

}  // namespace gdr
