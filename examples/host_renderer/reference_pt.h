// The toy renderer's own unidirectional path tracer: BSDF sampling plus
// next-event estimation, combined by multiple importance sampling with the
// power heuristic (Veach, "Robust Monte Carlo Methods for Light Transport
// Simulation", 1997, chapter 9). It reads the scene only through the
// gdr::PathHost operations, so it is also a check of what a host provides;
// it is the reference that gradient-domain renders of the toy scenes are
// compared with.
#pragma once

#include "gdr/core/sampler.h"
#include "host.h"

namespace toy {

/// How the reference path tracer samples: max_depth, the longest path in segments (the camera
/// ray is the first); nee, next-event estimation with MIS (false: BSDF sampling alone, an
/// independent estimator of the same integral); rr_depth, Russian roulette from that many
/// segments on (negative: none).
struct PtOptions {
    int max_depth = 16;
    bool nee = true;
    int rr_depth = 5;
};

/// Power heuristic weight (exponent 2) of a strategy of density a against one of density b.
inline float power_heuristic(float a, float b) { return a * a / (a * a + b * b); }

/// One estimate of the radiance (W/(m^2 sr)) arriving at the camera through film point `film`
/// (pixel units), drawing its numbers from `sampler`.
template <gdr::PathHost H>
Color radiance(const H& host, const Vec2& film, gdr::Sampler& sampler, const PtOptions& opt = {}) {
    Ray ray = host.camera().generate_ray(film);
    Color L(0.f), beta(1.f);
    float prev_pdf = 0.f;   // solid-angle density of the last BSDF sample (1/sr)
    bool prev_delta = true;  // the camera ray, or a delta lobe: no light sample competes
    for (int segments = 1; segments <= opt.max_depth; ++segments) {
        typename H::Interaction hit;
        if (!host.intersect(ray, hit)) break;
        const Vec3 wo_world = -ray.d;
        if (host.is_emitter(hit)) {
            float w = 1.f;
            if (opt.nee && !prev_delta) {  // the light sampler could have produced this point too
                const float cos_l = std::abs(glm::dot(hit.ng, wo_world));
                w = power_heuristic(prev_pdf, host.light_pdf_a(hit) * hit.t * hit.t / cos_l);
            }
            L += beta * host.emitted(hit, wo_world) * w;
        }
        const auto& traits = host.surface(hit);
        if (traits.black || segments == opt.max_depth) break;
        const Vec3 wo = hit.frame.to_local(wo_world);
        const float u_select = sampler.next1d();
        const Vec2 u_light = sampler.next2d();
        if (opt.nee && !traits.pure_delta && host.has_lights()) {
            const LightSample ls = host.sample_light(hit.p, u_select, u_light);
            const Vec3 d = ls.p - hit.p;
            const float dist2 = glm::dot(d, d), dist = std::sqrt(dist2);
            const Vec3 wi_world = d / dist;
            const float cos_l = -glm::dot(ls.n, wi_world);
            if (ls.pdf_a > 0.f && cos_l > 0.f && !gdr::is_black(ls.radiance)) {
                const Vec3 wi = hit.frame.to_local(wi_world);
                const BsdfEval e = host.eval_bsdf(hit, wo, wi);
                if (!gdr::is_black(e.f) && host.visible(hit.p, hit.ng, ls.p, ls.n)) {
                    const float pdf_light = ls.pdf_a * dist2 / cos_l;
                    L += beta * e.f * std::abs(wi.z) * ls.radiance * (power_heuristic(pdf_light, e.pdf) / pdf_light);
                }
            }
        }
        const float u_lobe = sampler.next1d();
        const auto s = host.sample_bsdf(hit, wo, u_lobe, sampler.next2d());
        if (!s || !(s->pdf > 0.f)) break;
        beta *= s->f * std::abs(s->wi.z) / s->pdf;
        prev_pdf = s->pdf, prev_delta = s->is_delta();
        const float u_rr = sampler.next1d();
        if (opt.rr_depth >= 0 && segments >= opt.rr_depth) {
            const float q = std::min(0.95f, gdr::max_component(beta));
            if (u_rr >= q) break;
            beta /= q;
        }
        ray = gdr::spawn_ray(hit, hit.frame.to_world(s->wi));
    }
    return L;
}

}  // namespace toy
