// Options of `gdr render` that `gdr submit` checks and passes on to its parts.
#pragma once

#include <string>
#include <utility>

#include "gdr/io/scene_file.h"

namespace gdr::cli {

/// Most worker threads: more is a typing error, not a machine.
constexpr long long kMaxThreads = 1 << 16;

/// Most pixels along one side: more is a typing error, and the EXR reader refuses it.
constexpr long long kMaxResolution = 1 << 20;

/// True if the --set assignment "key=value" names a key of the scene (fov) rather than of the integrator.
bool is_scene_key(const std::string& assignment);

/// Applies a --set assignment of a scene key (is_scene_key: the field of view, degrees) to the loaded scene.
void apply_scene_setting(SceneFile& sf, const std::string& assignment);

/// Adds the -D assignment "name=value" (a Mitsuba XML scene's $name parameter) to
/// `options`; throws ParameterError unless it is a non-empty name, '=' and a value.
void add_define(SceneFileOptions& options, const std::string& assignment);

/// The width and height (pixels) of --resolution "WxH".
std::pair<int, int> parse_resolution(const std::string& v);

}  // namespace gdr::cli
