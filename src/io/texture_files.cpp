// Image textures from files: 8-bit images (PNG, JPEG, ...) decoded from sRGB
// or a power law into linear values (gdr::srgb_to_linear, shared with the PNG
// writer) so that shading multiplies reflectances, not display-encoded
// values, and Radiance .hdr files as stored.
#include "gdr/io/texture_files.h"

#include <array>
#include <cmath>
#include <filesystem>
#include <vector>

#include <stb/stb_image.h>

#include "gdr/core/error.h"
#include "gdr/io/png.h"

namespace gdr {
namespace {

/// stb's reason for the last failure (it may have none).
std::string stb_reason() {
    const char* r = stbi_failure_reason();
    return r ? r : "unknown error";
}

/// The decoding of an 8-bit value v / 255 into a linear one by the options:
/// a power law when gamma is given, else sRGB or the value itself.
float decode_8bit(float v, const ImageTextureOptions& o) {
    if (o.gamma > 0.f) return std::pow(v, o.gamma);
    return o.srgb ? srgb_to_linear(v) : v;
}

/// The pixels of an image file as floats, `channels` per pixel (stb's
/// conversion), and the number of channels the file itself has.
struct Pixels {
    int w = 0, h = 0, file_channels = 0;
    std::vector<float> v;
    bool hdr = false;  // linear floats (.hdr); otherwise 8-bit values / 255
};

Pixels read_pixels(const std::string& path, int channels) {
    // stb opens the file itself: a FIFO would block it for ever, a device feed it without end.
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
        throw InputError("cannot read texture '" + path + "': not a file");
    Pixels p;
    if (stbi_is_hdr(path.c_str())) {  // Radiance .hdr files are already linear
        float* px = stbi_loadf(path.c_str(), &p.w, &p.h, &p.file_channels, channels);
        if (!px) throw InputError("cannot read texture '" + path + "': " + stb_reason());
        p.v.assign(px, px + size_t(p.w) * p.h * channels);
        p.hdr = true;
        stbi_image_free(px);
    } else {
        unsigned char* px = stbi_load(path.c_str(), &p.w, &p.h, &p.file_channels, channels);
        if (!px) throw InputError("cannot read texture '" + path + "': " + stb_reason());
        p.v.resize(size_t(p.w) * p.h * channels);
        for (size_t i = 0; i < p.v.size(); ++i) p.v[i] = float(px[i]) / 255.f;
        stbi_image_free(px);
    }
    if (p.w <= 0 || p.h <= 0) throw InputError("cannot read texture '" + path + "': empty image");
    return p;
}

}  // namespace

std::shared_ptr<Texture> load_image_texture(const std::string& path, const Color& scale) {
    ImageTextureOptions o;
    o.scale = scale;
    return load_image_texture(path, o);
}

Image read_image_rgb(const std::string& path, const ImageTextureOptions& options) {
    const Pixels p = read_pixels(path, 3);
    std::array<float, 256> lut;
    for (int i = 0; i < 256; ++i) lut[i] = decode_8bit(float(i) / 255.f, options);
    Image img(p.w, p.h, 3);
    float* dst = img.data();
    for (size_t i = 0; i < p.v.size(); ++i) dst[i] = p.hdr ? p.v[i] : lut[size_t(std::lround(p.v[i] * 255.f))];
    return img;
}

std::shared_ptr<Texture> load_image_texture(const std::string& path, const ImageTextureOptions& options) {
    return make_image_texture(read_image_rgb(path, options), options);
}

std::shared_ptr<Texture> load_opacity_texture(const std::string& path, const ImageTextureOptions& options,
                                              bool use_alpha) {
    const Pixels p = read_pixels(path, 4);
    const bool alpha = use_alpha && (p.file_channels == 2 || p.file_channels == 4);
    Image img(p.w, p.h, 3);
    float* dst = img.data();
    for (size_t i = 0, n = size_t(p.w) * p.h; i < n; ++i) {
        const float* px = &p.v[4 * i];
        float o;
        if (alpha) {
            o = px[3];
        } else {
            const auto lin = [&](float c) { return p.hdr ? c : decode_8bit(c, options); };
            o = luminance(Color(lin(px[0]), lin(px[1]), lin(px[2])));
        }
        dst[3 * i] = dst[3 * i + 1] = dst[3 * i + 2] = o;
    }
    return make_image_texture(std::move(img), options);
}

void read_material_textures(MaterialDesc& m) {
    m.kd_map = m.map_kd.empty() ? nullptr : load_image_texture(m.map_kd, diffuse_map_scale(m));
}

}  // namespace gdr
