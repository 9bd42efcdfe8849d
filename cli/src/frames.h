// Frame numbers and per-frame file names of the commands that take --frames.
#pragma once

#include <string>
#include <utility>

namespace gdr::cli {

/// The inclusive frame range "A:B" (A <= B) of option `opt`; throws ParameterError naming it otherwise.
std::pair<int, int> parse_frame_range(const std::string& opt, const std::string& v);

/// True if `pattern` holds a printf frame directive (%d, %4d or %04d).
bool has_frame_pattern(const std::string& pattern);

/// `pattern` with its one frame directive replaced by `frame` (padded as the
/// directive says); `pattern` itself if it has none. Throws ParameterError
/// naming `opt` for a '%' that is not one such directive, or for two of them.
std::string frame_path(const std::string& opt, const std::string& pattern, int frame);

}  // namespace gdr::cli
