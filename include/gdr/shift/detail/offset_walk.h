// The walk of an offset path, templated on the host (gdr/path/host.h):
// shift_camera_path() and gdr's packet tracing are made of these steps.
// Internal: included by gdr/shift/offset_path.h.
#pragma once

#include "gdr/detail/in_place.h"
#include "gdr/path/trace.h"
#include "gdr/shift/shift.h"
#include "gdr/shift/steps.h"

namespace gdr::detail {

// Shadow segments of several offset walks, traced together as packets after
// the walks (Scene::visible8). A walk goes on as if each queued segment were
// unblocked; resolve() then zeroes blocked light connections and cuts an
// offset at a blocked reconnection, which gives what stopping there would have.
template <class H>
struct DeferredVisibility {
    static constexpr int kMax = 16;
    struct Target {
        BasicOffsetPath<H>* path;
        size_t k;        // depth of the light connection or of the reconnecting step
        bool reconnect;  // a reconnection y_k -> x_{k+1}, else the light connection at y_k
    };
    // Filled during the walks and traced after them: by then the stores have
    // left the store buffer, and the packet's setup reads four lanes at a time.
    VisibilityBatch q[kMax / VisibilityBatch::kLanes];
    Target t[kMax];
    int n = 0;

    // Queues the segment p0 -> p1 for `target` and returns true, or, with no
    // queue or a full one, returns whether it is unblocked, tested now.
    static bool queued_or_visible(const H& scene, DeferredVisibility* queue, const Vec3& p0, const Vec3& n0,
                                  const Vec3& p1, const Vec3& n1, const Target& target) {
        if (!queue || queue->n == kMax) return scene.visible(p0, n0, p1, n1);
        queue->q[queue->n / VisibilityBatch::kLanes].add(p0, n0, p1, n1);
        queue->t[queue->n++] = target;
        return true;
    }
    // Traces the queued segments and applies the blocked ones; once, after the walks.
    void resolve(const H& scene) {
        bool vis[kMax];
        for (int b = 0; b * VisibilityBatch::kLanes < n; ++b) scene.visible8(q[b], vis + b * VisibilityBatch::kLanes);
        // A cut only removes records beyond its depth, so targets are checked against the records left.
        for (int i = 0; i < n; ++i) {
            if (vis[i]) continue;
            BasicOffsetPath<H>& y = *t[i].path;
            const size_t k = t[i].k;
            if (k >= y.v.size()) continue;  // beyond an earlier cut
            if (!t[i].reconnect) {
                y.v[k].nee_radiance = Color(0.f);
            } else if (y.v[k].step.kind == ShiftStep::Kind::Reconnect) {
                y.v[k].step = ShiftStep{};  // Fail, as a tested reconnection would have
                y.v.resize(k + 1);
                y.merged_from = y.base_values_from = size_t(-1);
            }
        }
    }
};

// True if the offset vertex y, sharing the base vertex x, scatters with x's
// BSDF values for any wi: the BSDF depends on wo only through its side, and
// both arrive on the same side.
template <class H>
bool same_side_values(const H& scene, const BasicOffsetVertex<H>& y, const BasicVertex<H>& x) {
    return scene.surface(y.si).wo_side_only && y.wo.z * glm::dot(x.wo, x.si.frame.n) > 0.f;
}

// The base's sample of a point or spot light, seen from offset vertex y_k:
// the same light position (a delta in position, so shared exactly), its
// intensity towards y_k. Light sampling's density there is p_select ly^2 per
// steradian (the cosine at a point light is 1 by convention, LightSample),
// so the Jacobian of the shared direction is (p_select lx^2) / (p_select
// ly^2), and no BSDF sample reaches the light (BSDF density 0).
template <class H>
void shift_delta_light_connection(const H& scene, const LightConnection& nee, BasicOffsetPath<H>& path, size_t k,
                                  DeferredVisibility<H>* defer) {
    BasicOffsetRecord<H>& rec = path.v[k];
    const LightSample& ls = nee.light;
    const BasicOffsetVertex<H>& y = rec.y;
    const Vec3d dy = Vec3d(ls.p) - Vec3d(y.si.p);
    const double ly2 = glm::dot(dy, dy);
    if (!(ly2 > 0.0) || !(ls.pdf_a > 0.f)) return;
    const Vec3 wi_world = Vec3(dy / std::sqrt(ly2));
    const Vec3 wi = y.si.frame.to_local(wi_world);
    const double pdf_y = double(ls.pdf_a) * ly2;
    rec.nee = true;
    rec.nee_cos = abs_cos_theta(wi);
    const BsdfEval fe = scene.eval_bsdf(y.si, y.wo, wi);
    rec.nee_f = fe.f;
    rec.nee_pdf_bsdf = 0.f;
    rec.nee_pdf_light_w = pdf_y;
    rec.nee_jacobian = nee.pdf_w / pdf_y;
    const Color le = ls.delta_light->intensity_towards(-wi_world);
    if (!is_black(le) && !is_black(rec.nee_f)) {
        ++path.rays;
        const bool lit =
            DeferredVisibility<H>::queued_or_visible(scene, defer, y.si.p, y.si.ng, ls.p, Vec3(0.f), {&path, k, false});
        rec.nee_radiance = lit ? le : Color(0.f);
    }
}

// The base's light sample at x_k, seen from the offset vertex y_k (of
// `path`); its shadow segment is queued in `defer` if given and not full.
template <class H>
void shift_light_connection(const H& scene, const ShiftConfig& config, const BasicCameraPath<H>& base, size_t k,
                            BasicOffsetPath<H>& path, DeferredVisibility<H>* defer) {
    BasicOffsetRecord<H>& rec = path.v[k];
    const LightConnection& nee = base.nee[k];
    if (!nee.valid) return;
    const LightSample& ls = nee.light;
    const BasicOffsetVertex<H>& y = rec.y;
    if (y.infinite) return;  // the offset left the scene: no light sample there
    if (y.on_base) {
        // Same vertex, same light segment (measured once for the base): only
        // the BSDF's incoming direction differs.
        if (!(nee.dist > 0.f)) return;
        const Vec3& wi = nee.wi;
        // Arriving on the base's side of a BSDF that sees only that side, the
        // offset's values are the base's.
        const BsdfEval fe =
            same_side_values(scene, y, base.v[k]) ? BsdfEval{nee.f, nee.pdf_bsdf} : scene.eval_bsdf(y.si, y.wo, wi);
        rec.nee = true;
        rec.nee_f = fe.f;
        rec.nee_cos = abs_cos_theta(wi);
        rec.nee_jacobian = 1.0;
        rec.nee_pdf_light_w = nee.pdf_w;
        rec.nee_pdf_bsdf = ls.delta ? 0.f : fe.pdf;  // no BSDF sample reaches a delta light
        if (nee.tested) {
            rec.nee_radiance = nee.visible ? ls.radiance : Color(0.f);
        } else if (!is_black(ls.radiance) && !is_black(fe.f)) {
            // The base's own value was 0, so it left the segment untraced.
            ++path.rays;
            const bool lit =
                DeferredVisibility<H>::queued_or_visible(scene, defer, y.si.p, y.si.ng, ls.p, ls.n, {&path, k, false});
            rec.nee_radiance = lit ? ls.radiance : Color(0.f);
        }
        return;
    }
    // The light point is shared in area measure; both ends must be connectable
    // so that the inverse shift is defined too.
    const BasicShiftStepInput<H> in{scene, config, base, k, y};
    if (!shift::both_connectable(in)) return;
    if (!(nee.pdf_w > 0.0)) return;  // the base cannot sample this light point (or sits on it)
    if (ls.infinite) {
        if constexpr (!EnvironmentHost<H>) {
            return;  // a host without an environment samples no direction
        } else {
        // A direction to the environment is shared in solid angle: the offset
        // sees the same direction, radiance and light density (|J| = 1).
        const Vec3 wi_world = -ls.n;
        const Vec3 wi = y.si.frame.to_local(wi_world);
        const BsdfEval fe = scene.eval_bsdf(y.si, y.wo, wi);
        rec.nee = true;
        rec.nee_cos = abs_cos_theta(wi);
        rec.nee_f = fe.f;
        rec.nee_pdf_bsdf = ls.delta ? 0.f : fe.pdf;  // a directional light: as the environment's, a delta
        rec.nee_pdf_light_w = nee.pdf_w;
        rec.nee_jacobian = 1.0;
        if (!is_black(ls.radiance) && !is_black(fe.f)) {
            ++path.rays;
            const bool lit = DeferredVisibility<H>::queued_or_visible(scene, defer, y.si.p, y.si.ng,
                                                                   scene.beyond_scene(y.si.p, wi_world), ls.n,
                                                                   {&path, k, false});
            rec.nee_radiance = lit ? ls.radiance : Color(0.f);
        }
        return;
        }
    }
    if (ls.delta) {
        shift_delta_light_connection(scene, nee, path, k, defer);
        return;
    }
    const Vec3d pz(ls.p), nz(ls.n);
    const Vec3d dy = pz - Vec3d(y.si.p);
    const double ly2 = glm::dot(dy, dy);
    const double dot_y = -glm::dot(nz, dy);  // cosine at the light times the distance
    if (!(ly2 > 0.0)) return;
    const double ly = std::sqrt(ly2), pa = double(ls.pdf_a);
    // The light point is shared in area measure, so d omega_y / d omega_x is
    // the ratio of the two solid-angle densities of sampling it (pdf_a
    // cancels): p_x / p_y with p_y = pa ly^3 / |dot_y|. One division gives
    // both 1/ly and 1/p_y, where separate ones and a second square root (for
    // the base's distance, the same for all four offsets) were on the
    // critical path.
    double inv_ly, pdf_y, inv_pdf_y;
    const double m = pa * ly2 * ly, q = m * std::abs(dot_y);
    if (q > 0.0 && std::isfinite(q)) {
        const double inv_q = 1.0 / q;  // 1 / (pa ly^3 |dot_y|)
        inv_ly = inv_q * pa * ly2 * std::abs(dot_y);
        inv_pdf_y = inv_q * dot_y * dot_y;
        pdf_y = m * m * inv_q;
    } else {
        inv_ly = 1.0 / ly, pdf_y = 0.0, inv_pdf_y = 0.0;  // grazing or unsampleable: no density, no Jacobian
    }
    const double cos_zy = dot_y * inv_ly;
    rec.nee = true;
    const Vec3 wi_world = Vec3(dy * inv_ly);
    const Vec3 wi = y.si.frame.to_local(wi_world);
    rec.nee_cos = abs_cos_theta(wi);
    const BsdfEval fe = scene.eval_bsdf(y.si, y.wo, wi);
    rec.nee_f = fe.f;
    rec.nee_pdf_bsdf = fe.pdf;
    rec.nee_pdf_light_w = pdf_y;
    rec.nee_jacobian = nee.pdf_w * inv_pdf_y;
    const Color le = cos_zy > 0.0 ? scene.light_radiance(ls, -wi_world) : Color(0.f);
    if (!is_black(le) && !is_black(rec.nee_f)) {
        ++path.rays;
        const bool lit = DeferredVisibility<H>::queued_or_visible(scene, defer, y.si.p, y.si.ng, ls.p, ls.n, {&path, k, false});
        rec.nee_radiance = lit ? le : Color(0.f);
    }
}

// Makes `v` the environment vertex that an offset ray `ray` reaches on leaving
// the scene (path/environment.h's convention: ng the direction light travels).
template <EnvironmentHost H>
void set_on_environment(const H& scene, const Ray& ray, BasicOffsetVertex<H>& v) {
    v.infinite = true;
    v.si.ng = -ray.d;
    v.si.frame = Frame(v.si.ng);
    v.si.p = scene.beyond_scene(ray.o, ray.d);
    v.emitted = scene.environment()->eval(ray.d);
}

// Makes `v` the offset vertex that coincides with base vertex x_{k+1}, entered from `from`.
template <class H>
void set_on_base(const H& scene, BasicOffsetVertex<H>& v, const BasicVertex<H>& next, const Vec3& from) {
    v.si = next.si;
    v.on_base = true;
    const Vec3 w = glm::normalize(from - next.si.p);
    v.wo = next.si.frame.to_local(w);
    v.emitted = scene.is_emitter(next.si) ? scene.emitted(next.si, w) : Color(0.f);
}

template <PathHost H>
void walk_offset(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config, const BasicCameraPath<H>& base,
                 BasicOffsetPath<H>& out, DeferredVisibility<H>* defer);

// The offset's vertex count once its walk (and any cut) is final.
template <class H>
void finish_offset(const BasicCameraPath<H>& base, BasicOffsetPath<H>& out) {
    out.length = out.merged_from != size_t(-1) ? base.size() : out.v.size();
}

template <class H>
void reset(BasicOffsetPath<H>& out) {
    out.v.clear();
    out.rays = 0;
    out.merged_from = out.base_values_from = size_t(-1);
    out.length = 0;
}

// For a reset `out`: makes the records of the offset's camera vertex (the
// base's: one pinhole) and of its first hit, and sets `ray` to the camera ray
// through film + pixel_offset that reaches it; returns where that ray's hit goes.
template <PathHost H>
typename H::Interaction* start_offset(const H& scene, const Vec2& film, const Vec2& pixel_offset,
                                      BasicOffsetPath<H>& out, Ray& ray) {
    detail::assign_in_place(ray, [&] { return scene.camera().generate_ray(film + pixel_offset); });
    out.rays = 1;
    out.v.emplace_back().y.si.p = ray.o;
    return &out.v.emplace_back().y.si;
}

// After start_offset's camera ray was traced: walks on from its hit, or
// drops the first record on a miss. With `defer`, the walk's shadow segments
// are queued there, and `out` is final (and finish_offset() called) only once
// they are resolved.
template <PathHost H>
void complete_offset(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config,
                     const BasicCameraPath<H>& base, const Ray& ray, bool hit, BasicOffsetPath<H>& out,
                     DeferredVisibility<H>* defer = nullptr) {
    if (hit && base.size() > 1) {
        out.v.reserve(base.size());
        BasicOffsetRecord<H>& r1 = out.v[1];
        r1.y.wo = r1.y.si.frame.to_local(-ray.d);
        r1.y.emitted = scene.is_emitter(r1.y.si) ? scene.emitted(r1.y.si, -ray.d) : Color(0.f);
        walk_offset(scene, shift, config, base, out, defer);
    } else {
        out.v.clear();
    }
    if (!defer) finish_offset(base, out);
}

// Continues an offset path whose first hit out.v[1] is set.
template <PathHost H>
void walk_offset(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config, const BasicCameraPath<H>& base,
                 BasicOffsetPath<H>& out, DeferredVisibility<H>* defer) {
    for (size_t k = 1; k < base.size(); ++k) {
        shift_light_connection(scene, config, base, k, out, defer);
        BasicOffsetRecord<H>& rec = out.v[k];
        const BasicVertex<H>& x = base.v[k];
        if (!x.scattered() || k + 1 >= base.size()) return;
        const BasicVertex<H>& next = base.v[k + 1];
        const BasicOffsetVertex<H>& y = rec.y;
        ShiftStep& s = rec.step;
        if (y.on_base) {
            // Reconnected at x_k: same outgoing direction, own incoming one.
            s.wi = x.bs.wi;
            s.jacobian = 1.0;
            bool base_values = false;
            if (x.bs.is_delta()) {
                const auto e = scene.eval_delta(y.si, y.wo, s.wi);
                if (!e) return;
                s.f = e->f, s.pdf = e->pdf, s.delta = true;
            } else if (same_side_values(scene, y, x)) {
                s.f = x.bs.f, s.pdf = x.bs.pdf;  // sample() returns what eval_pdf() would
                base_values = true;              // as did its light sample (shift_light_connection)
            } else {
                const BsdfEval fe = scene.eval_bsdf(y.si, y.wo, s.wi);
                s.f = fe.f, s.pdf = fe.pdf;
            }
            if (is_black(s.f)) return;
            s.kind = ShiftStep::Kind::Direction;
            out.merged_from = k + 1;  // same vertex, same outgoing direction: y is x from here on
            if (base_values) out.base_values_from = k;
            return;
        }
        // The walk tests a reconnection's segment itself (queued, or at
        // once): every traced segment is then counted, blocked or not.
        detail::assign_in_place(s, [&] { return shift.step(BasicShiftStepInput<H>{scene, config, base, k, y}); });
        if (s.kind == ShiftStep::Kind::Fail) return;
        if (s.kind == ShiftStep::Kind::Reconnect) {
            ++out.rays;  // the visibility test of the reconnection
            // Onto the environment the segment leaves along the base's direction, out past the scene.
            Vec3 target = next.si.p;
            if constexpr (EnvironmentHost<H>)
                if (next.infinite) target = scene.beyond_scene(y.si.p, -next.si.ng);
            if (!DeferredVisibility<H>::queued_or_visible(scene, defer, y.si.p, y.si.ng, target, next.si.ng,
                                                       {&out, k, true})) {
                s = ShiftStep{};  // Fail
                return;
            }
            if constexpr (EnvironmentHost<H>) {
                if (next.infinite) {
                    const Ray ray = spawn_ray(y.si, -next.si.ng);
                    BasicOffsetVertex<H>& v = out.v.emplace_back().y;  // out.v may move: `y` and `s` are dead here
                    set_on_environment(scene, ray, v);
                    v.on_base = true;
                    continue;
                }
            }
            const Vec3 from = y.si.p;
            set_on_base(scene, out.v.emplace_back().y, next, from);  // out.v may move: `y` and `s` are dead here
            continue;
        }
        const Ray ray = spawn_ray(y.si, y.si.frame.to_world(s.wi));
        const bool reject_if_connectable = s.reject_if_connectable, reject_if_escapes = s.reject_if_escapes;
        ++out.rays;
        BasicOffsetRecord<H>& nr = out.v.emplace_back();  // invalidates `rec`, `y` and `s`
        const bool hit = scene.intersect(ray, nr.y.si);
        if constexpr (EnvironmentHost<H>)
            if (!hit && scene.environment()) {
                // Left the scene: the offset ends on the environment (its emitter
                // term at k + 1 is all it has from here; its step there stays Fail)
                // unless the inverse would have reconnected there (steps.h).
                if (reject_if_connectable || reject_if_escapes) {
                    out.v.pop_back();
                    out.v[k].step.kind = ShiftStep::Kind::Fail;
                    return;
                }
                set_on_environment(scene, ray, nr.y);
                return;
            }
        if (!hit ||
            (reject_if_connectable &&
             is_connectable(scene.surface(nr.y.si).min_roughness, next.u_classify, config))) {
            // Escaped (no emitter at infinity) or the inverse would have reconnected: no offset beyond.
            out.v.pop_back();
            out.v[k].step.kind = ShiftStep::Kind::Fail;
            return;
        }
        nr.y.wo = nr.y.si.frame.to_local(-ray.d);
        nr.y.emitted = scene.is_emitter(nr.y.si) ? scene.emitted(nr.y.si, -ray.d) : Color(0.f);
    }
}


}  // namespace gdr::detail
