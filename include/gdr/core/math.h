// Vector math for gdr: GLM aliases, constants, orthonormal frames and the
// small direction helpers (reflect, refract) every module needs.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/glm.hpp>

namespace gdr {

using Vec2 = glm::vec2;    ///< 2-D float vector (uv, sample pairs).
using Vec3 = glm::vec3;    ///< 3-D float vector (positions in scene units, directions unitless).
using Vec3d = glm::dvec3;  ///< 3-D double vector for cancellation-prone shift arithmetic.
using Vec4 = glm::vec4;    ///< 4-D float vector.
using Mat4 = glm::mat4;    ///< Affine transform, column-major as GLM.
using Color = glm::vec3;   ///< Linear RGB radiometric quantity (radiance, throughput, reflectance).

inline constexpr float kPi = 3.14159265358979323846f;      ///< pi
inline constexpr float kInvPi = 0.31830988618379067154f;   ///< 1 / pi
inline constexpr float kInf = std::numeric_limits<float>::infinity();  ///< +infinity (float)

/// Rec. 709 luminance of a linear RGB colour (same units as the colour).
inline float luminance(const Color& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; }

/// Largest channel of a colour.
inline float max_component(const Color& c) { return std::max(c.r, std::max(c.g, c.b)); }

/// True when every channel is finite (no NaN, no Inf).
inline bool is_finite(const Color& c) { return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b); }

/// True when all channels are exactly zero.
inline bool is_black(const Color& c) {
    // Same as c.r == 0 && c.g == 0 && c.b == 0 (either zero counts, NaN does
    // not), as integer tests: the float compares cost a branch per channel.
    const uint32_t bits = std::bit_cast<uint32_t>(c.r) | std::bit_cast<uint32_t>(c.g) | std::bit_cast<uint32_t>(c.b);
    return (bits << 1) == 0u;
}

/// Square of x.
template <typename T>
constexpr T sqr(T x) { return x * x; }

/// sqrt clamped at zero so rounding cannot produce NaN.
inline float safe_sqrt(float x) { return std::sqrt(std::max(0.f, x)); }
/// sqrt clamped at zero so rounding cannot produce NaN.
inline double safe_sqrt(double x) { return std::sqrt(std::max(0.0, x)); }

/// Mirror reflection of w about unit normal n (both pointing away from the surface).
inline Vec3 reflect(const Vec3& w, const Vec3& n) { return 2.f * glm::dot(w, n) * n - w; }

/// Refraction of w (pointing away from the surface, on the side of n) through a
/// surface with relative index eta = eta_transmitted / eta_incident; returns
/// false on total internal reflection. wt points away from the surface too.
inline bool refract(const Vec3& w, const Vec3& n, float eta, Vec3& wt) {
    const float cos_i = glm::dot(n, w);
    const float sin2_t = std::max(0.f, 1.f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.f) return false;
    const float cos_t = std::sqrt(1.f - sin2_t);
    wt = -w / eta + (cos_i / eta - cos_t) * n;
    return true;
}

/// Orthonormal frame; to_local/to_world convert directions (unit vectors).
struct Frame {
    Vec3 s{1, 0, 0}, t{0, 1, 0}, n{0, 0, 1};

    Frame() = default;
    /// Builds a frame around unit normal n (Duff et al. 2017 branchless basis).
    explicit Frame(const Vec3& normal) : n(normal) {
        const float sign = std::copysign(1.f, n.z);
        const float a = -1.f / (sign + n.z);
        const float b = n.x * n.y * a;
        s = Vec3(1.f + sign * n.x * n.x * a, sign * b, -sign * n.x);
        t = Vec3(b, sign + n.y * n.y * a, -n.y);
    }
    /// World direction -> local (z along n).
    Vec3 to_local(const Vec3& v) const { return {glm::dot(v, s), glm::dot(v, t), glm::dot(v, n)}; }
    /// Local direction -> world.
    Vec3 to_world(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

/// Local-frame trigonometry (z is the normal).
inline float cos_theta(const Vec3& w) { return w.z; }
/// |cos theta| in the local frame.
inline float abs_cos_theta(const Vec3& w) { return std::abs(w.z); }
/// True if both local directions are on the same side of the surface.
inline bool same_hemisphere(const Vec3& a, const Vec3& b) { return a.z * b.z > 0.f; }

}  // namespace gdr
