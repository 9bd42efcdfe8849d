// Small helpers shared by the path-based integrators.
#pragma once

#include "gdr/core/math.h"

namespace gdr {

/// Power heuristic (beta = 2) weight of strategy a against b; pdfs in one measure.
inline float power_heuristic(float pdf_a, float pdf_b) {
    const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
    return a > 0.f ? a / (a + b) : 0.f;
}

/// Solid-angle density from an area density at a point seen at distance
/// `dist` under |cos| `cos_at_point` (1/sr from 1/m^2).
inline float pdf_area_to_solid_angle(float pdf_a, float dist, float cos_at_point) {
    return cos_at_point > 0.f ? pdf_a * dist * dist / cos_at_point : 0.f;
}

/// Russian roulette survival probability for a path throughput (unitless).
inline float roulette_survival(const Color& throughput) { return std::min(0.95f, max_component(throughput)); }

}  // namespace gdr
