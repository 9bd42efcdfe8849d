// Constant and image textures. Image textures hold linear RGB; 8-bit files
// are sRGB-decoded on load (gdr::srgb_to_linear, shared with the PNG writer)
// so that shading multiplies reflectances, not display-encoded values.
#include <array>
#include <cmath>
#include <filesystem>
#include <memory>
#include <vector>

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

/// Bilinear (or nearest-texel) lookup; texel centres sit at (i + 0.5) / size.
class ImageTexture final : public Texture {
public:
    ImageTexture(Image img, const Color& scale, TextureWrap wrap = TextureWrap::Repeat, bool nearest = false)
        : img_(std::move(img)), scale_(scale), wrap_(wrap), nearest_(nearest) {
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
        const float x = fold(uv.x) * float(w) - 0.5f;
        const float y = (1.f - fold(uv.y)) * float(h) - 0.5f;
        if (nearest_) return img_.rgb(index(int(std::floor(x + 0.5f)), w), index(int(std::floor(y + 0.5f)), h)) * scale_;
        const float fx = std::floor(x), fy = std::floor(y);
        const float tx = x - fx, ty = y - fy;
        const int x0 = index(int(fx), w), x1 = index(int(fx) + 1, w);
        const int y0 = index(int(fy), h), y1 = index(int(fy) + 1, h);
        const Color top = (1.f - tx) * img_.rgb(x0, y0) + tx * img_.rgb(x1, y0);
        const Color bottom = (1.f - tx) * img_.rgb(x0, y1) + tx * img_.rgb(x1, y1);
        return ((1.f - ty) * top + ty * bottom) * scale_;
    }

    Color mean() const override { return mean_; }

private:
    // A coordinate's place in [0, 1] under the wrap mode (repeat: its fractional part).
    float fold(float t) const {
        switch (wrap_) {
        case TextureWrap::Repeat: return t - std::floor(t);
        case TextureWrap::Mirror: {
            const float p = t - 2.f * std::floor(0.5f * t);  // [0, 2)
            return p <= 1.f ? p : 2.f - p;
        }
        case TextureWrap::Clamp: return std::clamp(t, 0.f, 1.f);
        }
        return t;
    }
    // A texel index under the wrap mode: interpolation past the edge repeats
    // the image, or stays on the edge texel for the other modes.
    int index(int i, int n) const {
        if (wrap_ != TextureWrap::Repeat) return std::clamp(i, 0, n - 1);
        const int r = i % n;
        return r < 0 ? r + n : r;
    }

    Image img_;
    Color scale_;
    TextureWrap wrap_;
    bool nearest_;
    Color mean_{0.f};
};

/// Mitsuba's checkerboard of two textures.
class CheckerboardTexture final : public Texture {
public:
    CheckerboardTexture(std::shared_ptr<Texture> c0, std::shared_ptr<Texture> c1, const glm::mat3& m)
        : c0_(std::move(c0)), c1_(std::move(c1)), m_(m) {}
    Color eval(const Vec2& uv) const override {
        const Vec2 t = Vec2(m_ * Vec3(uv, 1.f));
        const bool hu = t.x - std::floor(t.x) > 0.5f, hv = t.y - std::floor(t.y) > 0.5f;
        return hu == hv ? c0_->eval(uv) : c1_->eval(uv);
    }
    Color mean() const override { return 0.5f * (c0_->mean() + c1_->mean()); }

private:
    std::shared_ptr<Texture> c0_, c1_;
    glm::mat3 m_;
};

/// A texture looked up at an affine map of uv.
class UvTransformedTexture final : public Texture {
public:
    UvTransformedTexture(std::shared_ptr<Texture> inner, const glm::mat3& m) : inner_(std::move(inner)), m_(m) {}
    Color eval(const Vec2& uv) const override { return inner_->eval(Vec2(m_ * Vec3(uv, 1.f))); }
    Color mean() const override { return inner_->mean(); }
    bool is_constant() const override { return inner_->is_constant(); }

private:
    std::shared_ptr<Texture> inner_;
    glm::mat3 m_;
};

/// A texture times a constant colour.
class ScaledTexture final : public Texture {
public:
    ScaledTexture(std::shared_ptr<Texture> inner, const Color& scale)
        : inner_(std::move(inner)), scale_(scale), mean_(inner_->mean() * scale) {}
    Color eval(const Vec2& uv) const override { return inner_->eval(uv) * scale_; }
    Color mean() const override { return mean_; }
    bool is_constant() const override { return inner_->is_constant(); }

private:
    std::shared_ptr<Texture> inner_;
    Color scale_, mean_;
};

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

std::shared_ptr<Texture> make_constant_texture(const Color& c) { return std::make_shared<ConstantTexture>(c); }

std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const Color& scale) {
    return std::make_shared<ImageTexture>(std::move(linear_rgb), scale);
}

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

std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const ImageTextureOptions& options) {
    return std::make_shared<ImageTexture>(std::move(linear_rgb), options.scale, options.wrap, options.nearest);
}

std::shared_ptr<Texture> load_image_texture(const std::string& path, const ImageTextureOptions& options) {
    return std::make_shared<ImageTexture>(read_image_rgb(path, options), options.scale, options.wrap, options.nearest);
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
    return std::make_shared<ImageTexture>(std::move(img), options.scale, options.wrap, options.nearest);
}

std::shared_ptr<Texture> make_checkerboard_texture(std::shared_ptr<Texture> c0, std::shared_ptr<Texture> c1,
                                                   const glm::mat3& m) {
    if (!c0 || !c1) throw ParameterError("checkerboard texture: both colours are needed");
    return std::make_shared<CheckerboardTexture>(std::move(c0), std::move(c1), m);
}

std::shared_ptr<Texture> make_scaled_texture(std::shared_ptr<Texture> inner, const Color& scale) {
    if (!inner) throw ParameterError("scaled texture: no texture given");
    if (!is_finite(scale)) throw ParameterError("scaled texture: the scale must be finite");
    return std::make_shared<ScaledTexture>(std::move(inner), scale);
}

std::shared_ptr<Texture> make_uv_transformed_texture(std::shared_ptr<Texture> inner, const glm::mat3& m) {
    if (!inner) throw ParameterError("uv-transformed texture: no texture given");
    return std::make_shared<UvTransformedTexture>(std::move(inner), m);
}

}  // namespace gdr
