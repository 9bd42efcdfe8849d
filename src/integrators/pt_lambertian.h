// The path tracer's vectorised kernel for scenes of untextured Lambertian
// surfaces (Scene::all_lambertian()): up to kLanes paths advance in
// lockstep, a vertex at a time, and their shading (BSDF sampling, light
// connection, MIS, spawning) runs four paths per instruction.
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/integrators/pt.h"
#include "gdr/scene/scene.h"

namespace gdr::detail {

/// Paths one call of trace_lambertian_paths() advances together.
inline constexpr int kLambertianLanes = 8;

/// trace_path() of camera rays rays[0..m) (m <= kLambertianLanes) whose
/// first hits are known: hit[i] says whether ray i hit, and si[i] is then its
/// hit record (si must hold kLambertianLanes records; the kernel reuses them).
/// Path i draws its numbers from *samplers[i] and its result goes to
/// results[i]. Requires scene.all_lambertian(), scene.has_lights() and
/// opt.nee; the results are bit-identical to trace_path()'s.
void trace_lambertian_paths(const Scene& scene, const Ray* rays, SurfaceInteraction* si, const bool* hit,
                            Sampler* const* samplers, int m, const PathOptions& opt, PathResult* results);

}  // namespace gdr::detail
