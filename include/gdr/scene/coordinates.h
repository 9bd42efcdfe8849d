// The range of coordinates a scene may use: what Embree accepts as ray
// origins, with room for the offsets and distances computed from them.
#pragma once

#include <cmath>

#include <glm/glm.hpp>

namespace gdr {

/// Largest coordinate magnitude (scene units, per axis) of a camera or scene
/// point. Embree refuses ray origins beyond its FLT_LARGE (about 1.8e18) per
/// axis, and the squared distance of two points must stay finite in float
/// (3 * (2e15)^2 is about 1e31, far below 3.4e38), so 1e15 keeps every ray
/// origin, offset origin and distance of a scene three orders inside both.
inline constexpr float kMaxCoordinate = 1e15f;

/// True when every coordinate of `p` is finite and at most kMaxCoordinate in magnitude.
inline bool within_coordinate_range(const glm::vec3& p) {
    return std::abs(p.x) <= kMaxCoordinate && std::abs(p.y) <= kMaxCoordinate && std::abs(p.z) <= kMaxCoordinate;
}

}  // namespace gdr
