// The one random walk of the path-space core. Camera and light subpaths,
// the path tracer and gradient-domain path tracing all extend their paths
// with walk_subpath(): it draws vertex k's numbers from its fixed block
// (dims.h), samples the BSDF, keeps the forward (and optionally reverse) area
// densities and applies Russian roulette. What differs between integrators
// is what happens at a vertex once its record is complete: a hook, called
// before the walk traces on. A path tracer evaluates emission and its light
// sample there (its shadow ray is traced while the vertex is still in
// cache); gradient-domain path tracing records the light sample its offsets
// will share; bidirectional methods only record (RecordVertices).
#pragma once

#include "gdr/detail/in_place.h"
#include "gdr/core/sampler.h"
#include "gdr/path/dims.h"
#include "gdr/path/environment.h"
#include "gdr/path/host.h"
#include "gdr/path/subpath.h"
#include "gdr/path/vertex.h"

namespace gdr {

/// A walk hook that does nothing: the walk only records its vertices.
struct RecordVertices {
    /// Called with the subpath whose last vertex is complete.
    template <class H>
    void operator()(BasicSubpath<H>&) const {}
};

/// Veach's shading-normal correction of importance transport, |wo.ns|
/// |wi.ng| / (|wo.ng| |wi.ns|) for unit world directions wo and wi at `si`
/// ("Robust Monte Carlo Methods for Light Transport Simulation", 1997,
/// section 5.3): light subpaths then see the adjoint of the BSDF the camera
/// side sees through shading normals. 1 for radiance transport.
template <class I>
float shading_correction(const I& si, const Vec3& wo, const Vec3& wi, TransportMode mode) {
    if (mode == TransportMode::Radiance) return 1.f;
    const float num = std::abs(glm::dot(wo, si.frame.n)) * std::abs(glm::dot(wi, si.ng));
    const float den = std::abs(glm::dot(wo, si.ng)) * std::abs(glm::dot(wi, si.frame.n));
    return den > 0.f ? num / den : 0.f;
}

/// First dimension of the number block of vertex k (k >= 1) of a subpath in transport `mode`.
constexpr uint32_t vertex_block(TransportMode mode, int k) {
    return mode == TransportMode::Radiance ? dims::vertex(k) : dims::light_vertex(k);
}

/// Extends `path` from its last vertex along unit-direction `ray`, which
/// that vertex sampled with solid-angle density pdf_w (1/sr; 0 for a delta
/// direction). `beta` is the throughput the ray carries (its unit is the
/// subpath's, see Vertex::beta) and `rel` its part after the endpoint, on
/// which roulette decides. If `first_recorded`, the ray was already traced
/// into a new last record of `path` (first_hit: it hit there), e.g. in one
/// Embree packet with other samples' rays; otherwise the walk traces it.
/// Vertex k's numbers come from vertex_block(path.mode, k); `on_vertex(path)`
/// runs once for every vertex found (for a camera walk that leaves a scene
/// with an environment light, also for the environment vertex it ends on,
/// Vertex::infinite), once its arrival is recorded (type,
/// point, wo, beta, pdf_fwd and its numbers, not yet the direction sampled
/// there, bs and delta, which are written after it), and must not add
/// vertices.
template <PathHost H, class OnVertex>
void walk_subpath(const H& scene, Ray ray, Color beta, Color rel, double pdf_w, const Sampler& sampler,
                  const WalkOptions& opt, BasicSubpath<H>& path, OnVertex&& on_vertex, bool first_recorded = false,
                  bool first_hit = false) {
    using Vertex = BasicVertex<H>;
    const TransportMode mode = path.mode;
    bool prefetch = false;
    if constexpr (PrefetchingHost<H>)
        prefetch = mode == TransportMode::Radiance && scene.light_prefetch_pays();
    // A vertex's emitter and lobe numbers (one hash) are drawn before the ray
    // that reaches it, so that the emitter they select starts loading during
    // the traversal: on scenes with many emitters the light sample then does
    // not wait for memory.
    Vec2 u_sel = sampler.at2(vertex_block(mode, 1) + dims::kLightSelect);
    static_assert(dims::kBsdfLobe == dims::kLightSelect + 1, "the emitter and lobe numbers are one pair");
    if constexpr (PrefetchingHost<H>)
        if (prefetch) scene.prefetch_light(u_sel.x);
    for (int k = 1; opt.max_vertices < 0 || k <= opt.max_vertices; ++k) {
        ++path.rays;
        const bool hit = k == 1 && first_recorded ? first_hit
                                                  : scene.intersect(ray, path.v.emplace_back().si);  // built in place
        if (!hit) {
            path.v.pop_back();
            // A camera walk that leaves the scene ends on the environment, if
            // there is one (path/environment.h); the hook sees that vertex too.
            if constexpr (EnvironmentHost<H>)
                if (mode == TransportMode::Radiance && scene.environment()) [[unlikely]] {
                    append_escape_vertex(scene, ray, beta, pdf_w, path);
                    on_vertex(path);
                }
            return;
        }
        Vertex& x = path.v.back();
        const Vertex& prev = path.v[path.v.size() - 2];
        x.type = VertexType::Surface;
        x.wo = -ray.d;
        x.beta = beta;
        if (prev.infinite) [[unlikely]] {
            x.pdf_fwd = area_density(pdf_w, prev, x);  // the emission disk's density (path/environment.h)
        } else if (opt.forward_densities || scene.is_emitter(x.si)) {
            // area_density() in float: distance and cosine of this segment.
            const Vec3 d = x.si.p - prev.si.p;
            const float dist2 = glm::dot(d, d);
            x.pdf_fwd = dist2 > 0.f ? pdf_w * double(std::abs(glm::dot(x.si.ng, d)) / (dist2 * std::sqrt(dist2))) : 0.0;
        }
        x.u_light = u_sel.x, x.u_lobe = u_sel.y;
        const typename H::Interaction& si = x.si;
        if ((opt.max_vertices >= 0 && k == opt.max_vertices) || scene.surface(si).black) {
            on_vertex(path);
            return;
        }
        const uint32_t b = vertex_block(mode, k);
        x.u_dir = sampler.at2(b + dims::kBsdfDir);
        const Vec3 wo = si.frame.to_local(x.wo);
        // The continuation is sampled before the hook's light sample: the two
        // are independent, so their dependency chains overlap.
        const std::optional<BsdfSample> bs = scene.sample_bsdf(si, wo, x.u_lobe, x.u_dir);
        on_vertex(path);
        if (!bs || !(bs->pdf > 0.f) || is_black(bs->f)) return;
        // Copied after the hook: the BSDF wrote the sample field by field,
        // and copying it 16 bytes at a time right away would stall store
        // forwarding. The throughput below reads the sample, not the copy.
        x.bs = *bs;
        x.delta = bs->is_delta();
        const Vec3 wi_world = si.frame.to_world(bs->wi);
        const Color step = bs->f * (host_transport_factor(scene, si, wo, bs->wi, mode) * abs_cos_theta(bs->wi) / bs->pdf *
                                    shading_correction(si, x.wo, wi_world, mode));
        beta *= step, rel *= step;
        // A delta lobe has no density in the area measure: Veach's remapping
        // (connection.cpp) treats its zero densities as 1 and skips the
        // strategies that would connect there.
        pdf_w = bs->is_delta() ? 0.0 : double(bs->pdf);
        if (opt.reverse_densities) {
            const double pdf_rev_w = bs->is_delta() ? 0.0 : double(scene.pdf_bsdf(si, bs->wi, wo));
            Vertex& before = path.v[path.v.size() - 2];
            before.pdf_rev = area_density(pdf_rev_w, x, before);
        }
        if (k >= opt.rr_depth) {
            const float q = roulette_survival(rel);
            if (sampler.at(b + dims::kRoulette) >= q) return;
            beta /= q, rel /= q;
            x.rr_survival = q;
        }
        if (is_black(beta)) return;
        detail::assign_in_place(ray, [&] { return spawn_ray(si, wi_world); });
        u_sel = sampler.at2(vertex_block(mode, k + 1) + dims::kLightSelect);
        if constexpr (PrefetchingHost<H>)
            if (prefetch) scene.prefetch_light(u_sel.x);
    }
}

/// Starts the camera subpath of primary ray `ray` (unit direction) in
/// `path`: the camera vertex at ray.o, and an empty record for the first
/// hit, whose address is returned so that the caller traces the ray into it
/// (e.g. in one packet with other rays), then walk_subpath() with
/// first_recorded = true continues.
template <PathHost H>
typename H::Interaction* begin_camera_subpath(const H& scene, const Ray& ray, BasicSubpath<H>& path) {
    path.mode = TransportMode::Radiance;
    path.v.clear();
    path.rays = 0;
    const auto& cam = scene.camera();
    BasicVertex<H>& c = path.v.emplace_back();
    c.type = VertexType::Camera;
    c.si.p = ray.o;
    c.si.ng = cam.forward();
    c.si.frame = Frame(cam.forward());
    // The pixel's own sample has We / pdf = 1: the film point is uniform in
    // the pixel and the measurement is the pixel's mean.
    c.beta = Color(1.f);
    c.pdf_fwd = 1.0;
    return &path.v.emplace_back().si;
}

}  // namespace gdr
