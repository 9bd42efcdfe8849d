// Tracing and recording camera paths for path-space integrators.
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/path/vertex.h"

namespace gdr {

/// Limits of a recorded camera path.
struct TraceOptions {
    int max_depth = -1;  ///< Longest path in segments (camera to light); -1 unlimited.
    int rr_depth = 5;    ///< Vertex index from which Russian roulette may end the path.
    /// Draw every vertex's classification number (PathVertex::u_classify),
    /// which only probabilistic classification reads; without it the number
    /// stays 0.5 and a vertex costs one hash less.
    bool classify_numbers = true;
};

/// Traces the camera ray through `film` and records every vertex with its
/// light sample and sampled direction. Vertex k draws its numbers from the
/// dims::vertex(k) block of `sampler` (the film position is not drawn here).
void trace_camera_path(const Scene& scene, const Vec2& film, Sampler& sampler, const TraceOptions& opt,
                       CameraPath& path);

/// trace_camera_path() in two halves, for a caller that traces the camera ray
/// itself (e.g. in one packet with its offsets'). This half resets `path`,
/// sets `ray` to the camera ray through `film` and returns the record its hit
/// must be written to.
SurfaceInteraction* begin_camera_path(const Scene& scene, const Vec2& film, CameraPath& path, Ray& ray);
/// The second half: `hit` says whether `ray` hit (its record then holds the hit).
void continue_camera_path(const Scene& scene, Sampler& sampler, const TraceOptions& opt, CameraPath& path, Ray ray,
                          bool hit);

/// Throughput f*|cos|/(pdf*survival) of the scattering at vertex k (unitless RGB).
inline Color scatter_weight(const PathVertex& x) {
    return x.bs.f * (abs_cos_theta(x.bs.wi) / (x.bs.pdf * x.rr_survival));
}

}  // namespace gdr
