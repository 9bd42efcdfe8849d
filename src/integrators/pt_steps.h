// The path tracer's per-vertex steps: emission with its MIS weight, and the
// scattering step (auxiliary data, next-event estimation, BSDF sampling,
// roulette).
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/path/mis.h"
#include "gdr/path/vertex.h"
#include "gdr/path/dims.h"
#include "gdr/integrators/pt.h"
#include "gdr/scene/scene.h"

namespace gdr::detail {

/// What a path carries from one vertex to the next.
struct PathState {
    Color beta{1.f};         ///< Throughput (unitless RGB).
    bool prev_delta = true;  ///< The last direction came from a delta lobe (a camera ray counts as one: no MIS).
    float prev_pdf_w = 0.f;  ///< Solid-angle pdf of the last direction (1/sr).
    bool aux_done = false;   ///< Albedo and normal are recorded (at the first non-delta vertex).
};

// The environment's steps are kept out of line (and cold): inlined, they
// pushed scatter() past GCC's inlining limits, and the path tracer lost a
// tenth of its speed on scenes without an environment.
/// add_escaped() once the scene is known to have an environment.
[[gnu::noinline, gnu::cold]] inline void add_environment_radiance(const Scene& scene, const Vec3& dir,
                                                                  const PathState& st, const PathOptions& opt,
                                                                  PathResult& r) {
    const Environment* env = scene.environment();
    const Color le = env->eval(dir);
    if (is_black(le)) return;
    const float w = opt.nee && !st.prev_delta ? power_heuristic(st.prev_pdf_w, scene.environment_pdf(dir)) : 1.f;
    r.radiance += st.beta * le * w;
}

/// Adds to r the environment's radiance along a ray that left the scene in
/// unit direction `dir`, MIS-weighted against light sampling as add_emission()
/// weights an emitter's (W/(m^2 sr)); nothing without an environment.
inline void add_escaped(const Scene& scene, const Vec3& dir, const PathState& st, const PathOptions& opt,
                        PathResult& r) {
    if (scene.environment()) [[unlikely]]
        add_environment_radiance(scene, dir, st, opt, r);
}

/// Next-event estimation with an infinite light sample `ls` (a direction to
/// the environment) at hit `si` entered from local direction wo: the shadow
/// ray is unbounded, and the light density is ls.pdf_w (solid angle).
[[gnu::noinline, gnu::cold]] inline void add_environment_sample(const Scene& scene, const SurfaceInteraction& si, const Bsdf& bsdf,
                                   const Vec3& wo, const LightSample& ls, const PathState& st, PathResult& r) {
    if (is_black(ls.radiance) || !(ls.pdf_w > 0.f)) return;
    const Vec3 wi_world = -ls.n;
    const Vec3 wi = si.frame.to_local(wi_world);
    const BsdfEval fe = bsdf.eval_pdf(wo, wi, si.uv);
    if (is_black(fe.f)) return;
    ++r.rays;
    if (scene.occluded(spawn_ray(si, wi_world))) return;
    const float w = power_heuristic(ls.pdf_w, fe.pdf);
    r.radiance += st.beta * fe.f * abs_cos_theta(wi) * ls.radiance * (w / ls.pdf_w);
}

// Both are inline: out of line, the path state went through memory between
// them, and the scalar kernel lost about a tenth of its speed.
/// Adds to r the emission of hit `si` seen in direction wo_world (unit, away
/// from the surface), MIS-weighted against light sampling (W/(m^2 sr)).
inline void add_emission(const Scene& scene, const SurfaceInteraction& si, const Vec3& wo_world,
                         const PathState& st, const PathOptions& opt, PathResult& r) {
    if (!si.is_emitter()) return;
    const Color le = si.emitted(wo_world);
    if (is_black(le)) return;
    float w = 1.f;
    if (opt.nee && !st.prev_delta) {
        const float cos_l = glm::dot(si.ng, wo_world);
        w = power_heuristic(st.prev_pdf_w, pdf_a_to_w(scene.light_pdf_a(si.prim), si.t, cos_l));
    }
    r.radiance += st.beta * le * w;
}

/// The scalar scattering step at hit `si`, vertex `depth`: auxiliary data,
/// the light sample (u_sel: emitter and lobe numbers), the BSDF sample and
/// roulette. Returns false if the path ends there; otherwise `ray` is the
/// next ray and `st` the state that goes with it.
inline bool scatter(const Scene& scene, const SurfaceInteraction& si, const Vec3& wo_world, Sampler& sampler,
                    const PathOptions& opt, int depth, const Vec2& u_sel, PathState& st, PathResult& r, Ray& ray) {
    const float u_light = u_sel.x, u_lobe = u_sel.y;
    const Bsdf& bsdf = *si.material->bsdf;
    const Vec3 wo = si.frame.to_local(wo_world);
    const bool pure_delta = si.material->pure_delta;
    if (!st.aux_done && !pure_delta) {
        r.albedo = bsdf.albedo(si.uv);
        r.normal = si.frame.n;
        st.aux_done = true;
    }
    // A black surface (an emitter with Kd 0) adds nothing by a light
    // sample and scatters nothing: its light sample would only cost a
    // cache miss on a large emitter table.
    if (si.material->black) return false;
    // Numbers are drawn by address, only when needed: the vertex block's
    // layout (path_dims.h) is the same whether or not a strategy runs.
    const uint32_t block = dims::vertex(depth);
    sampler.set_dimension(block + dims::kPerVertex);  // past this vertex's block, as trace_camera_path leaves it

    // The continuation is sampled before the light: the two are independent,
    // so their dependency chains (hash, warp, division) overlap instead of
    // the BSDF's running alone between the shadow ray and the next cast.
    const auto bs = bsdf.sample(wo, si.uv, u_lobe, sampler.at2(block + dims::kBsdfDir));
    if (opt.nee && !pure_delta && scene.has_lights()) {
        const LightSample ls = scene.sample_light(si.p, u_light, sampler.at2(block + dims::kLightPoint));
        const Vec3 d = ls.p - si.p;
        const float dist2 = glm::dot(d, d);
        if (ls.infinite) [[unlikely]] {
            add_environment_sample(scene, si, bsdf, wo, ls, st, r);
        } else if (!is_black(ls.radiance) && dist2 > 0.f) {
            const float dist = std::sqrt(dist2);
            const Vec3 wi_world = d / dist;
            const Vec3 wi = si.frame.to_local(wi_world);
            const BsdfEval fe = bsdf.eval_pdf(wo, wi, si.uv);
            if (!is_black(fe.f)) {
                ++r.rays;
                if (scene.visible(si.p, si.ng, ls.p, ls.n)) {
                    const float pdf_l = pdf_a_to_w(ls.pdf_a, dist, glm::dot(ls.n, -wi_world));
                    const float w = power_heuristic(pdf_l, fe.pdf);
                    r.radiance += st.beta * fe.f * abs_cos_theta(wi) * ls.radiance * (w / pdf_l);
                }
            }
        }
    }

    if (!bs || !(bs->pdf > 0.f) || is_black(bs->f)) return false;
    st.beta *= bs->f * (abs_cos_theta(bs->wi) / bs->pdf);
    st.prev_delta = bs->is_delta();
    st.prev_pdf_w = bs->pdf;
    ray = spawn_ray(si, si.frame.to_world(bs->wi));

    if (depth >= opt.rr_depth) {
        const float q = roulette_survival(st.beta);
        if (sampler.at(block + dims::kRoulette) >= q) return false;
        st.beta /= q;
    }
    return true;
}


}  // namespace gdr::detail
