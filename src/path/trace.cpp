#include "gdr/path/trace.h"

#include "gdr/detail/in_place.h"
#include "gdr/path/dims.h"
#include "gdr/path/walk.h"

namespace gdr {

namespace {

// The walk's hook: the light sample at each vertex, measured once for the
// base and its offsets, its shadow ray traced only where it contributes.
struct RecordLightSamples {
    const Scene& scene;
    const Sampler& sampler;
    const WalkOptions& opt;
    CameraPath& path;
    void operator()(Subpath&) const {
        const size_t k = path.v.size() - 1;
        LightConnection& c = path.nee.emplace_back();
        const Vertex& x = path.v[k];
        if (x.infinite) return;  // the path left the scene: no light sample there
        // A light sample at the last vertex would add a segment beyond max_depth.
        // A black surface gets its sample too (its value is 0, so it is not
        // traced): an offset on another surface shares it.
        if ((opt.max_vertices >= 0 && int(k) >= opt.max_vertices) || !scene.has_lights() ||
            x.si.material->pure_delta)
            return;
        const Vec2 u_point = sampler.at2(dims::vertex(int(k)) + dims::kLightPoint);
        c.valid = true;
        detail::assign_in_place(c.light, [&] { return scene.sample_light(x.si.p, x.u_light, u_point); });
        c.u_select = x.u_light;
        c.u_point = u_point;
        c.measure(x.si, x.si.frame.to_local(x.wo));
        if (!is_black(c.light.radiance) && !is_black(c.f)) {
            ++path.rays;
            c.tested = true;
            c.visible = scene.visible(x.si.p, x.si.ng, c.light.p, c.light.n);
        }
    }
};

}  // namespace

SurfaceInteraction* begin_camera_path(const Scene& scene, const Vec2& film, CameraPath& path, Ray& ray) {
    path.film = film;
    path.nee.clear();
    path.nee.emplace_back();  // the camera's: none
    detail::assign_in_place(ray, [&] { return scene.camera().generate_ray(film); });
    return begin_camera_subpath(scene, ray, path);
}

void continue_camera_path(const Scene& scene, const Sampler& sampler, const WalkOptions& opt, CameraPath& path,
                          const Ray& ray, bool hit) {
    walk_subpath(scene, ray, Color(1.f), Color(1.f), scene.camera().direction_pdf(ray.d), sampler, opt, path,
                 RecordLightSamples{scene, sampler, opt, path}, true, hit);
    path.nee.resize(path.v.size());  // a miss drops the last record
}

void trace_camera_path(const Scene& scene, const Vec2& film, const Sampler& sampler, const WalkOptions& opt,
                       CameraPath& path) {
    Ray ray;
    SurfaceInteraction* first = begin_camera_path(scene, film, path, ray);
    continue_camera_path(scene, sampler, opt, path, ray, scene.intersect(ray, *first));
}

}  // namespace gdr
