// The shift validator on bidirectional paths: what gbdpt adds to a shift
// mapping's work. A base path is a camera subpath joined to a light subpath
// by a strategy (s >= 1); its offset follows the camera side as
// shift_camera_subpath() walks it and reconnects at the latest at the
// connection itself (shift_onto()), or, for light tracing (t = 1), shifts
// the film point of the light vertex the camera sees.
#include <algorithm>
#include <optional>

#include "gdr/core/sampler.h"
#include "gdr/path/dims.h"
#include "gdr/path/environment.h"
#include "gdr/shift/bidir.h"
#include "gdr/shift/validate.h"
#include "validate_report.h"

namespace gdr {

namespace {

// Solid-angle area spanned by central differences of a direction (first order).
double spanned(const Vec3d w[4]) { return glm::length(glm::cross(w[0] - w[1], w[2] - w[3])); }

// Finite-difference |d omega_y / d omega_x| of the directions from x and
// from y to a point moved in the tangent plane (normal n) of point p.
std::optional<double> fd_reconnection(const Vec3& p, const Vec3& n, const Vec3& x, const Vec3& y, float eps) {
    const Vec3d pd(p), nd(n), xd(x), yd(y);
    for (const Vec3d& q : {xd, yd})
        if (!(std::abs(glm::dot(nd, glm::normalize(q - pd))) > 1e-4)) return std::nullopt;  // edge-on: rounding
    const Frame f(n);
    const double h = double(eps) * glm::length(pd - xd);
    const Vec3d d[4] = {h * Vec3d(f.s), -h * Vec3d(f.s), h * Vec3d(f.t), -h * Vec3d(f.t)};
    Vec3d wx[4], wy[4];
    for (int i = 0; i < 4; ++i) wx[i] = glm::normalize(pd + d[i] - xd), wy[i] = glm::normalize(pd + d[i] - yd);
    const double ax = spanned(wx);
    if (!(ax > 0.0)) return std::nullopt;
    return spanned(wy) / ax;
}

// Finite-difference |dA(y_1) / dA(x_1)| of light tracing's film shift: x_1
// moved in its tangent plane, each moved point's film position displaced by
// `delta` and traced again.
std::optional<double> fd_film_shift(const Scene& scene, const Vertex& x1, const Vec2& delta, uint32_t prim_y, float eps) {
    const Camera& cam = scene.camera();
    const Frame f(x1.si.ng);
    const double h = double(eps) * glm::length(x1.si.p - cam.position());
    const Vec3 d[4] = {float(h) * f.s, -float(h) * f.s, float(h) * f.t, -float(h) * f.t};
    Vec3d px[4], py[4];
    for (int i = 0; i < 4; ++i) {
        const Vec3 q = x1.si.p + d[i];
        Vec2 film;
        if (!(cam.importance(glm::normalize(q - cam.position()), film) > 0.f)) return std::nullopt;
        SurfaceInteraction hit;
        if (!scene.intersect(cam.generate_ray(film + delta), hit) || hit.prim != prim_y) return std::nullopt;
        px[i] = Vec3d(q), py[i] = Vec3d(hit.p);
    }
    const double ax = glm::length(glm::cross(px[0] - px[1], px[2] - px[3]));
    if (!(ax > 0.0)) return std::nullopt;
    return glm::length(glm::cross(py[0] - py[1], py[2] - py[3])) / ax;
}

template <typename F>
std::optional<double> richardson(float eps, F&& fd) {
    const auto a = fd(eps), b = fd(0.5f * eps);
    if (!a || !b) return std::nullopt;
    return (4.0 * *b - *a) / 3.0;
}

// The camera side of offset y up to depth m, as a camera walk would have
// recorded it: the base path of the inverse shift.
CameraPath offset_as_base(const CameraPath& x, const CameraOffset& y, int m, const Vec2& delta) {
    CameraPath p;
    p.film = x.film + delta;
    for (int k = 0; k <= m; ++k) {
        Vertex v = y.p.v[size_t(k)];
        if (k >= 1 && k < m && k < y.merged) {
            const ShiftStep& s = y.steps[size_t(k)];
            v.bs = step_as_sample(s, v.si.frame.to_local(v.wo), x.v[size_t(k)].bs);
            v.delta = s.delta;
        }
        p.v.push_back(v);
    }
    p.nee.resize(p.v.size());
    return p;
}

}  // namespace

ShiftReport validate_bidirectional_shift(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                                         const ValidateOptions& o) {
    ShiftReport rep;
    rep.shift = shift.name() + " (bidirectional)";
    rep.bidirectional = true;
    require_no_environment(scene, "the bidirectional shift validator (check-shift --integrator gbdpt)");
    if (!scene.delta_lights().empty())
        throw ParameterError("the bidirectional shift validator (check-shift --integrator gbdpt): scenes with point, spot "
                             "or directional lights are not supported yet (its finite differences move a light point on "
                             "an emitter's surface); check-shift --integrator gpt validates their light connections");
    const int W = scene.camera().width(), H = scene.camera().height();
    if (W < 3) throw ParameterError("validate_bidirectional_shift: the image must be at least 3 pixels wide");
    if (!scene.has_lights()) throw ParameterError("validate_bidirectional_shift: the scene has no emitter");
    const Vec2 right(1.f, 0.f);
    const double tol = o.position_tolerance * scene.bounding_radius();
    std::vector<double> errors;
    const auto check_jacobian = [&](double analytic, const std::optional<double>& fd) {
        if (!fd || !(analytic > 0.0)) return;
        const double e = std::abs(analytic / *fd - 1.0);
        errors.push_back(e);
        rep.jacobian_checked++;
        rep.jacobian_ok += e <= o.jacobian_tolerance;
    };
    CameraPath x, scratch, scratch2;
    Subpath light, first;
    CameraOffset y, back;
    WalkOptions copt, lopt;
    copt.max_vertices = o.max_depth;
    copt.rr_depth = lopt.rr_depth = 1 << 20;  // roulette changes nothing a shift does; keep paths long
    lopt.max_vertices = o.max_depth > 0 ? o.max_depth - 1 : -1;
    uint64_t rays = 0;
    for (int i = 0; i < o.paths; ++i) {
        Sampler pick(SampleKey{o.seed ^ 0xb1d1ull, 0, 0, uint32_t(i)});
        const int px = std::min(W - 2, int(pick.next1d() * float(W - 1)));
        const int py = std::min(H - 1, int(pick.next1d() * float(H)));
        Sampler s(SampleKey{o.seed, uint32_t(px), uint32_t(py), uint32_t(i)});
        const Vec2 film = Vec2(float(px), float(py)) + s.at2(dims::kFilm);
        trace_camera_subpath(scene, film, s, copt, x);
        x.film = film;
        x.nee.assign(x.v.size(), LightConnection{});
        trace_light_subpath(scene, s, lopt, light);
        ++rep.sampled;
        // One connection strategy at random: t camera vertices, s >= 2 light
        // vertices (s = 1's own light point is a light vertex like any other
        // here), both ends connectable surfaces.
        if (light.size() < 2) continue;
        const int t = int(pick.next1d() * float(x.size()));  // 0 .. size - 1: t = 0 stands for light tracing
        const int sv = 2 + std::min(light.size() - 2, int(pick.next1d() * float(light.size() - 1)));
        const Vertex& q = light.v[size_t(sv - 1)];
        if (!connectible(scene, q)) continue;
        if (t >= 2) {
            const Vertex& pt = x.v[size_t(t - 1)];
            if (pt.infinite || !connectible(scene, pt)) continue;
            ++rep.base_paths;
            shift_camera_subpath(scene, shift, config, x, right, y, rays);
            if (y.size() < t) continue;
            if (y.b <= t - 2) {
                // Reconnected inside the camera subpath: the gpt validator's steps.
                if (y.blocked) continue;
                ++rep.complete;
            } else {
                const ShiftStep st = shift_onto(scene, shift, config, x.v.data(), t - 1, q, y.y[size_t(t - 1)], scratch);
                if (st.kind != ShiftStep::Kind::Reconnect) continue;
                ++rep.complete;
                const Vec3 yp = y.p.v[size_t(t - 1)].si.p;
                check_jacobian(st.jacobian, richardson(o.fd_step, [&](float e) {
                                   return fd_reconnection(q.si.p, q.si.ng, pt.si.p, yp, e);
                               }));
            }
            // Shift back from y's camera side: the camera part of x again.
            const int m = std::min(t - 1, y.size() - 1);
            const CameraPath ybf = offset_as_base(x, y, m, right);
            ++rep.reverse_checked;
            shift_camera_subpath(scene, shift, config, ybf, -right, back, rays);
            if (back.size() < t || (y.b > t - 2 && back.b <= t - 2)) {
                ++rep.reverse_failed_shift;
                continue;
            }
            if (y.b > t - 2) {
                const ShiftStep bs =
                    shift_onto(scene, shift, config, ybf.v.data(), t - 1, q, back.y[size_t(t - 1)], scratch2);
                if (bs.kind != ShiftStep::Kind::Reconnect) {
                    ++rep.reverse_failed_shift;
                    continue;
                }
            }
            bool same = true;
            for (int k = 1; k < t; ++k) same &= glm::length(back.p.v[size_t(k)].si.p - x.v[size_t(k)].si.p) <= tol;
            rep.reverse_ok += same;
        } else {
            // Light tracing: the camera sees q; its neighbour's film point, reconnected to the next light vertex.
            Vec2 fx;
            const Vec3 to_eye = x.v[0].si.p - q.si.p;
            if (!(scene.camera().importance(-glm::normalize(to_eye), fx) > 0.f)) continue;
            if (!scene.visible(q.si.p, q.si.ng, x.v[0].si.p, Vec3(0.f))) continue;
            if (!(fx.x + 1.f < float(W))) continue;
            ++rep.base_paths;
            const Vertex& z2 = light.v[size_t(sv - 2)];
            trace_camera_subpath(scene, scene.camera().generate_ray(fx + right), s, WalkOptions{1, 5}, first);
            if (first.size() < 2) continue;
            const Vertex prefix[2] = {x.v[0], camera_side_vertex(q, x.v[0], z2)};
            OffsetVertex y1;
            y1.si = first.v[1].si;
            y1.wo = y1.si.frame.to_local(first.v[1].wo);
            const ShiftStep st = shift_onto(scene, shift, config, prefix, 1, z2, y1, scratch);
            if (st.kind != ShiftStep::Kind::Reconnect) continue;
            ++rep.complete;
            // The film shift's area Jacobian as gbdpt computes it: the camera's densities of x_1 and y_1.
            const double jx = pdf_area(scene, nullptr, x.v[0], q), jy = pdf_area(scene, nullptr, x.v[0], first.v[1]);
            check_jacobian(jx / jy, richardson(o.fd_step, [&](float e) {
                               return fd_film_shift(scene, q, right, first.v[1].si.prim, e);
                           }));
            check_jacobian(st.jacobian, richardson(o.fd_step, [&](float e) {
                               return fd_reconnection(z2.si.p, z2.si.ng, q.si.p, y1.si.p, e);
                           }));
            // Back: the ray through y_1's film point minus one pixel sees x_1 again.
            ++rep.reverse_checked;
            SurfaceInteraction hit;
            if (!scene.intersect(scene.camera().generate_ray(fx), hit)) {
                ++rep.reverse_failed_shift;
                continue;
            }
            OffsetVertex yx;
            yx.si = hit;
            yx.wo = hit.frame.to_local(glm::normalize(x.v[0].si.p - hit.p));
            const Vertex back_prefix[2] = {x.v[0], camera_side_vertex(first.v[1], x.v[0], z2)};
            if (shift_onto(scene, shift, config, back_prefix, 1, z2, yx, scratch2).kind != ShiftStep::Kind::Reconnect) {
                ++rep.reverse_failed_shift;
                continue;
            }
            rep.reverse_ok += glm::length(hit.p - q.si.p) <= tol;
        }
    }
    finish_report(rep, errors, o);
    return rep;
}

}  // namespace gdr
