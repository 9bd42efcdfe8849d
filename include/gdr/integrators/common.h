// Small helpers shared by the path-based integrators.
#pragma once

#include "gdr/core/math.h"
#include "gdr/path/mis.h"

namespace gdr {

/// Solid-angle density from an area density at a point seen at distance
/// `dist` under |cos| `cos_at_point` (1/sr from 1/m^2).
inline float pdf_area_to_solid_angle(float pdf_a, float dist, float cos_at_point) {
    return cos_at_point > 0.f ? pdf_a * dist * dist / cos_at_point : 0.f;
}

/// Russian roulette survival probability for a path throughput (unitless).
inline float roulette_survival(const Color& throughput) { return std::min(0.95f, max_component(throughput)); }

}  // namespace gdr
