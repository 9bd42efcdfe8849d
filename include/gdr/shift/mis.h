// The MIS weight of gradient-domain rendering: base path x of pixel i
// against the offset y = T(x) seen as a base path of pixel j (Kettunen et
// al., "Gradient-Domain Path Tracing", 2015; Manzi et al., "Temporal
// Gradient-Domain Path Tracing", 2016). A case of the one MIS module
// (gdr/path/mis.h) over four strategy densities.
#pragma once

#include "gdr/path/mis.h"

namespace gdr {

/// Settings of the gradient MIS weight.
struct GradientMis {
    MisHeuristic heuristic = MisHeuristic::Power;
    /// Share of samples of the base's pixel, a = n_i / (n_i + n_j) (temporal adaptive sampling); 0.5 = uniform.
    double sample_ratio = 0.5;
};

/// Weight of a contribution of base technique t. Densities are per technique
/// at the path's last vertex, all in the base's solid-angle measure:
///   a_t, a_other: the base's density for t and for the other technique (light or BSDF sampling);
///   b_t, b_other: the offset's own densities times the last step's Jacobian;
///   r: ratio of the offset's prefix density (times Jacobians) to the base's.
/// w = (a q_t(x))^b / sum_t' [ (a q_t'(x))^b + ((1-a) q_t'(y))^b ], the
/// multi-sample power (b = 2) or balance (b = 1) heuristic with sample counts;
/// a failed shift passes b_t = b_other = 0, reducing to plain path-tracing MIS.
inline double gradient_mis_weight(const GradientMis& m, double a_t, double a_other, double b_t, double b_other,
                                  double r) {
    const double sa = m.sample_ratio, sb = 1.0 - m.sample_ratio;
    const double xt = sa * a_t;
    // A zero density stays zero even when r overflowed.
    const double yt = b_t > 0.0 ? sb * r * b_t : 0.0, yo = b_other > 0.0 ? sb * r * b_other : 0.0;
    return mis_weight(m.heuristic, xt, {xt, sa * a_other, yt, yo});
}

}  // namespace gdr
