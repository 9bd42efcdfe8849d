// A validator for shift mappings: samples base paths of a scene, shifts them
// to the right-hand neighbour and checks what every shift must satisfy:
// failures are counted, shifting back returns the base path, and the
// analytic Jacobian of every step matches a finite-difference one.
#pragma once

#include <string>

#include <algorithm>
#include <bit>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

#include "gdr/core/error.h"
#include "gdr/core/sampler.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/shift/offset_path.h"
#include "gdr/shift/shift.h"

namespace gdr {

/// What and how much to check.
struct ValidateOptions {
    int paths = 20000;              ///< Base paths to sample.
    uint64_t seed = 1;              ///< Sampler seed.
    int max_depth = 8;              ///< Longest base path (segments).
    double position_tolerance = 1e-3;  ///< Reversibility: allowed vertex distance, relative to the scene's radius.
    double jacobian_tolerance = 0.02;  ///< Allowed relative error of an analytic Jacobian.
    float fd_step = 2e-4f;          ///< Central-difference step in primary-sample space.
    double required_fraction = 0.99;   ///< Share of checks that must pass.
};

/// The outcome of validating one shift on one scene.
struct ShiftReport {
    std::string shift;                 ///< Name of the shift.
    size_t sampled = 0;                ///< Camera paths sampled (ValidateOptions::paths).
    size_t base_paths = 0;             ///< ...with at least two vertices: the ones a shift can act on.
    size_t complete = 0;               ///< Offsets as long as their base path (the shift never failed).
    size_t reverse_checked = 0;        ///< Complete offsets shifted back.
    size_t reverse_ok = 0;             ///< ...that returned to their base path.
    size_t reverse_failed_shift = 0;   ///< ...whose inverse shift failed instead (a mismatch of conditions).
    size_t jacobian_checked = 0;       ///< Steps whose Jacobian was compared with finite differences.
    size_t jacobian_ok = 0;            ///< ...within tolerance.
    size_t jacobian_skipped = 0;       ///< Replay steps at multi-lobe BSDFs (density-ratio Jacobians, see ShiftStep).
    double jacobian_median_error = 0.0;   ///< Median relative error of the analytic Jacobians.
    double jacobian_worst_error = 0.0;    ///< Largest relative error seen.
    bool passed = false;               ///< All checks passed at the required fraction.
    /// Base paths join a camera and a light subpath (validate_bidirectional_shift).
    bool bidirectional = false;

