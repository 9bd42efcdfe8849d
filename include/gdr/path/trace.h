// Camera paths as gradient-domain path tracing records them: the core's
// camera subpath (walk.h) plus the light sample drawn at each vertex, which
// the offset paths of a shift share (offset_path.h).
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/path/subpath.h"
#include "gdr/path/vertex.h"

namespace gdr {

/// A camera subpath (v[0] the camera, v[k] its k-th hit) with the light
/// sample, the s = 1 connection, drawn at each vertex: recorded once, since
/// the offsets of all four neighbouring pixels reconnect to the same light
/// point in area measure.
struct CameraPath : Subpath {
    Vec2 film{0.f};                    ///< Film position (pixel units) of the primary ray.
    std::vector<LightConnection> nee;  ///< nee[k]: the light sample at v[k] (nee[0], the camera's, never valid).
    /// Number of vertices, the camera included (as an index bound of v and nee).
    size_t size() const { return v.size(); }
};

/// Traces the camera ray through `film` with the core's walk, and records
/// at every vertex its light sample (with the vertex's own light numbers)
/// and, where the sample contributes, whether it is visible. Vertex k draws
/// from the dims::vertex(k) block of `sampler` (the film position is not
/// drawn here). opt.max_vertices is the path's longest depth in segments.
void trace_camera_path(const Scene& scene, const Vec2& film, const Sampler& sampler, const WalkOptions& opt,
                       CameraPath& path);

/// trace_camera_path() in two halves, for a caller that traces the camera ray
/// itself (e.g. in one packet with its offsets'). This half resets `path`,
/// sets `ray` to the camera ray through `film` and returns the record its hit
/// must be written to.
SurfaceInteraction* begin_camera_path(const Scene& scene, const Vec2& film, CameraPath& path, Ray& ray);
/// The second half: `hit` says whether `ray` hit (its record then holds the hit).
void continue_camera_path(const Scene& scene, const Sampler& sampler, const WalkOptions& opt, CameraPath& path,
                          const Ray& ray, bool hit);

/// Throughput f*|cos|/(pdf*survival) of the scattering at a vertex that sampled a direction (unitless RGB).
inline Color scatter_weight(const Vertex& x) {
    return x.bs.f * (abs_cos_theta(x.bs.wi) / (x.bs.pdf * x.rr_survival));
}

/// Radiance emitted by a surface vertex, or the environment vertex a path
/// ends on, towards the previous vertex of its path (W/(m^2 sr); 0 if it does not emit).
inline Color emitted(const Vertex& x) {
    if (x.infinite) return x.le;
    return x.si.is_emitter() ? x.si.emitted(x.wo) : Color(0.f);
}

}  // namespace gdr
