// The camera side of bidirectional shifts (see gdr/shift/bidir.h).
#include "gdr/shift/bidir.h"

namespace gdr {

void shift_camera_subpath(const Scene& scene, const Shift& shift, const ShiftConfig& config, const CameraPath& x,
                          const Vec2& delta, CameraOffset& o, uint64_t& rays) {
    o.p.mode = TransportMode::Radiance;
    o.p.v.clear(), o.y.clear(), o.r.clear(), o.steps.clear();
    o.b = kNoDepth, o.blocked = false, o.merged = kNoDepth;
    if (x.size() < 2) return;
    const Ray ray = scene.camera().generate_ray(x.film + delta);
    ++rays;
    OffsetVertex y1;
    if (!scene.intersect(ray, y1.si)) return;
    y1.wo = y1.si.frame.to_local(-ray.d);
    o.p.v.push_back(x.v[0]);
    o.y.emplace_back();
    o.r.push_back(1.0);
    o.steps.emplace_back();
    {
        Vertex& v = o.p.v.emplace_back();
        v.si = y1.si, v.wo = -ray.d, v.beta = x.v[1].beta;
        v.u_light = x.v[1].u_light, v.u_classify = x.v[1].u_classify;
        v.u_lobe = x.v[1].u_lobe, v.u_dir = x.v[1].u_dir;
    }
    o.y.push_back(y1);
    o.r.push_back(1.0);
    o.steps.emplace_back();
    for (size_t k = 1; k + 1 < x.size(); ++k) {
        const Vertex& xk = x.v[k];
        if (!xk.scattered()) break;
        const Vertex& next = x.v[k + 1];
        const OffsetVertex yk = o.y[k];
        ShiftStep s;
        if (yk.on_base) {
            // y_k is x_k entered from elsewhere: it leaves along the base's direction (|J| = 1).
            const Bsdf& bsdf = *yk.si.material->bsdf;
            s.kind = ShiftStep::Kind::Direction, s.wi = xk.bs.wi, s.jacobian = 1.0;
            if (xk.bs.is_delta()) {
                const auto e = bsdf.eval_delta(yk.wo, s.wi, yk.si.uv);
                if (!e) break;
                s.f = e->f, s.pdf = e->pdf, s.delta = true;
            } else {
                const BsdfEval fe = bsdf.eval_pdf(yk.wo, s.wi, yk.si.uv);
                s.f = fe.f, s.pdf = fe.pdf;
            }
            if (is_black(s.f) || !(s.pdf > 0.f)) break;
        } else {
            s = shift.step(ShiftStepInput{scene, config, x, k, yk});
            if (s.kind == ShiftStep::Kind::Fail) break;
        }
        const double inv_pdf = 1.0 / double(xk.bs.pdf);
        Color beta = o.p.v[k].beta * s.f * float(abs_cos_theta(s.wi) * s.jacobian * inv_pdf / xk.rr_survival);
        const double r = o.r[k] * double(s.pdf) * s.jacobian * inv_pdf;
        o.p.v[k].delta = s.delta;
        o.steps[k] = s;
        if (yk.on_base) {
            // Same vertex, same outgoing direction: y is x from x_{k+1} on.
            o.merged = int(k) + 1;
            for (size_t j = k + 1; j < x.size(); ++j) {
                Vertex v = x.v[j];
                v.beta = beta;
                o.p.v.push_back(v);
                o.y.emplace_back();
                o.r.push_back(r);
                o.steps.emplace_back();
                if (!x.v[j].scattered()) break;
                beta *= scatter_weight(x.v[j]);
            }
            break;
        }
        OffsetVertex ny;
        Vertex v;
        if (s.kind == ShiftStep::Kind::Reconnect) {
            o.b = int(k);
            ++rays;
            o.blocked = !scene.visible(yk.si.p, yk.si.ng, next.si.p, next.si.ng);
            const Vec3 w = glm::normalize(yk.si.p - next.si.p);
            ny.si = next.si, ny.on_base = true, ny.wo = next.si.frame.to_local(w);
            v = next;
            v.wo = w;
        } else {
            const Ray r2 = spawn_ray(yk.si, yk.si.frame.to_world(s.wi));
            ++rays;
            if (!scene.intersect(r2, ny.si)) break;
            // The inverse would have reconnected at a connectable y_{k+1}.
            if (s.reject_if_connectable && is_connectable(ny.si.material->min_roughness, next.u_classify, config))
                break;
            ny.wo = ny.si.frame.to_local(-r2.d);
            v.si = ny.si, v.wo = -r2.d;
            v.u_light = next.u_light, v.u_classify = next.u_classify;
            v.u_lobe = next.u_lobe, v.u_dir = next.u_dir;  // the offset replays x's numbers at its depth
        }
        v.type = VertexType::Surface;
        v.beta = beta;
        v.delta = false;
        o.p.v.push_back(v);
        o.y.push_back(ny);
        o.r.push_back(r);
        o.steps.emplace_back();
    }
    // The offset's own densities, as its walk would have recorded them (a
    // delta step has none, as in walk_subpath).
    // Past the merge the densities are x's: the vertices they read are x's.
    std::vector<Vertex>& v = o.p.v;
    const size_t fwd_own = o.merged == kNoDepth ? v.size() : size_t(o.merged) + 1;
    const size_t rev_own = o.merged == kNoDepth ? v.size() : size_t(o.merged) - 1;
    for (size_t k = 1; k < v.size() && k < fwd_own; ++k)
        v[k].pdf_fwd = k >= 2 && v[k - 1].delta ? 0.0 : pdf_area(scene, k >= 2 ? &v[k - 2] : nullptr, v[k - 1], v[k]);
    for (size_t k = 0; k + 2 < v.size() && k < rev_own; ++k)
        v[k].pdf_rev = v[k + 1].delta ? 0.0 : pdf_area(scene, &v[k + 2], v[k + 1], v[k]);
}


ShiftStep shift_onto(const Scene& scene, const Shift& shift, const ShiftConfig& config, const Vertex* prefix, int k,
                     const Vertex& next, const OffsetVertex& y, CameraPath& b) {
    b.v.assign(prefix, prefix + k + 1);
    Vertex& xk = b.v[size_t(k)];
    if (!xk.scattered()) {
        // The camera walk stopped at x_k: only a reconnection reads this step, and it needs positions only.
        xk.bs = BsdfSample{};
        xk.bs.pdf = 1.f;
    }
    Vertex& nx = b.v.emplace_back(next);
    // Light vertices carry no material; the shift classifies the emitter's.
    if (nx.type == VertexType::Light) nx.si.material = &scene.materials()[scene.mesh().material_ids[next.si.prim]];
    nx.type = VertexType::Surface;
    b.nee.resize(b.v.size());
    return shift.step(ShiftStepInput{scene, config, b, size_t(k), y});
}

Vertex camera_side_vertex(const Vertex& q, const Vertex& towards, const Vertex& away) {
    Vertex v = q;
    v.type = VertexType::Surface;
    v.wo = glm::normalize(towards.si.p - q.si.p);
    v.bs = BsdfSample{};
    v.bs.wi = q.si.frame.to_local(glm::normalize(away.si.p - q.si.p));
    v.bs.pdf = 1.f;
    v.bs.lobe = v.bs.wi.z * q.si.frame.to_local(v.wo).z > 0.f ? kReflection : kTransmission;
    v.rr_survival = 1.f;
    return v;
}

}  // namespace gdr
