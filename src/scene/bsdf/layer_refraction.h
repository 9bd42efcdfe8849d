// Refraction through the interface of a coating layer as Mitsuba's `coating`
// and `roughcoating` compute it: the refracted direction keeps its side of
// the surface, so the layer's directions are on the side their light came
// from (a coated glass transmits through a like interface below). Internal
// to the library.
#pragma once

#include <algorithm>
#include <cmath>

#include "gdr/core/math.h"

namespace gdr::detail {

/// w (outside) refracted into a layer of relative index eta (inside /
/// outside), on w's side of the surface; false on total internal reflection
/// (an index below the outside's).
inline bool refract_into_layer(const Vec3& w, float eta, Vec3& w_in) {
    const float sin2 = std::max(0.f, 1.f - w.z * w.z) / (eta * eta);
    if (sin2 >= 1.f) return false;
    const float c = std::sqrt(1.f - sin2);
    w_in = Vec3(w.x / eta, w.y / eta, w.z > 0.f ? c : -c);
    return true;
}

/// w_in (inside the layer) refracted out, on its side; false on total internal reflection.
inline bool refract_out_of_layer(const Vec3& w_in, float eta, Vec3& w) {
    const float sin2 = eta * eta * std::max(0.f, 1.f - w_in.z * w_in.z);
    if (sin2 >= 1.f) return false;
    const float c = std::sqrt(1.f - sin2);
    w = Vec3(w_in.x * eta, w_in.y * eta, w_in.z > 0.f ? c : -c);
    return true;
}

}  // namespace gdr::detail