    /// Share of base paths whose shift failed somewhere (in [0,1]).
    double failure_rate() const { return base_paths ? 1.0 - double(complete) / double(base_paths) : 0.0; }
    /// A human-readable report ending in one PASS/FAIL line.
    std::string summary() const;
};

/// Validates `shift` on `scene`, gdr's Scene or any other host (see
/// ShiftReport for what is measured). Scenes with an environment light are
/// refused (InputError).
template <PathHost H>
ShiftReport validate_shift(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config,
                           const ValidateOptions& options = {});

/// Validates `shift` as gbdpt applies it (gdr/shift/bidir.h), on paths that
/// join a camera subpath to a light subpath: each sample picks one
/// connection strategy (light tracing included), shifts it to the right-hand
/// neighbour, counts undefined offsets as failures, shifts the offset back,
/// and compares the Jacobians the bidirectional shift adds (a reconnection
/// onto a light-side vertex, light tracing's film shift in area measure)
/// with finite differences. base_paths counts the connection paths tried.
ShiftReport validate_bidirectional_shift(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                                         const ValidateOptions& options = {});

namespace detail {

/// The BSDF sample a camera walk would have recorded for an offset step `s`
/// taken at a vertex entered from local direction `wo`, whose base vertex
/// sampled `base` there: the inverse shift reads it as its base's sample.
inline BsdfSample step_as_sample(const ShiftStep& s, const Vec3& wo, const BsdfSample& base) {
    const bool reflect = s.wi.z * wo.z > 0.f;
    BsdfSample b;
    b.wi = s.wi, b.f = s.f, b.pdf = s.pdf;
    b.eta = reflect ? 1.f : base.eta;
    b.lobe = (reflect ? kReflection : kTransmission) | (s.delta ? uint32_t(kSpecular) : (base.lobe & (kDiffuse | kGlossy)));
    return b;
}

/// Fills rep's Jacobian error statistics from the relative `errors` (sorted
/// here) and decides rep.passed from the required fraction of `o`.
inline void finish_report(ShiftReport& rep, std::vector<double>& errors, const ValidateOptions& o) {
    if (!errors.empty()) {
        std::sort(errors.begin(), errors.end());
        rep.jacobian_median_error = errors[errors.size() / 2];
        rep.jacobian_worst_error = errors.back();
    }
    const auto frac = [](size_t a, size_t b) { return b ? double(a) / double(b) : 1.0; };
    rep.passed = rep.base_paths > 0 && frac(rep.reverse_ok, rep.reverse_checked) >= o.required_fraction &&
                 frac(rep.jacobian_ok, rep.jacobian_checked) >= o.required_fraction;
}

// Solid-angle area spanned by central differences of a direction (first order).
inline double spanned_area(const Vec3d w[4]) { return glm::length(glm::cross(w[0] - w[1], w[2] - w[3])); }

// Finite-difference Jacobian of the shift step at base vertex k: perturbs the
// numbers that sampled x_k's direction, re-traces x_{k+1}, re-applies the step.
template <PathHost H>
std::optional<double> fd_step_jacobian(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config,
                                       const BasicCameraPath<H>& x, size_t k, const BasicOffsetVertex<H>& y,
                                       const ShiftStep& ref, float eps) {
    const BasicVertex<H>& X = x.v[k];
    const Vec3 wo = X.si.frame.to_local(X.wo);
    BasicCameraPath<H> xp;
    xp.film = x.film;
    xp.v.assign(x.v.begin(), x.v.begin() + long(std::min(x.size(), k + 2)));
    xp.nee.assign(x.nee.begin(), x.nee.begin() + long(std::min(x.size(), k + 2)));
    Vec3d wx[4], wy[4];
    const Vec2 du[4] = {{eps, 0.f}, {-eps, 0.f}, {0.f, eps}, {0.f, -eps}};
    const Vec3& p1 = x.v[k + 1].si.p;
    float moved = 0.f;  // largest displacement of x_{k+1}
    for (int i = 0; i < 4; ++i) {
        const Vec2 u = X.u_dir + du[i];
        if (u.x <= 0.f || u.y <= 0.f || u.x >= 1.f || u.y >= 1.f) return std::nullopt;
        const auto bs = scene.sample_bsdf(X.si, wo, X.u_lobe, u);
        if (!bs || bs->lobe != X.bs.lobe || !(bs->pdf > 0.f)) return std::nullopt;
        xp.v[k].bs = *bs;
        xp.v[k].u_dir = u;
        const Vec3 dir = X.si.frame.to_world(bs->wi);
        typename H::Interaction hit;
        if (!scene.intersect(spawn_ray(X.si, dir), hit) || hit.prim != x.v[k + 1].si.prim) return std::nullopt;
        moved = std::max(moved, glm::length(hit.p - p1));
        xp.v[k + 1].si = hit;
        xp.v[k + 1].wo = -dir;
        const ShiftStep s = shift.step(BasicShiftStepInput<H>{scene, config, xp, k, y});
        if (s.kind != ref.kind) return std::nullopt;
        wx[i] = Vec3d(dir);
        wy[i] = Vec3d(y.si.frame.to_world(s.wi));
    }
    // A moved x_{k+1} within a few hundred float steps of where it was (after
    // a bounce thousands of times shorter than the scene) cannot be told
    // apart from rounding: its differences would measure the float grid,
    // not the shift.
    const float resolution = 128.f * std::numeric_limits<float>::epsilon() *
                             std::max({1.f, std::abs(p1.x), std::abs(p1.y), std::abs(p1.z)});
    if (!(moved > resolution)) return std::nullopt;
    const double ax = spanned_area(wx);
    if (!(ax > 0.0)) return std::nullopt;
    return spanned_area(wy) / ax;
}

// Finite-difference Jacobian of the shared light point: moves the point in its
// emitter's tangent plane (in double, independent of how it was sampled).
template <class H>
std::optional<double> fd_light_jacobian(const BasicVertex<H>& X, const LightConnection& nee,
                                        const BasicOffsetVertex<H>& y, float eps) {
    const Vec3d p(nee.light.p), n(nee.light.n), px(X.si.p), py(y.si.p);
    // Seen edge-on (a vertex in the emitter's own plane), both the density
    // and its differences are float rounding.
    for (const Vec3d& q : {px, py})
        if (!nee.light.delta && !(std::abs(glm::dot(n, glm::normalize(q - p))) > 1e-4)) return std::nullopt;
    const double h = double(eps) * glm::length(p - px);
    // A point or spot light is the limit of a small sphere: each vertex sees
    // a disk of it facing that vertex (so the cosine at the light is 1 from
    // everywhere, LightSample's convention), moved in its own plane.
    const Frame f(nee.light.n), fx(Vec3(glm::normalize(px - p))), fy(Vec3(glm::normalize(py - p)));
    const Frame& gx = nee.light.delta ? fx : f;
    const Frame& gy = nee.light.delta ? fy : f;
    const auto step = [h](const Frame& g, int i) {
        const Vec3d s(g.s), t(g.t);
        return i == 0 ? h * s : i == 1 ? -h * s : i == 2 ? h * t : -h * t;
    };
    Vec3d wx[4], wy[4];
    for (int i = 0; i < 4; ++i) {
        wx[i] = glm::normalize(p + step(gx, i) - px);
        wy[i] = glm::normalize(p + step(gy, i) - py);
    }
    const double ax = spanned_area(wx);
    if (!(ax > 0.0)) return std::nullopt;
    return spanned_area(wy) / ax;
}

// Central differences err by O(eps^2); one Richardson step cancels that term,
// which matters where the offset vertex is close to the reconnection vertex.
template <typename F>
std::optional<double> richardson(float eps, F&& fd) {
    const auto a = fd(eps), b = fd(0.5f * eps);
    if (!a || !b) return std::nullopt;
    return (4.0 * *b - *a) / 3.0;
}

// The offset path seen as a base path of its own pixel (same random numbers).
template <PathHost H>
BasicCameraPath<H> as_base_path(const H& scene, const BasicCameraPath<H>& x, const BasicOffsetPath<H>& y,
                                const Vec2& offset) {
    BasicCameraPath<H> p;
    p.film = x.film + offset;
    p.v.push_back(x.v[0]);  // the same pinhole
    p.nee.push_back(x.nee[0]);
    for (size_t k = 1; k < y.size(); ++k) {
        BasicVertex<H> v = x.v[k];
        LightConnection nee = x.nee[k];
        if (y.merged(k)) {
            p.v.push_back(v);  // the shared suffix is the base's own
            p.nee.push_back(nee);
            continue;
        }
        const BasicOffsetRecord<H>& r = y.v[k];
        v.si = r.y.si;
        v.wo = r.y.si.frame.to_world(r.y.wo);
        if (nee.valid) nee.measure(scene, v.si, r.y.wo);  // the same light point, seen from y_k
        v.bs = BsdfSample{};
        if (k + 1 < y.size()) {
            v.bs = step_as_sample(r.step, r.y.wo, x.v[k].bs);
            v.delta = r.step.delta;
        }
        p.v.push_back(v);
        p.nee.push_back(nee);
    }
    return p;
}

}  // namespace detail

template <PathHost H>
ShiftReport validate_shift(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config,
                           const ValidateOptions& o) {
    using namespace detail;
    ShiftReport rep;
    rep.shift = shift.name();
    if constexpr (EnvironmentHost<H>)
        if (scene.environment())
            throw InputError("the shift validator (check-shift) does not support environment lights yet: the scene "
                             "has one (constant or envmap); remove it to use the shift validator (check-shift)");
    const int W = scene.camera().width(), height = scene.camera().height();
    if (W < 2) throw ParameterError("validate_shift: the image must be at least 2 pixels wide");
    const Vec2 right(1.f, 0.f);
    const double tol = o.position_tolerance * scene.bounding_radius();
    std::vector<double> errors;
    BasicCameraPath<H> x;
    BasicOffsetPath<H> y, back;
    WalkOptions topt;
    topt.max_vertices = o.max_depth;
    topt.reverse_densities = false;
    topt.rr_depth = 1 << 20;  // roulette changes nothing a shift does; keep paths long
    for (int i = 0; i < o.paths; ++i) {
        Sampler pick(SampleKey{o.seed ^ 0x5eedull, 0, 0, uint32_t(i)});
        const int px = std::min(W - 2, int(pick.next1d() * float(W - 1)));
        const int py = std::min(height - 1, int(pick.next1d() * float(height)));
        Sampler s(SampleKey{o.seed, uint32_t(px), uint32_t(py), uint32_t(i)});
        s.set_dimension(dims::kFilm);
        trace_camera_path(scene, Vec2(float(px), float(py)) + s.next2d(), s, topt, x);
        if (config.probabilistic) draw_classification_numbers(scene, s, topt.max_vertices, x);
        ++rep.sampled;
        if (x.size() < 3) continue;  // the camera and at least two hits
        ++rep.base_paths;
        shift_camera_path(scene, shift, config, x, right, y);

        for (size_t k = 1; k + 1 < y.size() && k < y.v.size(); ++k) {
            const BasicOffsetRecord<H>& r = y.v[k];
            // A directional light's direction is shared as such: |J| = 1 by construction.
            if (r.nee && !r.y.on_base && x.nee[k].valid && r.nee_jacobian > 0.0 && !x.nee[k].light.infinite) {
                if (auto j = richardson(o.fd_step, [&](float e) { return fd_light_jacobian(x.v[k], x.nee[k], r.y, e); })) {
                    const double e = std::abs(r.nee_jacobian / *j - 1.0);
                    errors.push_back(e);
                    rep.jacobian_checked++;
                    rep.jacobian_ok += e <= o.jacobian_tolerance;
                }
            }
            if (r.y.on_base || x.v[k].bs.is_delta() || r.step.kind == ShiftStep::Kind::Fail) continue;
            // A density-ratio Jacobian equals the geometric one only where each side has a single lobe
            // (a delta lobe beside a smooth one counts: its share of the samples depends on wo).
            const auto lobes = [&](const typename H::Interaction& at) {
                return uint32_t(scene.bsdf_flags(at)) & (kDiffuse | kGlossy | kSpecular);
            };
            if (r.step.sample_space &&
                (std::popcount(lobes(x.v[k].si)) > 1 || std::popcount(lobes(r.y.si)) > 1)) {
                ++rep.jacobian_skipped;
                continue;
            }
            // Sharp lobes turn numbers into directions with slope ~ roughness: scale the step to stay above float noise.
            float eps = std::clamp(o.fd_step / std::max(x.v[k].bs.roughness, 1e-3f), o.fd_step, 0.02f);
            // Keep the moved x_{k+1} well inside the offset vertex's distance to it, or curvature dominates.
            if (r.step.kind == ShiftStep::Kind::Reconnect) {
                const float dy = glm::length(x.v[k + 1].si.p - r.y.si.p), dx = glm::length(x.v[k + 1].si.p - x.v[k].si.p);
                eps *= std::clamp(dy / std::max(dx, 1e-6f), 0.05f, 1.f);
            }
            if (auto j = richardson(eps, [&](float e) { return fd_step_jacobian(scene, shift, config, x, k, r.y, r.step, e); })) {
                const double e = std::abs(r.step.jacobian / *j - 1.0);
                errors.push_back(e);
                rep.jacobian_checked++;
                rep.jacobian_ok += e <= o.jacobian_tolerance;
            }
        }

        if (y.size() != x.size()) continue;
        ++rep.complete;
        const BasicCameraPath<H> yb = as_base_path(scene, x, y, right);
        shift_camera_path(scene, shift, config, yb, -right, back);
        ++rep.reverse_checked;
        if (back.size() != x.size()) {
            ++rep.reverse_failed_shift;
            continue;
        }
        bool same = true;
        for (size_t k = 1; k < back.v.size(); ++k) same &= glm::length(back.v[k].y.si.p - x.v[k].si.p) <= tol;
        rep.reverse_ok += same;
    }
    finish_report(rep, errors, o);
    return rep;
}

inline std::string ShiftReport::summary() const {
    std::ostringstream os;
    const auto pct = [](size_t a, size_t b) { return b ? 100.0 * double(a) / double(b) : 100.0; };
    os.precision(4);
    os << "shift " << shift << ": " << base_paths << " base paths of " << sampled << " sampled";
    // A camera path that leaves the scene or ends at its first vertex has nothing to shift.
    if (sampled > base_paths && bidirectional)
        os << " (" << sampled - base_paths << " had no connection between connectable vertices to try)";
    else if (sampled > base_paths)
        os << " (" << sampled - base_paths << " left the scene or ended at their first vertex)";
    os << ", failure rate " << 100.0 * failure_rate() << "%\n"
       << "  reversibility: " << reverse_ok << " / " << reverse_checked << " (" << pct(reverse_ok, reverse_checked)
       << "%) returned to the base path; " << reverse_failed_shift << " inverse shifts failed\n"
       << "  jacobian: " << jacobian_ok << " / " << jacobian_checked << " (" << pct(jacobian_ok, jacobian_checked)
       << "%) within tolerance; median relative error " << jacobian_median_error << ", worst " << jacobian_worst_error
       << "\n  (" << jacobian_skipped << " replay steps at multi-lobe BSDFs not comparable to a geometric Jacobian)\n"
       << (passed ? "PASS" : "FAIL") << ": " << shift << "\n";
    return os.str();
}

// gdr's own Scene's is compiled once, in the library.
extern template ShiftReport validate_shift(const Scene&, const Shift&, const ShiftConfig&, const ValidateOptions&);

}  // namespace gdr
