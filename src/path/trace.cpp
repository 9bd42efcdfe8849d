#include "gdr/path/trace.h"

#include "gdr/core/in_place.h"
#include "gdr/path/vertex.h"
#include "gdr/path/dims.h"

namespace gdr {

SurfaceInteraction* begin_camera_path(const Scene& scene, const Vec2& film, CameraPath& path, Ray& ray) {
    path.film = film;
    path.v.clear();
    path.rays = 1;
    assign_in_place(ray, [&] { return scene.camera().generate_ray(film); });
    // Built in place: a vertex is a few hundred bytes and this is the hot loop.
    return &path.v.emplace_back().si;
}

void continue_camera_path(const Scene& scene, Sampler& sampler, const TraceOptions& opt, CameraPath& path, Ray ray,
                          bool hit) {
    Color beta(1.f);
    // Each vertex's emitter and lobe numbers (one hash) are drawn before the
    // ray that reaches it, so that the emitter they select starts loading
    // during the traversal: on scenes with many emitters the light sample
    // then does not wait for memory.
    float u_light, u_lobe;
    const auto draw_ahead = [&](int depth) {
        const Vec2 u = sampler.at2(dims::vertex(depth) + dims::kLightSelect);  // with kBsdfLobe
        u_light = u.x, u_lobe = u.y;
        if (scene.light_prefetch_pays()) scene.prefetch_light(u_light);
    };
    draw_ahead(1);  // the first hit is already known: as early as it gets
    for (int depth = 1;; ++depth) {
        if (!hit) {
            path.v.pop_back();
            return;
        }
        PathVertex& x = path.v.back();
        const Vec3 wo_world = -ray.d;
        x.wo = x.si.frame.to_local(wo_world);
        x.emitted = x.si.is_emitter() ? x.si.emitted(wo_world) : Color(0.f);
        const bool last = opt.max_depth > 0 && depth >= opt.max_depth;

        const uint32_t block = dims::vertex(depth);
        const Vec2 u_point = sampler.at2(block + dims::kLightPoint);
        x.u_lobe = u_lobe;
        x.u_dir = sampler.at2(block + dims::kBsdfDir);
        // Numbers are drawn only where they are read: roulette from rr_depth
        // on, classification only for probabilistic classification.
        if (opt.classify_numbers) x.u_classify = sampler.at(block + dims::kClassify);
        sampler.set_dimension(block + dims::kPerVertex);

        const Bsdf& bsdf = *x.si.material->bsdf;
        // The continuation is sampled before the light: the two are
        // independent, so their dependency chains overlap instead of the
        // BSDF's running alone between the shadow ray and the next cast.
        // (Built in place: assigning an optional would copy it through memory.)
        const std::optional<BsdfSample> bs =
            last ? std::optional<BsdfSample>() : bsdf.sample(x.wo, x.si.uv, x.u_lobe, x.u_dir);
        if (!last && scene.has_lights() && !x.si.material->pure_delta) {
            x.nee.valid = true;
            assign_in_place(x.nee.light, [&] { return scene.sample_light(x.si.p, u_light, u_point); });
            x.nee.u_select = u_light;
            x.nee.u_point = u_point;
            x.nee.measure(x.si, x.wo);
            if (!is_black(x.nee.light.radiance) && !is_black(x.nee.f)) {
                ++path.rays;
                x.nee.tested = true;
                x.nee.visible = scene.visible(x.si.p, x.si.ng, x.nee.light.p, x.nee.light.n);
            }
        }
        if (last) return;
        if (!bs || !(bs->pdf > 0.f) || is_black(bs->f)) return;
        // The throughput and the next ray read the sample, not its copy in the
        // vertex: that copy moves 16 bytes at a time, and reading it back at
        // once stalled store forwarding.
        x.bs = *bs;
        x.scattered = true;
        beta *= bs->f * (abs_cos_theta(bs->wi) / bs->pdf);
        if (depth >= opt.rr_depth) {
            const float q = roulette_survival(beta);
            if (sampler.at(block + dims::kRoulette) >= q) {
                x.scattered = false;
                return;
            }
            x.rr_survival = q, beta /= q;
        }
        ray = spawn_ray(x.si, x.si.frame.to_world(bs->wi));
        ++path.rays;
        draw_ahead(depth + 1);
        hit = scene.intersect(ray, path.v.emplace_back().si);  // invalidates `x`
    }
}

void trace_camera_path(const Scene& scene, const Vec2& film, Sampler& sampler, const TraceOptions& opt,
                       CameraPath& path) {
    Ray ray;
    SurfaceInteraction* first = begin_camera_path(scene, film, path, ray);
    continue_camera_path(scene, sampler, opt, path, ray, scene.intersect(ray, *first));
}

}  // namespace gdr
