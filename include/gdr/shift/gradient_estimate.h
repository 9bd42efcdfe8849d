// The G-PT estimator of one base path and its offset (Kettunen, Manzi,
// Aittala, Lehtinen, Durand and Zwicker, "Gradient-Domain Path Tracing",
// 2015), templated on the host (gdr/path/host.h): the base's terms,
// computed once per base path, and the MIS-weighted base, offset and
// gradient contributions of each pair. gdr's gpt and tgpt integrators and
// any host's own G-PT loop share it.
#pragma once

#include <type_traits>
#include <vector>

#include "gdr/path/host.h"
#include "gdr/path/trace.h"
#include "gdr/shift/mis.h"
#include "gdr/shift/offset_path.h"

namespace gdr {

/// Sums of the MIS-weighted contributions of one base path and its offset.
struct PairEstimate {
    Color base{0.f};      ///< Sum of w f(x)/q(x): the base's share of its own pixel (W/(m^2 sr)).
    Color offset{0.f};    ///< Sum of w f(y)|J|/q(x): the offset's share of the neighbour pixel.
    Color gradient{0.f};  ///< Sum of w (f(y)|J| - f(x))/q(x): an estimate of I_j - I_i.
};

/// What the base path contributes at each vertex, computed once and shared by
/// its four offsets. Densities are solid-angle (1/sr), contributions radiance.
struct BaseTerms {
    /// The terms of one base vertex x_k.
    struct Vertex {
        Color emitted{0.f};     ///< Radiance emitted by x_k towards x_{k-1} (W/(m^2 sr)).
        Color emit{0.f};        ///< f(x)/q(x) of the emitter hit at x_k by BSDF sampling at x_{k-1}.
        double emit_pdf_bsdf = 0.0;   ///< BSDF density of that direction at x_{k-1}.
        double emit_pdf_light = 0.0;  ///< Light-sampling density of it (0 if light sampling could not produce it).
        Color beta{0.f};        ///< Base throughput up to x_k (before it scatters).
        Color nee{0.f};         ///< f(x)/q(x) of the light sample at x_k (0 if blocked).
        Color nee_unit{0.f};    ///< The same without the throughput: f |cos| Le / pdf at x_k.
        double nee_pdf_light = 0.0;   ///< Light-sampling density of the light direction at x_k.
        double nee_pdf_bsdf = 0.0;    ///< BSDF density of that direction at x_k.
        double inv_nee_pdf_light = 0.0;  ///< 1 / nee_pdf_light (0 if that is 0), in sr.
        double inv_bs_pdf = 0.0;         ///< 1 / the BSDF density of the sampled direction at x_k (sr; 0 if none).
        double inv_scatter_pdf = 0.0;    ///< inv_bs_pdf / the Russian-roulette survival after x_k.
        Color scatter{0.f};              ///< Throughput of the scattering at x_k (scatter_weight; 0 if none).
        /// Path-tracing-MIS-weighted contributions of the light sample at x_k and of
        /// every later vertex, per unit throughput at x_k (emitter hit at x_k
        /// excluded). An offset that has merged with the base at x_k contributes
        /// its own throughput times this, scaled by one MIS factor (see evaluate_pair).
        Color suffix{0.f};
    };
    std::vector<Vertex> v;  ///< One entry per base vertex (v[0], the camera's, stays empty).
};

/// Fills `terms` for base path `x`; `heuristic` weighs the suffix sums.
template <PathHost H>
void compute_base_terms(const H& scene, const BasicCameraPath<H>& x, MisHeuristic heuristic, BaseTerms& terms);

/// Evaluates every contribution (light sampling and emitter hits, from the second
/// vertex on: directly visible emitters are left out) of base path `x` and
/// offset `y` (nullptr or empty = the shift failed: plain path-tracing MIS).
/// The suffix an offset shares with the base is summed in closed form from
/// terms.suffix; `closed_form = false` walks it vertex by vertex instead (the
/// reference evaluation the closed form is tested against).
template <PathHost H>
PairEstimate evaluate_pair(const H& scene, const BasicCameraPath<H>& x, const BaseTerms& terms,
                           std::type_identity_t<const BasicOffsetPath<H>*> y, const GradientMis& mis,
                           bool closed_form = true);


namespace detail {

// Solid-angle density (1/sr) with which light sampling at `from` picks the
// emitter point of `at`, or, if `infinite`, the environment's direction -at.ng.
template <PathHost H>
double light_pdf_w(const H& scene, const Vec3& from, const typename H::Interaction& at, bool infinite) {
    if constexpr (EnvironmentHost<H>) {
        if (infinite) return scene.environment_pdf(-at.ng);
    } else if (infinite) {
        return 0.0;  // a host without an environment has no directions to sample
    }
    const float pa = scene.light_pdf_a(at);
    if (!(pa > 0.f)) return 0.0;
    const Vec3d d = Vec3d(at.p) - Vec3d(from);
    const double dist = glm::length(d);
    return pdf_a_to_w(double(pa), dist, glm::dot(Vec3d(at.ng), d / dist));
}

// Inlined: it sits in evaluate_pair's inner loop, and as a call it kept its
// operands in memory.
[[gnu::always_inline]] inline void add_weighted(PairEstimate& e, double w, const Color& cx, const Color& cy) {
    const float wf = float(w);
    e.base += wf * cx;
    e.offset += wf * cy;
    e.gradient += wf * (cy - cx);
}

// Plain path-tracing MIS weight of technique density a_t against a_other:
// the gradient weight without offset densities (the sample ratio cancels).
inline double pt_mis_weight(MisHeuristic h, double a_t, double a_other) {
    return gradient_mis_weight(GradientMis{h, 0.5}, a_t, a_other, 0.0, 0.0, 1.0);
}

}  // namespace detail

template <PathHost H>
void compute_base_terms(const H& scene, const BasicCameraPath<H>& x, MisHeuristic heuristic, BaseTerms& t) {
    using detail::light_pdf_w;
    using detail::pt_mis_weight;
    using Vertex = BasicVertex<H>;
    t.v.assign(x.size(), BaseTerms::Vertex{});
    Color beta(1.f);
    for (size_t k = 1; k < x.size(); ++k) {
        const Vertex& X = x.v[k];
        const LightConnection& nee = x.nee[k];
        BaseTerms::Vertex& T = t.v[k];
        T.beta = beta;
        T.emitted = emitted(scene, X);
        if (k >= 2) {
            const Vertex& P = x.v[k - 1];
            T.emit = beta * T.emitted;
            T.emit_pdf_bsdf = P.bs.pdf;
            if (!P.bs.is_delta() && x.nee[k - 1].valid && !is_black(T.emitted))
                T.emit_pdf_light = light_pdf_w(scene, P.si.p, X.si, X.infinite);
        }
        if (nee.valid) {
            const LightSample& ls = nee.light;
            T.nee_pdf_light = nee.pdf_w;
            if (T.nee_pdf_light > 0.0) {
                const Vec3& wi = nee.wi;
                T.nee_pdf_bsdf = nee.pdf_bsdf;
                T.inv_nee_pdf_light = 1.0 / T.nee_pdf_light;
                if (nee.visible) {
                    T.nee_unit = nee.f * abs_cos_theta(wi) * ls.radiance * float(T.inv_nee_pdf_light);
                    T.nee = beta * T.nee_unit;
                }
            }
        }
        if (!X.scattered()) break;
        T.inv_bs_pdf = 1.0 / double(X.bs.pdf);
        T.inv_scatter_pdf = T.inv_bs_pdf / double(X.rr_survival);
        T.scatter = scatter_weight(X);
        beta *= T.scatter;
    }
    // Suffix sums, back to front. Where y equals x (same vertices, same
    // densities), gradient_mis_weight(a_t, a_o, a_t, a_o, r) factors into the
    // path-tracing weight of (a_t, a_o) times a function of r alone, and r and
    // beta_y / beta_x stay constant: the whole shared suffix is one product.
    Color next(0.f);  // suffix of vertex k+1 plus its emitter hit, per unit throughput at k+1
    for (size_t k = x.size(); k-- > 1;) {
        const Vertex& X = x.v[k];
        BaseTerms::Vertex& T = t.v[k];
        // Weights only where they multiply something (each costs a division).
        T.suffix = is_black(T.nee_unit) ? Color(0.f)
                                        : float(pt_mis_weight(heuristic, T.nee_pdf_light, T.nee_pdf_bsdf)) * T.nee_unit;
        if (X.scattered() && k + 1 < x.size()) T.suffix += T.scatter * next;
        next = T.suffix;
        if (k >= 2 && !is_black(T.emitted))
            next += float(pt_mis_weight(heuristic, T.emit_pdf_bsdf, T.emit_pdf_light)) * T.emitted;
    }
}

namespace detail {

// evaluate_pair() with `closed_form` fixed at compile time: the rendering
// loop's form carries none of the vertex-by-vertex walk's tests.
template <bool closed_form, PathHost H>
PairEstimate evaluate_pair_as(const H& scene, const BasicCameraPath<H>& x, const BaseTerms& t,
                              const BasicOffsetPath<H>* y, const GradientMis& mis) {
    using Vertex = BasicVertex<H>;
    PairEstimate e;
    Color beta_y(1.f);
    double r = 1.0, r_prev = 1.0;  // offset prefix density / base prefix density (through k-1, k-2)
    const size_t m = y ? y->size() : 0;
    bool y_alive = m > 0;
    for (size_t k = 1; k < x.size(); ++k) {
        const Vertex& X = x.v[k];
        const BaseTerms::Vertex& T = t.v[k];
        const bool has_y = y_alive && k < m;
        // In the shared suffix the offset is the base with its own throughput and prefix density.
        const bool merged = has_y && y->merged(k);
        // In closed form the walk stops at the first merged vertex, so there
        // every merged vertex is the first one; it stops one vertex sooner
        // where the offset reconnected onto x_k with x_k's BSDF values, past
        // x_k's emitter term (that one sees the offset's own previous vertex).
        const bool closed_from_here = closed_form && (merged || (has_y && k == y->base_values_from));
        if (closed_form && !has_y) {
            // No offset from here on (none, failed or ended): every later term has
            // the plain path-tracing weight and no offset share, so the base's
            // suffix sums give the rest at once.
            Color c = T.suffix;
            if (k >= 2 && !is_black(T.emitted))
                c += float(pt_mis_weight(mis.heuristic, T.emit_pdf_bsdf, T.emit_pdf_light)) * T.emitted;
            const Color cx = T.beta * c;
            if (!is_black(cx)) add_weighted(e, 1.0, cx, Color(0.f));
            break;
        }

        // Emitter reached by BSDF sampling at x_{k-1}.
        if (k >= 2) {
            Color cy(0.f);
            double b_b = 0.0, b_l = 0.0;
            if (merged) {
                cy = beta_y * T.emitted;
                if (closed_form || k == y->merged_from) {
                    const ShiftStep& S = y->v[k - 1].step;  // left the shared vertex with its own incoming direction
                    b_b = double(S.pdf) * S.jacobian;
                    b_l = T.emit_pdf_light * S.jacobian;
                } else {
                    b_b = T.emit_pdf_bsdf, b_l = T.emit_pdf_light;
                }
            } else if (has_y) {
                const BasicOffsetRecord<H>& Y = y->v[k];
                const ShiftStep& S = y->v[k - 1].step;
                cy = beta_y * Y.y.emitted;
                // The offset's densities weigh the base even where the offset itself contributes nothing.
                b_b = double(S.pdf) * S.jacobian;
                const BasicOffsetVertex<H>& Yp = y->v[k - 1].y;
                if (!S.delta && (Y.y.infinite || scene.is_emitter(Y.y.si)) && scene.has_lights() &&
                    !scene.surface(Yp.si).pure_delta)
                    b_l = light_pdf_w(scene, Yp.si.p, Y.y.si, Y.y.infinite) * S.jacobian;
            }
            if (!is_black(T.emit) || !is_black(cy))
                add_weighted(e, gradient_mis_weight(mis, T.emit_pdf_bsdf, T.emit_pdf_light, b_b, b_l, r_prev), T.emit, cy);
        }

        if (closed_from_here) {
            // Everything from here on (this light sample, later vertices) in closed
            // form: w = w_pt * g(r), g(r) = (a q)^b / ((a q)^b + ((1-a) r q)^b),
            // which is the gradient weight of one technique of density 1 against
            // an offset of density 1 (and no other technique).
            const double g = gradient_mis_weight(mis, 1.0, 0.0, 1.0, 0.0, r);
            if (g > 0.0) {
                const Color cx = T.beta * T.suffix, cy = beta_y * T.suffix;
                add_weighted(e, g, cx, cy);
            }
            break;
        }

        // Light sample at x_k, shared with the offset.
        if (T.nee_pdf_light > 0.0) {
            Color cy(0.f);
            double b_l = 0.0, b_b = 0.0;
            if (!closed_form && merged) {
                cy = beta_y * T.nee_unit;
                b_l = T.nee_pdf_light, b_b = T.nee_pdf_bsdf;
            } else if (has_y && y->v[k].nee) {
                const BasicOffsetRecord<H>& R = y->v[k];
                b_l = R.nee_pdf_light_w * R.nee_jacobian;
                b_b = double(R.nee_pdf_bsdf) * R.nee_jacobian;
                cy = beta_y * R.nee_f * R.nee_cos * R.nee_radiance * float(R.nee_jacobian * T.inv_nee_pdf_light);
            }
            if (!is_black(T.nee) || !is_black(cy))
                add_weighted(e, gradient_mis_weight(mis, T.nee_pdf_light, T.nee_pdf_bsdf, b_l, b_b, r), T.nee, cy);
        }

        if (!X.scattered()) break;
        r_prev = r;
        if (!closed_form && merged) {
            beta_y *= scatter_weight(X);
        } else if (has_y) {
            const ShiftStep& S = y->v[k].step;
            if (S.kind == ShiftStep::Kind::Fail || k + 1 >= m) {
                y_alive = false;
            } else {
                // Products with the base's reciprocals: four offsets share them.
                beta_y *= S.f * float(abs_cos_theta(S.wi) * S.jacobian * T.inv_scatter_pdf);
                r *= double(S.pdf) * S.jacobian * T.inv_bs_pdf;
            }
        }
    }
    return e;
}

}  // namespace detail

template <PathHost H>
PairEstimate evaluate_pair(const H& scene, const BasicCameraPath<H>& x, const BaseTerms& t,
                           std::type_identity_t<const BasicOffsetPath<H>*> y, const GradientMis& mis, bool closed_form) {
    return closed_form ? detail::evaluate_pair_as<true>(scene, x, t, y, mis)
                       : detail::evaluate_pair_as<false>(scene, x, t, y, mis);
}




// gdr's own Scene's are compiled once, in the library.
extern template void compute_base_terms(const Scene&, const CameraPath&, MisHeuristic, BaseTerms&);
extern template PairEstimate evaluate_pair(const Scene&, const CameraPath&, const BaseTerms&, const OffsetPath*,
                                           const GradientMis&, bool);

}  // namespace gdr
