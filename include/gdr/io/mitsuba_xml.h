// Mitsuba scene files (XML of Mitsuba 0.6 and 3.x) as gdr scenes. Names are
// accepted in both spellings (0.6's camelCase, 3.x's snake_case). What is
// supported, and what is approximated, is listed in docs/scenes.md, "Mitsuba
// scenes" section: shapes obj, ply, rectangle, cube, sphere and disk
// (triangulated); the BSDFs diffuse, roughdiffuse, conductor, roughconductor,
// dielectric, thindielectric, roughdielectric, plastic, roughplastic,
// twosided and mask with bitmap and checkerboard textures; area emitters; a
// perspective sensor with its film; the integrator's max_depth and rr_depth;
// default, $parameters, include and ref. Anything else is an InputError
// naming the file, line, element and id, or with SceneFileOptions::lenient a
// warning (SceneFile::warnings) and the element skipped.
#pragma once

#include <string>

#include "gdr/io/scene_file.h"
#include "gdr/scene/microfacet.h"

namespace gdr {

/// Loads a Mitsuba XML scene. Paths inside are relative to the file that
/// names them (an included file's own directory first, then the scene's).
/// Render defaults: spp from the sampler's sample_count, max_depth (and
/// rr_depth) from the integrator, integrator `pt` (`bdpt` or `gpt` for those
/// Mitsuba integrators). Throws InputError naming the file and line.
SceneFile load_mitsuba_scene(const std::string& path, const SceneFileOptions& options = {});

/// The normal-incidence reflectance (unitless RGB in [0, 1]) of a conductor
/// of complex index of refraction eta + i k relative to the outside medium:
/// ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2) per channel.
Color conductor_reflectance(const Color& eta, const Color& k);

/// The normal-incidence reflectance (unitless RGB) of one of Mitsuba's named
/// conductors ("Cu", "Au", "Al", "Ag", "Cr", ..., "none" for a perfect
/// mirror), computed from its RGB complex index of refraction; false for an
/// unknown name.
bool named_conductor_reflectance(const std::string& name, Color& f0);

/// The RGB complex index of refraction (unitless) of one of Mitsuba's named
/// conductors (eta 0, k 1 for "none"); false for an unknown name.
bool named_conductor_ior(const std::string& name, ConductorIor& ior);

}  // namespace gdr
