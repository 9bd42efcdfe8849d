// The path tracer's sample estimator on the path-space core, templated on
// the host (gdr/path/host.h): unidirectional path tracing with next-event
// estimation and multiple importance sampling (power heuristic) between light
// and BSDF sampling, as the camera subpath's walk finds each vertex: the
// emitter the walk hit (s = 0) and the vertex's light sample (s = 1), by the
// core's connect(). gdr's pt integrator and any host's own loop share it.
#pragma once

#include <concepts>

#include "gdr/core/sampler.h"
#include "gdr/path/connection.h"
#include "gdr/path/dims.h"
#include "gdr/path/walk.h"

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


namespace detail {

// The path tracer's two connections at each vertex of the camera subpath,
// as the walk finds it.
template <PathHost H>
struct PathConnect {
    const H& scene;
    const Sampler& sampler;
    const PathOptions& opt;
    PathResult& r;
    bool aux_done = false;  ///< Albedo and normal are recorded (at the first non-delta vertex).
    void operator()(BasicSubpath<H>& path) {
        static const BasicSubpath<H> kNoLight;  // s <= 1 reads no light subpath: s = 1 samples its own light
        const StrategySet set{MisHeuristic::Power, opt.nee ? 1 : 0};
        const int t = path.size();
        const BasicVertex<H>& x = path.v.back();
        if (x.infinite) {
            // The walk left the scene: the environment's radiance (s = 0) is all there is.
            const ConnectionResult e = connect(scene, kNoLight, path, {0, t}, sampler, set, true, r.rays);
            if (!is_black(e.value)) r.radiance += e.value * float(e.weight);
            return;
        }
        if (t == 2) r.depth = x.si.t;
        // Auxiliary data at the first vertex that is not a pure delta surface.
        if (!aux_done && !scene.surface(x.si).pure_delta) {
            if constexpr (requires { { scene.albedo(x.si) } -> std::convertible_to<Color>; })
                r.albedo = scene.albedo(x.si);
            r.normal = x.si.frame.n;
            aux_done = true;
        }
        if (scene.is_emitter(x.si)) {
            const ConnectionResult e = connect(scene, kNoLight, path, {0, t}, sampler, set, true, r.rays);
            if (!is_black(e.value)) r.radiance += e.value * float(e.weight);
        }
        // A light sample would add a segment beyond max_depth.
        if (!opt.nee || (opt.max_depth > 0 && t > opt.max_depth)) return;
        const ConnectionResult l = connect(scene, kNoLight, path, {1, t}, sampler, set, true, r.rays);
        if (!is_black(l.value)) r.radiance += l.value * float(l.weight);
    }
};

}  // namespace detail

/// trace_path() of a camera ray already traced into the first hit record of
/// `path` (begin_camera_subpath), which hit if `first_hit`.
template <PathHost H>
PathResult trace_path_from(const H& scene, const Ray& ray, const Sampler& sampler, const PathOptions& opt,
                           BasicSubpath<H>& path, bool first_hit) {
    PathResult r;
    // A path tracer's strategies read no reverse densities, and forward
    // ones only at emitters.
    WalkOptions wo;
    wo.max_vertices = opt.max_depth, wo.rr_depth = opt.rr_depth;
    wo.reverse_densities = false, wo.forward_densities = false;
    walk_subpath(scene, ray, Color(1.f), Color(1.f), scene.camera().direction_pdf(ray.d), sampler, wo, path,
                 detail::PathConnect<H>{scene, sampler, opt, r}, true, first_hit);
    r.rays += path.rays;
    return r;
}

/// Traces a camera ray (unit direction) with NEE + MIS and Russian roulette;
/// vertex k draws its random numbers from the dims::vertex(k) block of `sampler`.
template <PathHost H>
PathResult trace_path(const H& scene, Ray ray, Sampler& sampler, const PathOptions& opt) {
    thread_local BasicSubpath<H> path;
    typename H::Interaction* first = begin_camera_subpath(scene, ray, path);
    const bool hit = scene.intersect(ray, *first);
    return trace_path_from(scene, ray, sampler, opt, path, hit);
}

// gdr's own Scene's are compiled once, in the library.
extern template PathResult trace_path_from(const Scene&, const Ray&, const Sampler&, const PathOptions&, Subpath&,
                                           bool);
extern template PathResult trace_path(const Scene&, Ray, Sampler&, const PathOptions&);

}  // namespace gdr
