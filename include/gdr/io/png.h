// 8-bit previews of linear images.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gdr/core/image.h"

namespace gdr {

/// Writes an sRGB PNG of a linear image scaled by 2^exposure (stops), clamped
/// to [0,1]; grey images are written as grey. Throws RuntimeFailure naming the file.
void write_png_preview(const std::string& path, const Image& linear, float exposure = 0.f);

/// The 8-bit pixels write_png_preview() stores for `linear` (row-major; 1, 3
/// or 4 channels, 3 for a 2-channel image), so that other outputs of an image
/// (video frames) show exactly what its PNG shows. NaN becomes 0, +Inf 255.
std::vector<uint8_t> preview_bytes(const Image& linear, float exposure = 0.f);

/// sRGB transfer function of one linear value in [0,1].
float linear_to_srgb(float v);
/// Inverse sRGB transfer function (8-bit texture decoding), value in [0,1].
float srgb_to_linear(float v);

}  // namespace gdr
