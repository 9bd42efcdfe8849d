// Camera paths as gradient-domain path tracing records them: the core's
// camera subpath (walk.h) plus the light sample drawn at each vertex, which
// the offset paths of a shift share (offset_path.h).
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/path/subpath.h"
#include "gdr/path/vertex.h"
#include "gdr/path/walk.h"
#include "gdr/detail/in_place.h"
#include "gdr/path/dims.h"

namespace gdr {

/// A camera subpath on host H (v[0] the camera, v[k] its k-th hit) with the
/// light sample, the s = 1 connection, drawn at each vertex: recorded once,
/// since the offsets of all four neighbouring pixels reconnect to the same
/// light point in area measure.
template <class H>
struct BasicCameraPath : BasicSubpath<H> {
    Vec2 film{0.f};                    ///< Film position (pixel units) of the primary ray.
    std::vector<LightConnection> nee;  ///< nee[k]: the light sample at v[k] (nee[0], the camera's, never valid).
    /// Number of vertices, the camera included (as an index bound of v and nee).
    size_t size() const { return this->v.size(); }
};
/// A camera path on gdr's own Scene.
using CameraPath = BasicCameraPath<Scene>;

namespace detail {

// The walk's hook: the light sample at each vertex, measured once for the
// base and its offsets, its shadow ray traced only where it contributes.
template <class H>
struct RecordLightSamples {
    const H& scene;
    const Sampler& sampler;
    const WalkOptions& opt;
    BasicCameraPath<H>& path;
    void operator()(BasicSubpath<H>&) const {
        const size_t k = path.v.size() - 1;
        LightConnection& c = path.nee.emplace_back();
        const BasicVertex<H>& x = path.v[k];
        if (x.infinite) return;  // the path left the scene: no light sample there
        // A light sample at the last vertex would add a segment beyond max_depth.
        // A black surface gets its sample too (its value is 0, so it is not
        // traced): an offset on another surface shares it.
        if ((opt.max_vertices >= 0 && int(k) >= opt.max_vertices) || !scene.has_lights() ||
            scene.surface(x.si).pure_delta)
            return;
        const Vec2 u_point = sampler.at2(dims::vertex(int(k)) + dims::kLightPoint);
        c.valid = true;
        detail::assign_in_place(c.light, [&] { return scene.sample_light(x.si.p, x.u_light, u_point); });
        c.u_select = x.u_light;
        c.u_point = u_point;
        c.measure(scene, x.si, x.si.frame.to_local(x.wo));
        if (!is_black(c.light.radiance) && !is_black(c.f)) {
            ++path.rays;
            c.tested = true;
            c.visible = scene.visible(x.si.p, x.si.ng, c.light.p, c.light.n);
        }
    }
};

}  // namespace detail

/// trace_camera_path() in two halves, for a caller that traces the camera ray
/// itself (e.g. in one packet with its offsets'). This half resets `path`,
/// sets `ray` to the camera ray through `film` and returns the record its hit
/// must be written to.
template <PathHost H>
typename H::Interaction* begin_camera_path(const H& scene, const Vec2& film, BasicCameraPath<H>& path, Ray& ray) {
    path.film = film;
    path.nee.clear();
    path.nee.emplace_back();  // the camera's: none
    detail::assign_in_place(ray, [&] { return scene.camera().generate_ray(film); });
    return begin_camera_subpath(scene, ray, path);
}

/// The second half: `hit` says whether `ray` hit (its record then holds the hit).
template <PathHost H>
void continue_camera_path(const H& scene, const Sampler& sampler, const WalkOptions& opt, BasicCameraPath<H>& path,
                          const Ray& ray, bool hit) {
    walk_subpath(scene, ray, Color(1.f), Color(1.f), scene.camera().direction_pdf(ray.d), sampler, opt, path,
                 detail::RecordLightSamples<H>{scene, sampler, opt, path}, true, hit);
    path.nee.resize(path.v.size());  // a miss drops the last record
}

/// Traces the camera ray through `film` with the core's walk, and records
/// at every vertex its light sample (with the vertex's own light numbers)
/// and, where the sample contributes, whether it is visible. Vertex k draws
/// from the dims::vertex(k) block of `sampler` (the film position is not
/// drawn here). opt.max_vertices is the path's longest depth in segments.
template <PathHost H>
void trace_camera_path(const H& scene, const Vec2& film, const Sampler& sampler, const WalkOptions& opt,
                       BasicCameraPath<H>& path) {
    Ray ray;
    typename H::Interaction* first = begin_camera_path(scene, film, path, ray);
    continue_camera_path(scene, sampler, opt, path, ray, scene.intersect(ray, *first));
}

// gdr's own Scene's are compiled once, in the library.
extern template SurfaceInteraction* begin_camera_path(const Scene&, const Vec2&, CameraPath&, Ray&);
extern template void continue_camera_path(const Scene&, const Sampler&, const WalkOptions&, CameraPath&, const Ray&,
                                          bool);
extern template void trace_camera_path(const Scene&, const Vec2&, const Sampler&, const WalkOptions&, CameraPath&);

/// Throughput f*|cos|/(pdf*survival) of the scattering at a vertex that sampled a direction (unitless RGB).
template <class H>
Color scatter_weight(const BasicVertex<H>& x) {
    return x.bs.f * (abs_cos_theta(x.bs.wi) / (x.bs.pdf * x.rr_survival));
}

/// Radiance emitted by a surface vertex, or the environment vertex a path
/// ends on, towards the previous vertex of its path (W/(m^2 sr); 0 if it does not emit).
template <PathHost H>
Color emitted(const H& host, const BasicVertex<H>& x) {
    if (x.infinite) return x.le;
    return host.is_emitter(x.si) ? host.emitted(x.si, x.wo) : Color(0.f);
}

}  // namespace gdr
