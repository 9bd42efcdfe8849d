// The primal path tracer's core, reusable by other integrators and tests.
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/integrators/integrator.h"

namespace gdr {

/// Options of one traced camera path.
struct PathOptions {
    int max_depth = -1;  ///< Longest path in segments (camera to light); -1 unlimited.
    int rr_depth = 5;    ///< Depth from which Russian roulette may end the path.
    bool nee = true;     ///< Next-event estimation with MIS; false = BSDF sampling only.
};

/// One path-traced sample of a camera ray.
struct PathResult {
    Color radiance{0.f};   ///< Radiance estimate along the ray (W/(m^2 sr)).
    Color albedo{0.f};     ///< Albedo at the first non-delta vertex.
    Vec3 normal{0.f};      ///< Shading normal (world) at the first non-delta vertex.
    float depth = 0.f;     ///< Distance to the first hit (scene units), 0 on a miss.
    uint64_t rays = 0;     ///< Rays cast.
};

/// Traces a camera ray with NEE + MIS and Russian roulette; vertex k draws its
/// random numbers from the dims::vertex(k) block of `sampler`.
PathResult trace_path(const Scene& scene, Ray ray, Sampler& sampler, const PathOptions& opt);

/// Registers "pt".
void register_pt(Registry<Integrator>& r);

}  // namespace gdr
