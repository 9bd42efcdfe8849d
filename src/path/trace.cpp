#include "gdr/path/trace.h"

#include "gdr/integrators/common.h"
#include "gdr/integrators/path_dims.h"

namespace gdr {

void trace_camera_path(const Scene& scene, const Vec2& film, Sampler& sampler, const TraceOptions& opt,
                       CameraPath& path) {
    path.film = film;
    path.v.clear();
    path.rays = 0;
    Ray ray = scene.camera().generate_ray(film);
    Color beta(1.f);
    for (int depth = 1;; ++depth) {
        // Built in place: a vertex is a few hundred bytes and this is the hot loop.
        PathVertex& x = path.v.emplace_back();
        ++path.rays;
        if (!scene.intersect(ray, x.si)) {
            path.v.pop_back();
            return;
        }
        const Vec3 wo_world = -ray.d;
        x.wo = x.si.frame.to_local(wo_world);
        x.emitted = x.si.is_emitter() ? x.si.emitted(wo_world) : Color(0.f);
        const bool last = opt.max_depth > 0 && depth >= opt.max_depth;

        sampler.set_dimension(dims::vertex(depth));
        const float u_light = sampler.next1d();
        const Vec2 u_point = sampler.next2d();
        x.u_lobe = sampler.next1d();
        x.u_dir = sampler.next2d();
        const float u_rr = sampler.next1d();
        x.u_classify = sampler.next1d();

        const Bsdf& bsdf = *x.si.material->bsdf;
        if (!last && scene.has_lights() && !x.si.material->pure_delta) {
            x.nee.valid = true;
            x.nee.light = scene.sample_light(x.si.p, u_light, u_point);
            x.nee.u_select = u_light;
            x.nee.u_point = u_point;
            if (!is_black(x.nee.light.radiance)) {
                ++path.rays;
                x.nee.visible = scene.visible(x.si.p, x.si.ng, x.nee.light.p, x.nee.light.n);
            }
        }
        if (!last) {
            if (auto bs = bsdf.sample(x.wo, x.si.uv, x.u_lobe, x.u_dir); bs && bs->pdf > 0.f && !is_black(bs->f)) {
                x.bs = *bs;
                x.scattered = true;
            }
        }
        if (x.scattered) {
            beta *= x.bs.f * (abs_cos_theta(x.bs.wi) / x.bs.pdf);
            if (depth >= opt.rr_depth) {
                const float q = roulette_survival(beta);
                if (u_rr >= q) x.scattered = false;
                else x.rr_survival = q, beta /= q;
            }
        }
        if (!x.scattered) return;
        ray = spawn_ray(x.si, x.si.frame.to_world(x.bs.wi));
    }
}

}  // namespace gdr
