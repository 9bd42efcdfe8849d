// OpenEXR I/O for frame buffers: every layer as 32-bit float channels
// ("color.R", "dx.G", "depth.Y", ...), metadata as string attributes.
#pragma once

#include <map>
#include <string>

#include "gdr/core/image.h"

namespace gdr {

/// Writes all layers of `fb` (32-bit float, ZIP compression) and its metadata
/// as string header attributes. Throws RuntimeFailure naming the file on error.
void write_exr(const std::string& path, const FrameBuffer& fb);

/// Reads every channel of an EXR into layers: "L.R/G/B[/A]" -> layer L with 3
/// (or 4) channels, "L.Y" or a lone channel -> 1 channel; bare R, G, B (the
/// usual single-image layout) -> layer "color". String attributes become
/// metadata. Throws InputError naming the file if missing or malformed.
FrameBuffer read_exr(const std::string& path);

/// Reads only the header of an EXR: its metadata (the string attributes, as
/// read_exr() gives them) and its size in pixels, without the pixels, for
/// looking at many renders quickly. Throws InputError naming the file if it is
/// missing or not an EXR.
struct ExrHeader {
    int width = 0;                                ///< Columns (pixels).
    int height = 0;                               ///< Rows (pixels).
    std::map<std::string, std::string> metadata;  ///< String attributes, "gdr:" prefix removed.
};
/// See ExrHeader.
ExrHeader read_exr_header(const std::string& path);

/// Reads an EXR holding one RGB image (bare R, G, B channels, or a single
/// layer); throws InputError naming the file if it holds something else.
Image read_exr_rgb(const std::string& path);

/// Sets how many threads OpenEXR uses to compress and decompress (0: none,
/// the calling thread does it all). The setting is process-wide, so the
/// library never changes it on its own; the `gdr` tool uses every core.
void set_exr_threads(int threads);

/// Writes one RGB(A) or grey image as a plain single-layer EXR (bare channels).
void write_exr_image(const std::string& path, const Image& img);

}  // namespace gdr
