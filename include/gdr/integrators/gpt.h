// Gradient-domain path tracing (PI): the estimator of one base/offset pair.
#pragma once

#include "gdr/integrators/integrator.h"
#include "gdr/shift/mis.h"
#include "gdr/shift/offset_path.h"

namespace gdr {

/// Sums of the MIS-weighted contributions of one base path and its offset.
struct PairEstimate {
    Color base{0.f};      ///< Sum of w f(x)/q(x): the base's share of its own pixel (W/(m^2 sr)).
    Color offset{0.f};    ///< Sum of w f(y)|J|/q(x): the offset's share of the neighbour pixel.
    Color gradient{0.f};  ///< Sum of w (f(y)|J| - f(x))/q(x): an estimate of I_j - I_i.
};

/// Evaluates every contribution (light sampling and emitter hits, from the second
/// vertex on: directly visible emitters are left out) of base path `x` and
/// offset `y` (nullptr or empty = the shift failed: plain path-tracing MIS).
PairEstimate evaluate_pair(const Scene& scene, const CameraPath& x, const OffsetPath* y, const GradientMis& mis);

/// Registers "gpt".
void register_gpt(Registry<Integrator>& r);

}  // namespace gdr
