#include "gdr/shift/steps.h"

namespace gdr::shift {

namespace {
ShiftStep fail() { return ShiftStep{}; }
}  // namespace

ShiftStep reconnect(const ShiftStepInput& in) {
    // Every exit returns `s` (Fail until all tests pass), so that it is built
    // in the caller's slot: a local copied out on return was written field by
    // field and reloaded 16 bytes at a time, stalling store forwarding.
    ShiftStep s;
    const Vertex& x = in.base.v[in.k];
    const Vertex& next = in.base.v[in.k + 1];
    const SurfaceInteraction& y = in.y.si;
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
    const Bsdf& bsdf = *y.material->bsdf;
    const BsdfEval fe = bsdf.eval_pdf(in.y.wo, wi, y.uv);
    if (is_black(fe.f)) return s;
    if (in.defer_visibility)
        s.visibility_deferred = true;
    else if (!in.scene.visible(y.p, y.ng, next.si.p, point ? Vec3(0.f) : next.si.ng))
        return s;
    s.kind = ShiftStep::Kind::Reconnect;
    s.wi = wi;
    s.f = fe.f;
    s.pdf = fe.pdf;
    s.jacobian = std::abs(dot_y) * (lx2 * lx) * inv_d;
    s.delta = false;
    return s;
}

ShiftStep half_vector(const ShiftStepInput& in) {
    const Vertex& x = in.base.v[in.k];
    const Vec3 wo_x = x.si.frame.to_local(x.wo);
    const Vec3& wo_y = in.y.wo;
    const Bsdf& bsdf = *in.y.si.material->bsdf;
    // Both paths must arrive from the same side (for dielectrics: the same medium).
    if (wo_x.z * wo_y.z <= 0.f) return fail();
    const bool reflect_lobe = (x.bs.lobe & kReflection) != 0;
    ShiftStep s;
    s.kind = ShiftStep::Kind::Direction;

    if (x.bs.is_delta()) {
        if (reflect_lobe) {
            s.wi = Vec3(-wo_y.x, -wo_y.y, wo_y.z);
        } else {
            const Vec3 n(0.f, 0.f, wo_y.z > 0.f ? 1.f : -1.f);
            if (!refract(wo_y, n, x.bs.eta, s.wi)) return fail();
        }
        const auto e = bsdf.eval_delta(wo_y, s.wi, in.y.si.uv);
        if (!e || is_black(e->f) || !(e->pdf > 0.f)) return fail();
        s.f = e->f, s.pdf = e->pdf, s.delta = true, s.jacobian = 1.0;
        return s;
    }
    if (in.y.si.material->pure_delta) return fail();  // a smooth lobe cannot map onto a delta one

    if (reflect_lobe) {
        const Vec3d h = glm::normalize(Vec3d(wo_x) + Vec3d(x.bs.wi));
        const Vec3d wo(wo_y);
        const Vec3d wi = 2.0 * glm::dot(wo, h) * h - wo;
        if (wi.z * wo.z <= 0.0) return fail();
        const double dx = std::abs(glm::dot(Vec3d(wo_x), h));
        if (!(dx > 0.0)) return fail();
        s.jacobian = std::abs(glm::dot(wo, h)) / dx;
        s.wi = Vec3(glm::normalize(wi));
    } else {
        // Generalised half-vector h = wo + eta * wi (Walter et al. 2007), eta relative to wo's side.
        const double eta = x.bs.eta;
        const Vec3d hx = Vec3d(wo_x) + eta * Vec3d(x.bs.wi);
        const double lx = glm::length(hx);
        if (!(lx > 1e-9)) return fail();
        Vec3d m = hx / lx;
        const Vec3d wo(wo_y);
        if (glm::dot(m, wo) < 0.0) m = -m;
        const double cos_i = glm::dot(m, wo);
        const double sin2_t = std::max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
        if (sin2_t >= 1.0) return fail();  // total internal reflection
        const Vec3d wi = -wo / eta + (cos_i / eta - std::sqrt(1.0 - sin2_t)) * m;
        if (wi.z * wo.z >= 0.0) return fail();
        const Vec3d hy = wo + eta * wi;
        const double dot_y = std::abs(glm::dot(glm::normalize(wi), m));
        if (!(dot_y > 0.0)) return fail();
        s.jacobian = (glm::dot(hy, hy) / (lx * lx)) * (std::abs(glm::dot(Vec3d(x.bs.wi), m)) / dot_y);
        s.wi = Vec3(glm::normalize(wi));
    }
    const BsdfEval fe = bsdf.eval_pdf(wo_y, s.wi, in.y.si.uv);
    s.f = fe.f, s.pdf = fe.pdf;
    if (is_black(s.f)) return fail();
    s.delta = false;
    return s;
}

ShiftStep replay(const ShiftStepInput& in) {
    const Vertex& x = in.base.v[in.k];
    const Bsdf& bsdf = *in.y.si.material->bsdf;
    const auto bs = bsdf.sample(in.y.wo, in.y.si.uv, x.u_lobe, x.u_dir);
    if (!bs || !(bs->pdf > 0.f) || is_black(bs->f) || bs->is_delta() != x.bs.is_delta()) return fail();
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

ShiftStep reconnect_or(const ShiftStepInput& in, ShiftStep (*fallback)(const ShiftStepInput&)) {
    if (!base_has_next(in)) return fail();
    const bool both = base_connectable(in, in.k) && offset_connectable(in);
    if (both && base_connectable(in, in.k + 1)) return reconnect(in);
    ShiftStep s = fallback(in);
    s.reject_if_connectable = both;
    return s;
}

}  // namespace gdr::shift
