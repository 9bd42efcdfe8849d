// The one multiple-importance-sampling module. Every MIS weight gdr
// computes is the power or balance heuristic of Veach and Guibas, "Optimally
// Combining Sampling Techniques for Monte Carlo Rendering" (1995), over a
// list of the densities with which the competing strategies would have
// produced the same path: path tracing's light and BSDF sampling, the
// base/offset pair of gradient-domain rendering, and bidirectional path
// tracing's (s, t) strategies (path_densities below).
#pragma once

#include <cmath>
#include <initializer_list>
#include <span>

namespace gdr {

/// Heuristic of an MIS weight.
enum class MisHeuristic {
    Power,    ///< beta = 2
    Balance,  ///< beta = 1
};

/// MIS weight of the strategy whose density is `p_this` against all
/// strategies' densities `p_all` (which include p_this; any one measure,
/// scaled by the strategies' sample counts where they differ):
/// p_this^b / sum_i p_i^b with b = 2 (power) or 1 (balance). A zero or
/// non-finite result (all densities zero, an overflow) is 0.
inline double mis_weight(MisHeuristic h, double p_this, std::span<const double> p_all) {
    if (!(p_this > 0.0)) return 0.0;
    double sum = 0.0;
    if (h == MisHeuristic::Balance)
        for (double p : p_all) sum += p;
    else
        for (double p : p_all) sum += p * p;
    const double w = (h == MisHeuristic::Balance ? p_this : p_this * p_this) / sum;
    return std::isfinite(w) ? w : 0.0;
}
/// mis_weight() of a short list written in place.
inline double mis_weight(MisHeuristic h, double p_this, std::initializer_list<double> p_all) {
    return mis_weight(h, p_this, std::span<const double>(p_all.begin(), p_all.size()));
}

/// Power heuristic of strategy a against strategy b, in single precision,
/// for the path tracer's inner loop: mis_weight(Power, a, {a, b}).
inline float power_heuristic(float pdf_a, float pdf_b) {
    const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
    return a > 0.f ? a / (a + b) : 0.f;
}

}  // namespace gdr
