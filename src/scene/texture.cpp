// Constant, image and checkerboard textures. Image textures hold linear RGB
// (image files are read and decoded by gdr/io/texture_files.h).
#include <array>
#include <cmath>
#include <memory>
#include <vector>

#include "gdr/core/error.h"
#include "gdr/scene/texture.h"

namespace gdr {
namespace {

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

}  // namespace

std::shared_ptr<Texture> make_constant_texture(const Color& c) { return std::make_shared<ConstantTexture>(c); }

std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const Color& scale) {
    return std::make_shared<ImageTexture>(std::move(linear_rgb), scale);
}

std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const ImageTextureOptions& options) {
    return std::make_shared<ImageTexture>(std::move(linear_rgb), options.scale, options.wrap, options.nearest);
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
