// Constant and image textures. Image textures hold linear RGB; 8-bit files
// are sRGB-decoded on load (gdr::srgb_to_linear, shared with the PNG writer)
// so that shading multiplies reflectances, not display-encoded values.
#include <array>
#include <cmath>
#include <memory>

#include <stb/stb_image.h>

#include "gdr/core/error.h"
#include "gdr/io/png.h"
#include "gdr/scene/texture.h"

namespace gdr {
namespace {

/// stb's reason for the last failure (it may have none).
std::string stb_reason() {
    const char* r = stbi_failure_reason();
    return r ? r : "unknown error";
}

/// The same colour at every uv.
class ConstantTexture final : public Texture {
public:
    explicit ConstantTexture(const Color& c) : c_(c) {}
    Color eval(const Vec2&) const override { return c_; }
    Color mean() const override { return c_; }
    bool is_constant() const override { return true; }

private:
    Color c_;
};

/// Bilinear lookup with repeat wrap; texel centres sit at (i + 0.5) / size.
class ImageTexture final : public Texture {
public:
    ImageTexture(Image img, const Color& scale) : img_(std::move(img)), scale_(scale) {
        if (img_.empty() || img_.width() == 0 || img_.height() == 0)
            throw InputError("image texture: empty image");
        double sum[3] = {0, 0, 0};
        for (int y = 0; y < img_.height(); ++y)
            for (int x = 0; x < img_.width(); ++x) {
                const Color c = img_.rgb(x, y);
                for (int k = 0; k < 3; ++k) sum[k] += c[k];
            }
        const double n = double(img_.pixel_count());
        mean_ = Color(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n)) * scale_;
    }

    Color eval(const Vec2& uv) const override {
        if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) return img_.rgb(0, 0) * scale_;  // no UB on bad uv
        const int w = img_.width(), h = img_.height();
        // v = 0 is the bottom row of the file, image row 0 is the top.
        const float x = (uv.x - std::floor(uv.x)) * float(w) - 0.5f;
        const float y = (1.f - (uv.y - std::floor(uv.y))) * float(h) - 0.5f;
        const float fx = std::floor(x), fy = std::floor(y);
        const float tx = x - fx, ty = y - fy;
        const int x0 = wrap(int(fx), w), x1 = wrap(int(fx) + 1, w);
        const int y0 = wrap(int(fy), h), y1 = wrap(int(fy) + 1, h);
        const Color top = (1.f - tx) * img_.rgb(x0, y0) + tx * img_.rgb(x1, y0);
        const Color bottom = (1.f - tx) * img_.rgb(x0, y1) + tx * img_.rgb(x1, y1);
        return ((1.f - ty) * top + ty * bottom) * scale_;
    }

    Color mean() const override { return mean_; }

private:
    static int wrap(int i, int n) {
        const int r = i % n;
        return r < 0 ? r + n : r;
    }

    Image img_;
    Color scale_;
    Color mean_{0.f};
};

}  // namespace

std::shared_ptr<Texture> make_constant_texture(const Color& c) { return std::make_shared<ConstantTexture>(c); }

std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const Color& scale) {
    return std::make_shared<ImageTexture>(std::move(linear_rgb), scale);
}

std::shared_ptr<Texture> load_image_texture(const std::string& path, const Color& scale) {
    int w = 0, h = 0, n = 0;
    Image img;
    if (stbi_is_hdr(path.c_str())) {  // Radiance .hdr files are already linear
        float* px = stbi_loadf(path.c_str(), &w, &h, &n, 3);
        if (!px) throw InputError("cannot read texture '" + path + "': " + stb_reason());
        img = Image(w, h, 3);
        std::copy(px, px + size_t(w) * h * 3, img.data());
        stbi_image_free(px);
    } else {
        unsigned char* px = stbi_load(path.c_str(), &w, &h, &n, 3);
        if (!px) throw InputError("cannot read texture '" + path + "': " + stb_reason());
        std::array<float, 256> lut;
        for (int i = 0; i < 256; ++i) lut[i] = srgb_to_linear(float(i) / 255.f);
        img = Image(w, h, 3);
        float* dst = img.data();
        for (size_t i = 0, e = size_t(w) * h * 3; i < e; ++i) dst[i] = lut[px[i]];
        stbi_image_free(px);
    }
    if (w <= 0 || h <= 0) throw InputError("cannot read texture '" + path + "': empty image");
    return make_image_texture(std::move(img), scale);
}

}  // namespace gdr
