// Warps from the unit square [0,1)^2 to directions and surface points, with
// their densities and inverses. Densities are w.r.t. solid angle (1/sr) for
// directions and w.r.t. area of the target domain otherwise. Every warp has
// an exact inverse so that shift mappings (random-number replay) and tests
// (round trips) can map a direction back to the numbers that produced it.
#pragma once

#include "gdr/core/math.h"

namespace gdr::warp {

/// sin and cos of x for |x| <= pi/4 (Taylor to x^9 / x^10: error below 4e-8,
/// under float rounding), without the range reduction and calls of std::sin/cos.
inline Vec2 sincos_quarter(float x) {
    // Estrin's scheme (pairs of terms in x^2, then in x^4): about half the
    // dependent operations of Horner's, and this sits on the path from a
    // sample's numbers to its next ray.
    const float x2 = x * x, x4 = x2 * x2;
    const float s = x * ((1.f + x2 * (-1.f / 6.f)) +
                         x4 * ((1.f / 120.f + x2 * (-1.f / 5040.f)) + x4 * (1.f / 362880.f)));
    const float c = (1.f + x2 * -0.5f) +
                    x4 * ((1.f / 24.f + x2 * (-1.f / 720.f)) + x4 * (1.f / 40320.f + x2 * (-1.f / 3628800.f)));
    return {s, c};
}

/// Uniform point on the unit disk (Shirley-Chiu concentric map: low distortion,
/// continuous, so nearby numbers give nearby points; matters for shifts).
/// Branch-free: the wedge test is a coin flip per sample, which a branch
/// predictor cannot learn, and the angle never leaves [-pi/4, pi/4] around
/// the wedge's axis, where a short polynomial is exact to float precision.
inline Vec2 square_to_uniform_disk(const Vec2& u) {
    const float a = 2.f * u.x - 1.f, b = 2.f * u.y - 1.f;
    // The selects are bit masks: written as ?:, GCC compiles them to branches,
    // which mispredict on half the samples.
    const uint32_t horizontal = -uint32_t(std::abs(a) > std::abs(b));  // all ones or zero
    const auto pick = [horizontal](float if_h, float if_v) {
        return std::bit_cast<float>((std::bit_cast<uint32_t>(if_h) & horizontal) |
                                    (std::bit_cast<uint32_t>(if_v) & ~horizontal));
    };
    const float r = pick(a, b);  // signed radius along the wedge's axis
    const float q = pick(b, a);  // position across the wedge
    if (r == 0.f) return Vec2(0.f);
    const Vec2 sc = sincos_quarter((kPi / 4.f) * (q / r));
    // Right/left wedges: phi = pi/4 q/r; top/bottom: phi = pi/2 - pi/4 q/r (sin and cos swap).
    return {r * pick(sc.y, sc.x), r * pick(sc.x, sc.y)};
}

/// Inverse of square_to_uniform_disk (point in the unit disk -> [0,1]^2).
inline Vec2 uniform_disk_to_square(const Vec2& p) {
    const float r = std::sqrt(p.x * p.x + p.y * p.y);
    if (r == 0.f) return Vec2(0.5f);
    float phi = std::atan2(p.y, p.x);
    if (phi < -kPi / 4.f) phi += 2.f * kPi;  // phi in [-pi/4, 7pi/4)
    float a, b;
    if (phi < kPi / 4.f) {  // right wedge: r = a > 0
        a = r;
        b = phi * a / (kPi / 4.f);
    } else if (phi < 3.f * kPi / 4.f) {  // top wedge: r = b > 0
        b = r;
        a = (kPi / 2.f - phi) * b / (kPi / 4.f);
    } else if (phi < 5.f * kPi / 4.f) {  // left wedge: r = a < 0, phi - pi in [-pi/4, pi/4)
        a = -r;
        b = (phi - kPi) * a / (kPi / 4.f);
    } else {  // bottom wedge: r = b < 0
        b = -r;
        a = (3.f * kPi / 2.f - phi) * b / (kPi / 4.f);
    }
    return {0.5f * (a + 1.f), 0.5f * (b + 1.f)};
}

/// Density of square_to_uniform_disk w.r.t. area of the disk (1/m^2 of the unit disk).
inline float uniform_disk_pdf(const Vec2& p) { return (p.x * p.x + p.y * p.y) <= 1.f ? kInvPi : 0.f; }

/// Cosine-weighted direction on the upper hemisphere (z >= 0), Malley's
/// method on the concentric disk; pdf = cos(theta) / pi.
inline Vec3 square_to_cosine_hemisphere(const Vec2& u) {
    const Vec2 d = square_to_uniform_disk(u);
    return {d.x, d.y, safe_sqrt(1.f - d.x * d.x - d.y * d.y)};
}

/// Solid-angle density of square_to_cosine_hemisphere (1/sr); 0 below the horizon.
inline float cosine_hemisphere_pdf(const Vec3& w) { return w.z > 0.f ? w.z * kInvPi : 0.f; }

/// Inverse of square_to_cosine_hemisphere (w with z >= 0 -> [0,1]^2).
inline Vec2 cosine_hemisphere_to_square(const Vec3& w) { return uniform_disk_to_square(Vec2(w.x, w.y)); }

/// Uniform direction on the unit sphere (Archimedes: z uniform in [-1,1]).
inline Vec3 square_to_uniform_sphere(const Vec2& u) {
    const float z = 1.f - 2.f * u.x;
    const float r = safe_sqrt(1.f - z * z);
    const float phi = 2.f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

/// Solid-angle density of square_to_uniform_sphere (1/sr).
inline float uniform_sphere_pdf() { return 1.f / (4.f * kPi); }

/// Inverse of square_to_uniform_sphere (unit vector -> [0,1]^2).
inline Vec2 uniform_sphere_to_square(const Vec3& w) {
    float phi = std::atan2(w.y, w.x);
    if (phi < 0.f) phi += 2.f * kPi;
    return {0.5f * (1.f - w.z), std::min(phi * (0.5f * kInvPi), std::nextafter(1.f, 0.f))};
}

/// Uniform direction on the upper hemisphere (z >= 0).
inline Vec3 square_to_uniform_hemisphere(const Vec2& u) {
    const float z = u.x;
    const float r = safe_sqrt(1.f - z * z);
    const float phi = 2.f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

/// Solid-angle density of square_to_uniform_hemisphere (1/sr); 0 below the horizon.
inline float uniform_hemisphere_pdf(const Vec3& w) { return w.z >= 0.f ? 0.5f * kInvPi : 0.f; }

/// Uniform direction in the cone around +z with cos(half angle) = cos_max
/// (sampling a sphere light by solid angle); cos_max in [-1, 1).
inline Vec3 square_to_uniform_cone(const Vec2& u, float cos_max) {
    const float z = 1.f - u.x * (1.f - cos_max);
    const float r = safe_sqrt(1.f - z * z);
    const float phi = 2.f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

/// Solid-angle density of square_to_uniform_cone (1/sr): 1 / (2 pi (1 - cos_max)) inside, 0 outside.
inline float uniform_cone_pdf(const Vec3& w, float cos_max) {
    return w.z >= cos_max ? 1.f / (2.f * kPi * (1.f - cos_max)) : 0.f;
}

/// Inverse of square_to_uniform_cone (direction inside the cone -> [0,1]^2).
inline Vec2 uniform_cone_to_square(const Vec3& w, float cos_max) {
    float phi = std::atan2(w.y, w.x);
    if (phi < 0.f) phi += 2.f * kPi;
    return {(1.f - w.z) / (1.f - cos_max), std::min(phi * (0.5f * kInvPi), std::nextafter(1.f, 0.f))};
}

/// Uniform barycentric coordinates (b1, b2) on a triangle, b0 = 1 - b1 - b2;
/// the density w.r.t. the triangle's area is 1 / area (square-root
/// parametrisation, which has a closed-form inverse unlike the folding trick).
inline Vec2 square_to_uniform_triangle(const Vec2& u) {
    const float s = std::sqrt(u.x);
    return {1.f - s, u.y * s};
}

/// Inverse of square_to_uniform_triangle (barycentrics (b1, b2) -> [0,1]^2).
inline Vec2 uniform_triangle_to_square(const Vec2& b) {
    const float s = 1.f - b.x;
    return {s * s, s > 0.f ? std::min(b.y / s, 1.f) : 0.f};
}

/// Density of a uniform point on a triangle w.r.t. surface area (1/m^2).
inline float uniform_triangle_pdf(float area) { return area > 0.f ? 1.f / area : 0.f; }

}  // namespace gdr::warp
