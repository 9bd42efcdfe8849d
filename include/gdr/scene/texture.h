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

/// An image texture (bilinear, repeat wrap) scaled by `scale`; throws
/// InputError naming the file if it is missing or unreadable.
std::shared_ptr<Texture> load_image_texture(const std::string& path, const Color& scale = Color(1.f));

/// An image texture from linear RGB pixels (row 0 = top of the picture).
std::shared_ptr<Texture> make_image_texture(Image linear_rgb, const Color& scale = Color(1.f));

}  // namespace gdr
