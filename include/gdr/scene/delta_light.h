// Lights without extent: a point, a spot and a directional light. None can
// be hit by a ray, so they are reached only by next-event estimation or by
// light subpaths that start on them.
//
// Measures: a point or spot light is a delta in position; its emission is a
// radiant intensity I (W/sr), and it lights a surface point at distance r
// with irradiance I cos / r^2. A directional light is a delta in direction;
// its emission is the irradiance E (W/m^2) it delivers to a surface
// perpendicular to it, so a surface point receives E cos.
//
// The spot's falloff is that of Mitsuba 0.5/0.6's `spot` emitter (Jakob,
// "Mitsuba renderer documentation", 2014): full intensity within beamWidth
// of the axis, zero beyond cutoffAngle, and in between linear in the angle,
// I (cutoff - theta) / (cutoff - beamWidth). Emission directions of a spot
// are sampled uniformly in the cutoff cone, as Mitsuba does. A spot may
// project a texture along its axis, as Mitsuba's does: the intensity towards a
// direction of local coordinates (x, y, z) in the spot's frame is multiplied
// by the texture at Mitsuba's uv (0.5 + 0.5 x / (z tan cutoff), 0.5 + 0.5 y /
// (z tan cutoff)), so the image fills the square around the cutoff cone.
#pragma once

#include <cmath>
#include <memory>

#include "gdr/core/math.h"
#include "gdr/scene/texture.h"
#include "gdr/scene/warp.h"

namespace gdr {

/// A light without extent, in world space.
struct DeltaLight {
    /// What it is.
    enum class Kind : uint8_t {
        Point,        ///< Isotropic point: intensity (W/sr) in every direction.
        Spot,         ///< Point emitting in a cone around `direction`, with Mitsuba's falloff.
        Directional,  ///< Parallel light travelling along `direction`: irradiance (W/m^2).
    };
    Kind kind = Kind::Point;
    Vec3 position{0.f};            ///< Point and spot: where it sits (scene units).
    Vec3 direction{0.f, 0.f, 1.f}; ///< Spot: unit axis; directional: unit direction light travels.
    /// Point and spot: radiant intensity (W/sr), the spot's on its axis;
    /// directional: irradiance on a surface perpendicular to it (W/m^2).
    Color intensity{1.f};
    float cutoff = 0.f;            ///< Spot: cutoff angle (radians), no light beyond it.
    float beam_width = 0.f;        ///< Spot: angle (radians) within which the intensity is full; <= cutoff.
    /// Spot: unit local x and y axes of its frame (z is `direction`), which
    /// orient a projected texture.
    Vec3 axis_x{1.f, 0.f, 0.f}, axis_y{0.f, 1.f, 0.f};
    /// Spot: a texture projected along the axis (a unitless factor on the
    /// intensity; gdr's uv convention, v = 0 at the image's bottom), or null.
    std::shared_ptr<const Texture> texture;

    /// True for the kinds that are a delta in position (point and spot).
    bool is_positional() const { return kind != Kind::Directional; }

    /// Intensity (W/sr) emitted along unit world direction w away from a
    /// point or spot light: the spot's falloff applied.
    Color intensity_towards(const Vec3& w) const {
        if (kind != Kind::Spot) return intensity;
        const float cos_theta = glm::dot(w, direction), f = spot_falloff(cos_theta);
        if (!texture || f == 0.f) return intensity * f;
        return intensity * f * texture->eval(projected_uv(w));
    }

    /// The uv (gdr's convention) at which a spot's texture is read for unit
    /// world direction w inside its cone: Mitsuba's (0.5 + 0.5 x / (z tan
    /// cutoff), 0.5 + 0.5 y / (z tan cutoff)), whose v runs down the image.
    Vec2 projected_uv(const Vec3& w) const {
        const float z = glm::dot(w, direction), k = 0.5f / (z * std::tan(cutoff));
        return {0.5f + glm::dot(w, axis_x) * k, 0.5f - glm::dot(w, axis_y) * k};
    }

    /// The spot's falloff factor (unitless, in [0, 1]) at cos(theta) from its axis.
    float spot_falloff(float cos_theta) const {
        const float cos_cutoff = std::cos(cutoff);
        if (cos_theta <= cos_cutoff) return 0.f;
        if (cos_theta >= std::cos(beam_width)) return 1.f;
        const float theta = std::acos(std::min(1.f, cos_theta));
        return (cutoff - theta) / (cutoff - beam_width);
    }

    /// Solid-angle density (1/sr) with which a light subpath starting on a
    /// point or spot light emits along unit direction w: uniform on the
    /// sphere, or uniform in the spot's cutoff cone (0 outside).
    float emission_pdf_w(const Vec3& w) const {
        if (kind == Kind::Point) return warp::uniform_sphere_pdf();
        if (kind != Kind::Spot) return 0.f;
        const float cos_cutoff = std::cos(cutoff);
        return glm::dot(w, direction) > cos_cutoff ? 1.f / (2.f * kPi * (1.f - cos_cutoff)) : 0.f;
    }

    /// An emission direction of a point or spot light from two uniform
    /// numbers, with the density emission_pdf_w() gives it.
    Vec3 sample_emission(const Vec2& u) const {
        if (kind == Kind::Point) return warp::square_to_uniform_sphere(u);
        return Frame(direction).to_world(warp::square_to_uniform_cone(u, std::cos(cutoff)));
    }

    /// Luminance of the emitted power for light selection: W for a point or
    /// spot light; for a directional light its irradiance times the area
    /// pi r^2 of the disk of radius `scene_radius` it crosses (as pbrt-v4's
    /// power light sampler estimates it).
    double power(float scene_radius) const {
        const double y = double(luminance(intensity)) * (texture ? double(luminance(texture->mean())) : 1.0);
        switch (kind) {
            case Kind::Point: return 4.0 * 3.14159265358979323846 * y;
            case Kind::Spot: {
                // The full-intensity cone plus the falloff ring at its mean, roughly.
                const double c = 0.5 * (std::cos(double(cutoff)) + std::cos(double(beam_width)));
                return 2.0 * 3.14159265358979323846 * (1.0 - c) * y;
            }
            case Kind::Directional:
                return 3.14159265358979323846 * double(scene_radius) * double(scene_radius) * y;
        }
        return 0.0;
    }
};

}  // namespace gdr
