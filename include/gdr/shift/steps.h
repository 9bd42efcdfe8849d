// The building blocks the built-in shift mappings are made of: vertex
// classification, reconnection, half-vector copy and random-number replay.
// Each returns a ShiftStep for the base vertex in.k and offset vertex in.y.
#pragma once

#include <type_traits>

#include "gdr/shift/shift.h"

namespace gdr::shift {

/// Connectability of base vertex i (by its BSDF's roughness and its classification number).
template <class H>
bool base_connectable(const BasicShiftStepInput<H>& in, size_t i) {
    const BasicVertex<H>& x = in.base.v[i];
    // A vertex on the environment is a direction, not a surface (reconnect()
    // copies it; can_reconnect() says when).
    return !x.infinite && is_connectable(in.scene.surface(x.si).min_roughness, x.u_classify, in.config);
}

/// Connectability of the offset vertex y_k (classified with the base's number at the same depth).
template <class H>
bool offset_connectable(const BasicShiftStepInput<H>& in) {
    return !in.y.infinite &&
           is_connectable(in.scene.surface(in.y.si).min_roughness, in.base.v[in.k].u_classify, in.config);
}

/// True if base vertex x_k and offset vertex y_k are both connectable: where
/// light samples are shifted, and where a reconnection may start.
template <class H>
bool both_connectable(const BasicShiftStepInput<H>& in) { return base_connectable(in, in.k) && offset_connectable(in); }

/// True if the base continues to a vertex x_{k+1}.
template <class H>
bool base_has_next(const BasicShiftStepInput<H>& in) { return in.base.v[in.k].scattered() && in.k + 1 < in.base.size(); }

/// True if the base's next vertex x_{k+1} lies on the environment (a direction).
template <class H>
bool base_next_infinite(const BasicShiftStepInput<H>& in) { return base_has_next(in) && in.base.v[in.k + 1].infinite; }

/// True if reconnecting y_k -> x_{k+1} is allowed: x_k and y_k are connectable,
/// and x_{k+1} is too or lies on the environment.
template <class H>
bool can_reconnect(const BasicShiftStepInput<H>& in) {
    return base_has_next(in) && both_connectable(in) && (base_next_infinite(in) || base_connectable(in, in.k + 1));
}

/// Reconnection y_k -> x_{k+1} (Kettunen et al., "Gradient-Domain Path
/// Tracing", 2015): fails if the segment arrives from the other side of
/// x_{k+1}'s surface or carries no throughput; whether it is blocked is the
/// caller's test (ShiftStep::Kind::Reconnect).
/// |J| = |cos_y| ||x_k - x_{k+1}||^2 / (|cos_x| ||y_k - x_{k+1}||^2), cosines at x_{k+1}.
/// A vertex x_{k+1} on the environment is infinitely far: the offset leaves
/// y_k along the base's own direction, |J| = 1 in solid angle, and the
/// caller tests that it escapes. That is how the environment's light sample
/// at x_k is shifted too (by direction), and the gradients' MIS weights
/// combine the two strategies of a path ending on the environment only if
/// both shift it alike: with a half-vector or replayed direction for the
/// BSDF-sampled escape, E[dx] on an environment-lit box was off by up to
/// 6.5 standard errors once the map's radiance varied between neighbouring
/// directions (tests/test_environment.cpp).
template <PathHost H>
ShiftStep reconnect(const BasicShiftStepInput<H>& in);

/// Half-vector copy (Kettunen et al., "Gradient-Domain Path Tracing" (2015)): the offset keeps the base's half-vector in its local
/// frame (reflection, or generalised half-vector for refraction); delta lobes
/// map to delta lobes with J = 1. Fails on mismatched lobes, total internal
/// reflection, or a direction on the wrong side.
template <PathHost H>
ShiftStep half_vector(const BasicShiftStepInput<H>& in);

/// Random-number replay: the offset samples its BSDF with the base's numbers;
/// J = pdf_x / pdf_y. Fails if the offset's sample is missing or of another
/// kind (delta vs non-delta).
template <PathHost H>
ShiftStep replay(const BasicShiftStepInput<H>& in);

/// The pattern of the survey's shifts: reconnect as soon as x_k, y_k and x_{k+1}
/// are connectable (x_{k+1} on the environment counts as connectable),
/// otherwise take `fallback`'s own direction. When only x_{k+1} prevented the
/// reconnection, the step is marked reject_if_connectable: the inverse would
/// reconnect at a connectable y_{k+1} or at one on the environment, so T must
/// not go there.
template <PathHost H>
ShiftStep reconnect_or(const BasicShiftStepInput<H>& in,
                       std::type_identity_t<ShiftStep (*)(const BasicShiftStepInput<H>&)> fallback);

// The definitions; gdr's own Scene's are compiled once, in the library.

template <PathHost H>
ShiftStep reconnect(const BasicShiftStepInput<H>& in) {
    // Every exit returns `s` (Fail until all tests pass), so that it is built
    // in the caller's slot: a local copied out on return was written field by
    // field and reloaded 16 bytes at a time, stalling store forwarding.
    ShiftStep s;
    const BasicVertex<H>& x = in.base.v[in.k];
    const BasicVertex<H>& next = in.base.v[in.k + 1];
    const typename H::Interaction& y = in.y.si;
    if (next.infinite) {
        // x_{k+1}.ng is the direction light travels: towards x_k.
        const Vec3 wi = y.frame.to_local(-next.si.ng);
        const BsdfEval fe = in.scene.eval_bsdf(y, in.y.wo, wi);
        if (is_black(fe.f)) return s;
        s.kind = ShiftStep::Kind::Reconnect;
        s.wi = wi, s.f = fe.f, s.pdf = fe.pdf, s.jacobian = 1.0, s.delta = false;
        return s;
    }
    // Distances and cosines in double: the Jacobian is a ratio of nearly equal quantities.
    const Vec3d pn(next.si.p), ng(next.si.ng);
    const Vec3d dx = Vec3d(x.si.p) - pn, dy = Vec3d(y.p) - pn;
    const double lx2 = glm::dot(dx, dx), ly2 = glm::dot(dy, dy);
    if (!(lx2 > 0.0) || !(ly2 > 0.0)) return s;
    const double lx = std::sqrt(lx2), ly = std::sqrt(ly2);
    // At a point or spot light the cosine is 1 from everywhere (LightSample's convention).
    const bool point = next.delta_light != nullptr;
    const double dot_x = point ? lx : glm::dot(dx, ng), dot_y = point ? ly : glm::dot(dy, ng);  // cosines at `next` times the distances
    // Arriving from the other side of the surface would be another kind of path.
    if (!(dot_x * dot_y > 0.0)) return s;
    // The Jacobian |cos_y| lx^2 / (|cos_x| ly^2) = |dot_y| lx^3 / (|dot_x| ly^3)
    // and 1/ly from one division (there were six, then two).
    const double inv_d = 1.0 / (std::abs(dot_x) * ly2 * ly);
    const double inv_ly = std::abs(dot_x) * ly2 * inv_d;
    const Vec3 wi_world = Vec3(-dy * inv_ly);
    const Vec3 wi = y.frame.to_local(wi_world);
    const BsdfEval fe = in.scene.eval_bsdf(y, in.y.wo, wi);
    if (is_black(fe.f)) return s;
    s.kind = ShiftStep::Kind::Reconnect;
    s.wi = wi;
    s.f = fe.f;
    s.pdf = fe.pdf;
    s.jacobian = std::abs(dot_y) * (lx2 * lx) * inv_d;
    s.delta = false;
    return s;
}

template <PathHost H>
ShiftStep half_vector(const BasicShiftStepInput<H>& in) {
    const BasicVertex<H>& x = in.base.v[in.k];
    const Vec3 wo_x = x.si.frame.to_local(x.wo);
    const Vec3& wo_y = in.y.wo;
    // Both paths must arrive from the same side (for dielectrics: the same medium).
    if (wo_x.z * wo_y.z <= 0.f) return ShiftStep{};
    const bool reflect_lobe = (x.bs.lobe & kReflection) != 0;
    ShiftStep s;
    s.kind = ShiftStep::Kind::Direction;

    if (x.bs.is_delta()) {
        if (reflect_lobe) {
            s.wi = Vec3(-wo_y.x, -wo_y.y, wo_y.z);
        } else {
            const Vec3 n(0.f, 0.f, wo_y.z > 0.f ? 1.f : -1.f);
            if (!refract(wo_y, n, x.bs.eta, s.wi)) return ShiftStep{};
        }
        const auto e = in.scene.eval_delta(in.y.si, wo_y, s.wi);
        if (!e || is_black(e->f) || !(e->pdf > 0.f)) return ShiftStep{};
        s.f = e->f, s.pdf = e->pdf, s.delta = true, s.jacobian = 1.0;
        return s;
    }
    if (in.scene.surface(in.y.si).pure_delta) return ShiftStep{};  // a smooth lobe cannot map onto a delta one

    if (reflect_lobe) {
        const Vec3d h = glm::normalize(Vec3d(wo_x) + Vec3d(x.bs.wi));
        const Vec3d wo(wo_y);
        const Vec3d wi = 2.0 * glm::dot(wo, h) * h - wo;
        if (wi.z * wo.z <= 0.0) return ShiftStep{};
        const double dx = std::abs(glm::dot(Vec3d(wo_x), h));
        if (!(dx > 0.0)) return ShiftStep{};
        s.jacobian = std::abs(glm::dot(wo, h)) / dx;
        s.wi = Vec3(glm::normalize(wi));
    } else {
        // Generalised half-vector h = wo + eta * wi (Walter et al. 2007), eta relative to wo's side.
        const double eta = x.bs.eta;
        const Vec3d hx = Vec3d(wo_x) + eta * Vec3d(x.bs.wi);
        const double lx = glm::length(hx);
        if (!(lx > 1e-9)) return ShiftStep{};
        Vec3d m = hx / lx;
        const Vec3d wo(wo_y);
        if (glm::dot(m, wo) < 0.0) m = -m;
        const double cos_i = glm::dot(m, wo);
        const double sin2_t = std::max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
        if (sin2_t >= 1.0) return ShiftStep{};  // total internal reflection
        const Vec3d wi = -wo / eta + (cos_i / eta - std::sqrt(1.0 - sin2_t)) * m;
        if (wi.z * wo.z >= 0.0) return ShiftStep{};
        const Vec3d hy = wo + eta * wi;
        const double dot_y = std::abs(glm::dot(glm::normalize(wi), m));
        if (!(dot_y > 0.0)) return ShiftStep{};
        s.jacobian = (glm::dot(hy, hy) / (lx * lx)) * (std::abs(glm::dot(Vec3d(x.bs.wi), m)) / dot_y);
        s.wi = Vec3(glm::normalize(wi));
    }
    const BsdfEval fe = in.scene.eval_bsdf(in.y.si, wo_y, s.wi);
    s.f = fe.f, s.pdf = fe.pdf;
    if (is_black(s.f)) return ShiftStep{};
    s.delta = false;
    return s;
}

template <PathHost H>
ShiftStep replay(const BasicShiftStepInput<H>& in) {
    const BasicVertex<H>& x = in.base.v[in.k];
    const auto bs = in.scene.sample_bsdf(in.y.si, in.y.wo, x.u_lobe, x.u_dir);
    if (!bs || !(bs->pdf > 0.f) || is_black(bs->f) || bs->is_delta() != x.bs.is_delta()) return ShiftStep{};
    ShiftStep s;
    s.kind = ShiftStep::Kind::Direction;
    s.wi = bs->wi;
    s.f = bs->f;
    s.pdf = bs->pdf;
    s.delta = bs->is_delta();
    // Replay maps primary samples identically, so the offset's density in the
    // base's measure equals the base's: J = pdf_x / pdf_y.
    s.jacobian = double(x.bs.pdf) / double(bs->pdf);
    s.sample_space = true;
    return s;
}

template <PathHost H>
ShiftStep reconnect_or(const BasicShiftStepInput<H>& in,
                       std::type_identity_t<ShiftStep (*)(const BasicShiftStepInput<H>&)> fallback) {
    if (!base_has_next(in)) return ShiftStep{};
    const bool both = both_connectable(in);
    if (both && (base_next_infinite(in) || base_connectable(in, in.k + 1))) return reconnect(in);
    ShiftStep s = fallback(in);
    s.reject_if_connectable = both;
    return s;
}

extern template ShiftStep reconnect(const ShiftStepInput&);
extern template ShiftStep half_vector(const ShiftStepInput&);
extern template ShiftStep replay(const ShiftStepInput&);
extern template ShiftStep reconnect_or(const ShiftStepInput&, ShiftStep (*)(const ShiftStepInput&));

}  // namespace gdr::shift
