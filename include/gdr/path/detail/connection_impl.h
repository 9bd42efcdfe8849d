// The connections of the path-space core (declared in gdr/path/connection.h),
// templated on the host (gdr/path/host.h). Internal: included there.
#pragma once

#include <optional>
#include <type_traits>

#include "gdr/path/densities.h"
#include "gdr/path/dims.h"
#include "gdr/path/environment.h"

namespace gdr {

namespace detail {

// A delta step's zero density stands for a factor common to every strategy
// that can sample the path at all (Veach 1997, section 10.3.5).
inline double remap0(double p) { return p != 0.0 ? p : 1.0; }

// strategy_weight() of the emitter hit (0, t) among a path tracer's two
// strategies: the other one, s = 1 at the previous vertex, exists unless
// that vertex scattered by a delta lobe; its density over this one's is the
// light's origin density of the path's last vertex over the camera walk's.
template <PathHost H>
double emitter_hit_weight(const H& scene, const BasicSubpath<H>& camera, int t, MisHeuristic h) {
    const BasicVertex<H>& end = camera.v[t - 1];
    if (camera.v[t - 2].delta) return 1.0;
    return mis_weight(h, 1.0, {1.0, remap0(pdf_light_origin(scene, end)) / remap0(end.pdf_fwd)});
}

// The light numbers u pick one of gdr's Scene's delta lights (never on another host).
template <PathHost H>
bool picks_delta(const H& scene, float u) {
    if constexpr (std::is_same_v<H, Scene>) return scene.picks_delta(u);
    else return (void)scene, (void)u, false;
}
// The light numbers u pick gdr's Scene's environment (never on another host).
template <PathHost H>
bool picks_environment(const H& scene, float u) {
    if constexpr (std::is_same_v<H, Scene>) return scene.picks_environment(u);
    else return (void)scene, (void)u, false;
}
// A point on the emitters for next-event estimation from `ref`: gdr's
// Scene's area-light sample (its own emitter selection), another host's light sample.
template <PathHost H>
LightSample emitter_point(const H& scene, const Vec3& ref, float u_select, const Vec2& u) {
    if constexpr (std::is_same_v<H, Scene>) return (void)ref, scene.sample_emitter_point(u_select, u);
    else return scene.sample_light(ref, u_select, u);
}

}  // namespace detail

inline bool strategy_possible(const PathDensities& d, int t, int max_s) {
    const int n = d.size();
    if (t < 1 || t > n || (max_s >= 0 && n - t > max_s)) return false;
    if (t == n && d.delta_light) return false;  // no walk hits a delta light
    if (n == 2) return t == 2;
    if (t == n) return true;
    return !d.delta[t - 1] && !d.delta[t];
}

inline double strategy_weight(const StrategySet& set, const PathDensities& d, int t) {
    const int n = d.size();
    const int lowest = set.max_s >= 0 ? std::max(1, n - set.max_s) : 1;  // the fewest camera vertices in the set
    // Densities relative to strategy t's own: a strategy t' < t takes z_t' ..
    // z_{t-1} from the light side instead, each vertex's fwd density replaced
    // by its rev one; a strategy t' > t the other way round.
    thread_local std::vector<double> p;
    p.clear();
    p.push_back(1.0);
    double r = 1.0;
    for (int u = t - 1; u >= lowest; --u) {
        r *= detail::remap0(d.rev[u]) / detail::remap0(d.fwd[u]);
        if (strategy_possible(d, u)) p.push_back(r);
    }
    r = 1.0;
    for (int u = t + 1; u <= n; ++u) {
        r *= detail::remap0(d.fwd[u - 1]) / detail::remap0(d.rev[u - 1]);
        if (strategy_possible(d, u)) p.push_back(r);
    }
    return mis_weight(set.heuristic, 1.0, p);
}

inline void strategy_density_ratios(const PathDensities& d, int t, std::vector<double>& out) {
    const int n = d.size();
    out.assign(size_t(n) + 1, 0.0);
    out[size_t(t)] = strategy_possible(d, t) ? 1.0 : 0.0;
    double r = 1.0;
    for (int u = t - 1; u >= 1; --u) {
        r *= detail::remap0(d.rev[u]) / detail::remap0(d.fwd[u]);
        if (strategy_possible(d, u)) out[size_t(u)] = r;
    }
    r = 1.0;
    for (int u = t + 1; u <= n; ++u) {
        r *= detail::remap0(d.fwd[u - 1]) / detail::remap0(d.rev[u - 1]);
        if (strategy_possible(d, u)) out[size_t(u)] = r;
    }
}

template <PathHost H>
void connection_densities(const H& scene, const BasicSubpath<H>& light, const BasicSubpath<H>& camera, Connection c,
                          std::type_identity_t<const BasicVertex<H>*> q, PathDensities& d) {
    using Vertex = BasicVertex<H>;
    const int s = c.s, t = c.t, n = s + t;
    d.resize(n);
    for (int i = 0; i < t; ++i) {
        const Vertex& v = camera.v[i];
        d.fwd[i] = v.pdf_fwd, d.rev[i] = v.pdf_rev, d.delta[i] = v.delta;
    }
    for (int j = 0; j < s; ++j) {
        const Vertex& v = s == 1 ? *q : light.v[j];
        const int i = n - 1 - j;
        d.fwd[i] = v.pdf_rev, d.rev[i] = v.pdf_fwd, d.delta[i] = v.delta;
    }
    if (s > 0) d.delta_light = (s == 1 ? *q : light.v[0]).delta_light != nullptr;
    // The connecting vertices scatter towards each other, not by a delta lobe.
    d.delta[t - 1] = 0;
    if (s > 0) d.delta[t] = 0;
    const Vertex& pt = camera.v[t - 1];
    const Vertex* pt_prev = t >= 2 ? &camera.v[t - 2] : nullptr;
    if (s == 0) {
        d.rev[t - 1] = pdf_light_origin(scene, pt);
        if (pt_prev) d.rev[t - 2] = pdf_light_direction(scene, pt, *pt_prev);
        return;
    }
    const Vertex* q_prev = s >= 2 ? &light.v[s - 2] : nullptr;
    d.rev[t - 1] = pdf_area(scene, q_prev, *q, pt);
    if (pt_prev) d.rev[t - 2] = pdf_area(scene, q, pt, *pt_prev);
    d.fwd[t] = pdf_area(scene, pt_prev, pt, *q);
    if (q_prev) d.fwd[t + 1] = pdf_area(scene, &pt, *q, *q_prev);
}

template <PathHost H>
ConnectionResult connect(const H& scene, const BasicSubpath<H>& light, const BasicSubpath<H>& camera, Connection c,
                         const Sampler& camera_sampler, const StrategySet& set, bool want_weight, uint64_t& rays) {
    using Vertex = BasicVertex<H>;
    using detail::remap0;
    // gdr's Scene's own lights (delta, environment) and its light tracing
    // (t = 1) are the Scene's: another host's connections are its camera
    // walk's emitter hits and its light samples.
    constexpr bool kScene = std::is_same_v<H, Scene>;
    ConnectionResult r;
    const int s = c.s, t = c.t;
    const Vertex& pt = camera.v[t - 1];
    std::optional<Vertex> sampled;  // s = 1: the light point sampled from pt (a record is large: built only then)
    const Vertex* q = nullptr;
    if (pt.infinite) {
        // The camera walk left the scene: only s = 0 sees the environment.
        if (s != 0) return r;
        r.value = pt.beta * pt.le;
    } else if (s == 0) {
        // The camera walk hit an emitter.
        if (pt.type != VertexType::Surface || !scene.is_emitter(pt.si)) return r;
        r.value = pt.beta * scene.emitted(pt.si, pt.wo);
    } else if (s == 1 && detail::picks_delta(scene, pt.u_light)) {
      if constexpr (kScene) {
        // Next-event estimation towards a delta light: no other strategy of a
        // path tracer reaches it, and bidirectional ones only through its
        // light subpaths (the light end's density is a selection probability).
        if (!connectible(scene, pt) || pt.type != VertexType::Surface) return r;
        const LightSample ls =
            scene.sample_light(pt.si.p, pt.u_light, camera_sampler.at2(dims::vertex(t - 1) + dims::kLightPoint));
        if (!ls.delta || is_black(ls.radiance)) return r;
        const auto& si = pt.si;
        Vec3 w;
        float scale;  // 1 / (r^2 p_select) for a point (I in W/sr), 1 / p_select for a direction (E in W/m^2)
        if (ls.infinite) {
            w = -ls.n;
            scale = 1.f / ls.pdf_w;
        } else {
            const Vec3 d = ls.p - si.p;
            const float dist2 = glm::dot(d, d);
            if (!(dist2 > 0.f)) return r;
            w = d / std::sqrt(dist2);
            scale = 1.f / (dist2 * ls.pdf_a);
        }
        const Color f = host_bsdf_f(scene, si, si.frame.to_local(pt.wo), si.frame.to_local(w));
        r.value = pt.beta * f * ls.radiance * (abs_cos_shading(pt, w) * scale);
        if (is_black(r.value)) {
            r = {};  // every exit returns r, so it is built in the caller's slot
            return r;
        }
        ++rays;
        const bool lit = ls.infinite ? !scene.occluded(spawn_ray(si, w)) : scene.visible(si.p, si.ng, ls.p, Vec3(0.f));
        if (!lit) {
            r = {};
            r.occluded = true;
            return r;
        }
        if (!want_weight) return r;
        if (set.max_s == 0 || set.max_s == 1) {  // a path tracer's set (-1 is any strategy)
            r.weight = 1.0;
            return r;
        }
        sampled.emplace();
        Vertex& lv = *sampled;
        lv.type = VertexType::Light;
        lv.delta_light = ls.delta_light;
        lv.infinite = ls.infinite;
        lv.si.p = ls.p;
        lv.si.ng = ls.infinite ? ls.n : -w;
        lv.si.frame = Frame(lv.si.ng);
        lv.le = ls.radiance;
        lv.pdf_fwd = ls.infinite ? ls.pdf_w : ls.pdf_a;
        q = &*sampled;
      }
    } else if (s == 1 && detail::picks_environment(scene, pt.u_light)) {
      if constexpr (kScene) {
        // Next-event estimation towards the environment (path/environment.h).
        if (!connectible(scene, pt)) return r;
        const LightSample ls =
            scene.sample_light(pt.si.p, pt.u_light, camera_sampler.at2(dims::vertex(t - 1) + dims::kLightPoint));
        sampled.emplace();
        double nee_pdf_w = 0.0;  // pt's BSDF density of the direction (1/sr)
        if (!connect_environment(scene, pt, ls, r.value, nee_pdf_w, *sampled, rays)) {
            r = {};  // every exit returns r, so it is built in the caller's slot
            return r;
        }
        if (want_weight && set.max_s == 1) {
            // Both densities of a direction at infinity are solid-angle ones.
            r.weight = mis_weight(set.heuristic, 1.0, {1.0, remap0(nee_pdf_w) / remap0(double(ls.pdf_w))});
            return r;
        }
        q = &*sampled;
      }
    } else if (t == 1) {
      if constexpr (!kScene) {
        return r;
      } else {
        // Light tracing: the light subpath's vertex seen by the pinhole.
        q = &light.v[s - 1];
        if (q->type != VertexType::Surface || !connectible(scene, *q)) return r;
        const Vertex& eye = camera.v[0];
        const Vec3 d = eye.si.p - q->si.p;
        const float dist = glm::length(d);
        if (!(dist > 0.f)) return r;
        const Vec3 w = d / dist;  // towards the eye
        const float we = scene.camera().importance(-w, r.film);
        if (!(we > 0.f)) return r;
        const Color f = vertex_f(scene, *q, w, TransportMode::Importance);
        if (is_black(f)) return r;
        const float cos_eye = glm::dot(eye.si.ng, -w);
        r.value = q->beta * f * (abs_cos_shading(*q, w) * we * cos_eye / (dist * dist));
        if (is_black(r.value)) return r;
        ++rays;
        if (!scene.visible(q->si.p, q->si.ng, eye.si.p, Vec3(0.f))) {
            r = {};  // every exit returns r, so it is built in the caller's slot
            r.occluded = true;
            return r;
        }
        r.splat = true;
      }
    } else if (s == 1) {
        // Next-event estimation with the vertex's own light numbers.
        if (!connectible(scene, pt) || !scene.has_lights()) return r;
        const LightSample ls = detail::emitter_point(scene, pt.si.p, pt.u_light,
                                                     camera_sampler.at2(dims::vertex(t - 1) + dims::kLightPoint));
        const Vec3 d = ls.p - pt.si.p;
        const float dist2 = glm::dot(d, d);
        if (!(dist2 > 0.f) || !(ls.pdf_a > 0.f)) return r;
        const float dist = std::sqrt(dist2);
        const Vec3 w = d / dist;
        const float cos_light = glm::dot(ls.n, -w);
        if (!(cos_light > 0.f)) return r;
        // Radiance transport: f needs no conversion, and one call gives it
        // with the density a path tracer's MIS weight needs.
        const auto& si = pt.si;
        const BsdfEval fe = scene.eval_bsdf(si, si.frame.to_local(pt.wo), si.frame.to_local(w));
        if (is_black(fe.f)) return r;
        r.value = pt.beta * fe.f * ls.radiance * (abs_cos_shading(pt, w) * cos_light / (dist2 * ls.pdf_a));
        if (is_black(r.value)) return r;
        ++rays;
        if (!scene.visible(pt.si.p, pt.si.ng, ls.p, ls.n)) {
            r = {};  // every exit returns r, so it is built in the caller's slot
            r.occluded = true;
            return r;
        }
        if (!want_weight) return r;
        if (set.max_s == 1) {
            // A path tracer's two strategies: BSDF sampling's density of the
            // light point against light sampling's, both per unit area there.
            const double fwd = pdf_w_to_a(double(fe.pdf), double(dist), double(cos_light));
            r.weight = mis_weight(set.heuristic, 1.0, {1.0, remap0(fwd) / remap0(double(ls.pdf_a))});
            return r;
        }
        sampled.emplace();
        sampled->type = VertexType::Light;
        sampled->si.p = ls.p, sampled->si.ng = ls.n, sampled->si.frame = Frame(ls.n), sampled->si.prim = ls.prim;
        sampled->le = ls.radiance;
        sampled->pdf_fwd = ls.pdf_a;
        q = &*sampled;
    } else {
        // Two surface vertices joined by a shadow ray.
        q = &light.v[s - 1];
        if (!connectible(scene, *q) || pt.type != VertexType::Surface || !connectible(scene, pt)) return r;
        const Vec3 d = pt.si.p - q->si.p;
        const float dist = glm::length(d);
        if (!(dist > 0.f)) return r;
        const Vec3 w = d / dist;  // light side -> camera side
        const Color fq = vertex_f(scene, *q, w, TransportMode::Importance);
        if (is_black(fq)) return r;
        const Color fp = vertex_f(scene, pt, -w, TransportMode::Radiance);
        if (is_black(fp)) return r;
        const float g = abs_cos_shading(*q, w) * abs_cos_shading(pt, w) / (dist * dist);
        r.value = q->beta * fq * fp * pt.beta * g;
        if (is_black(r.value)) return r;
        ++rays;
        if (!scene.visible(q->si.p, q->si.ng, pt.si.p, pt.si.ng)) {
            r = {};  // every exit returns r, so it is built in the caller's slot
            r.occluded = true;
            return r;
        }
    }
    if (is_black(r.value)) {
            r = {};  // every exit returns r, so it is built in the caller's slot
            return r;
        }
    if (want_weight) {
        if (s + t == 2 || set.max_s == 0) {
            r.weight = 1.0;
        } else if (set.max_s == 1) {
            // A path tracer's two strategies: the weight needs only the
            // last vertex's two densities, not the whole path's.
            r.weight = detail::emitter_hit_weight(scene, camera, t, set.heuristic);  // s = 1 returned above
        } else {
            thread_local PathDensities d;
            connection_densities(scene, light, camera, c, q, d);
            r.weight = strategy_weight(set, d, t);
        }
    }
    return r;
}

// gdr's own Scene's are compiled once, in the library.
extern template void connection_densities(const Scene&, const Subpath&, const Subpath&, Connection, const Vertex*,
                                          PathDensities&);
extern template ConnectionResult connect(const Scene&, const Subpath&, const Subpath&, Connection, const Sampler&,
                                         const StrategySet&, bool, uint64_t&);

}  // namespace gdr
