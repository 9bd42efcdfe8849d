// Textures: a colour as a function of surface uv. Image textures are stored
// in linear RGB (8-bit sRGB files are decoded to linear on load).
#pragma once

#include <memory>
#include <string>

#include "gdr/core/image.h"
#include "gdr/core/math.h"

namespace gdr {

/// A colour field over uv (reflectance, unitless in [0,1] for albedo textures).
class Texture {
public:
    virtual ~Texture() = default;
    /// Value at uv (uv wraps with period 1; v = 0 is the bottom of the image file).
    virtual Color eval(const Vec2& uv) const = 0;
    /// Mean value over the texture (used for lobe-selection weights and albedo estimates).
    virtual Color mean() const = 0;
    /// True if eval() returns mean() everywhere: a BSDF may then keep the
    /// value and skip the per-hit lookup.
    virtual bool is_constant() const { return false; }
};

/// A texture that returns one colour everywhere.
std::shared_ptr<Texture> make_constant_texture(const Color& c);


/// An image texture from linear RGB pixels (row 0 = top of the picture).
std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const Color& scale = Color(1.f));

/// What an image texture does with uv outside [0, 1).
enum class TextureWrap {
    Repeat,  ///< Tiles the image (period 1).
    Mirror,  ///< Tiles it mirrored at every integer (period 2).
    Clamp,   ///< Repeats the edge texels.
};

/// How an image texture is read and looked up.
struct ImageTextureOptions {
    Color scale{1.f};                        ///< Factor on every texel (unitless).
    bool srgb = true;                        ///< Decode 8-bit files from sRGB; false takes the stored values as linear.
    /// A power law instead: linear = stored^gamma for 8-bit files (Mitsuba's
    /// bitmap `gamma`); 0 keeps `srgb`'s choice. Float files (.hdr, .exr) are linear.
    float gamma = 0.f;
    TextureWrap wrap = TextureWrap::Repeat;  ///< Lookups outside [0, 1).
    bool nearest = false;                    ///< The nearest texel instead of bilinear interpolation.
};

/// An image texture of linear RGB pixels (row 0 at the top) looked up with
/// options.scale, wrap and nearest (srgb and gamma do not apply: the pixels are linear).
std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const ImageTextureOptions& options);

/// A checkerboard of period 1 in (u', v') = (m * (u, v, 1)).xy: c0 where the
/// fractional parts of u' and v' are both above 1/2 or both at most 1/2, c1
/// elsewhere (Mitsuba's checkerboard); c0 and c1 are looked up at uv itself.
std::shared_ptr<Texture> make_checkerboard_texture(std::shared_ptr<Texture> c0, std::shared_ptr<Texture> c1,
                                                   const glm::mat3& m = glm::mat3(1.f));

/// `inner` times `scale` (Mitsuba's `scale` texture); its mean is inner's times scale.
std::shared_ptr<Texture> make_scaled_texture(std::shared_ptr<Texture> inner, const Color& scale);

/// `inner` looked up at an affine map of uv: eval(uv) = inner->eval((m * (u, v, 1)).xy),
/// e.g. a texture's scale, offset or rotation in uv. Its mean is inner's.
std::shared_ptr<Texture> make_uv_transformed_texture(std::shared_ptr<Texture> inner, const glm::mat3& m);

}  // namespace gdr
