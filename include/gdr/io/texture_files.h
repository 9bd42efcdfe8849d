// Image textures read from files: the scene's textures hold decoded linear
// pixels (gdr/scene/texture.h); reading and decoding image files is I/O's.
#pragma once

#include <memory>
#include <string>

#include "gdr/core/image.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/texture.h"

namespace gdr {

/// An image texture (bilinear, repeat wrap) scaled by `scale`; throws
/// InputError naming the file if it is missing or unreadable.
std::shared_ptr<Texture> load_image_texture(const std::string& path, const Color& scale = Color(1.f));

/// An image texture read with `options`; throws InputError naming the file if
/// it is missing or unreadable.
std::shared_ptr<Texture> load_image_texture(const std::string& path, const ImageTextureOptions& options);

/// The linear RGB pixels (row 0 at the top) of an 8-bit image (PNG, JPEG,
/// ..., decoded by options.srgb / options.gamma) or a Radiance .hdr file (as
/// stored), as load_image_texture reads them; options.scale, wrap and
/// nearest do not apply. Throws InputError naming the file.
Image read_image_rgb(const std::string& path, const ImageTextureOptions& options);

/// The opacity of an image as a grey texture (unitless in [0, 1]): its alpha
/// channel, as stored, where the file has one and `use_alpha` is set, else the
/// luminance of its (decoded) colour, times options.scale. Throws InputError
/// as load_image_texture.
std::shared_ptr<Texture> load_opacity_texture(const std::string& path, const ImageTextureOptions& options,
                                              bool use_alpha = true);

/// Reads the textures a material description names (map_kd into kd_map,
/// scaled by diffuse_map_scale()); throws InputError naming a file that is
/// missing or unreadable.
void read_material_textures(MaterialDesc& m);

}  // namespace gdr
