#include "gdr/scene/camera.h"

#include "gdr/core/error.h"
#include "gdr/scene/coordinates.h"

#include <fmt/format.h>

#include <utility>

namespace gdr {

Camera::Camera(const CameraDesc& d) : desc_(d) {
    if (d.width <= 0 || d.height <= 0)
        throw ParameterError("camera: resolution must be positive, got " + std::to_string(d.width) + "x" +
                             std::to_string(d.height));
    // Pixel coordinates travel as floats and 32-bit sampler keys; 65536 keeps them exact.
    if (d.width > 65536 || d.height > 65536)
        throw ParameterError("camera: resolution must be at most 65536 per side, got " + std::to_string(d.width) +
                             "x" + std::to_string(d.height));
    if (!(d.fov_deg > 0.f && d.fov_deg < 180.f))
        throw ParameterError("camera: fov must be in (0, 180) degrees, got " + std::to_string(d.fov_deg));
    if (d.fov_axis != 'x' && d.fov_axis != 'y') throw ParameterError("camera: fov_axis must be 'x' or 'y'");
    // Far-away points would reach Embree as invalid rays (an assertion, not an error) and their
    // differences would overflow, so that a wrong message would blame the up vector.
    for (const auto& [key, v] : {std::pair<const char*, Vec3>{"position", d.position}, {"target", d.target}, {"up", d.up}})
        if (!within_coordinate_range(v))
            throw ParameterError(fmt::format("camera: {} ({}, {}, {}) must be finite and within +-{:g} on every axis",
                                             key, v.x, v.y, v.z, kMaxCoordinate));
    const Vec3 f = d.target - d.position;
    if (!(glm::length(f) > 0.f)) throw ParameterError("camera: position and target coincide");
    forward_ = glm::normalize(f);
    const Vec3 r = glm::cross(forward_, d.up);
    if (!(glm::length(r) > 1e-6f)) throw ParameterError("camera: up is parallel to the viewing direction");
    right_ = glm::normalize(r);
    up_ = glm::cross(right_, forward_);
    const float t = std::tan(0.5f * d.fov_deg * kPi / 180.f);
    const float aspect = float(d.width) / float(d.height);
    if (d.fov_axis == 'x') tan_half_x_ = t, tan_half_y_ = t / aspect;
    else tan_half_y_ = t, tan_half_x_ = t * aspect;
    corner_ = forward_ - tan_half_x_ * right_ + tan_half_y_ * up_;
    per_pixel_x_ = (2.f * tan_half_x_ / float(d.width)) * right_;
    per_pixel_y_ = (-2.f * tan_half_y_ / float(d.height)) * up_;
}

bool Camera::project(const Vec3& p, Vec2& film) const {
    const Vec3 v = p - desc_.position;
    const float z = glm::dot(v, forward_);
    if (z <= 0.f) return false;
    const float sx = glm::dot(v, right_) / (z * tan_half_x_), sy = glm::dot(v, up_) / (z * tan_half_y_);
    film = Vec2((sx + 1.f) * 0.5f * float(desc_.width), (1.f - sy) * 0.5f * float(desc_.height));
    return true;
}

float Camera::importance(const Vec3& w, Vec2& film) const {
    const float c = glm::dot(w, forward_);
    if (!(c > 0.f) || !project(desc_.position + w, film)) return 0.f;
    if (!(film.x >= 0.f && film.x < float(desc_.width) && film.y >= 0.f && film.y < float(desc_.height))) return 0.f;
    const float c2 = c * c;
    return 1.f / (film_area_at_unit_distance() * c2 * c2);
}

float Camera::direction_pdf(const Vec3& w) const {
    // importance() times the cosine, without the film position it also
    // finds: every camera ray's walk asks for this density.
    const float c = glm::dot(w, forward_);
    if (!(c > 0.f) || std::abs(glm::dot(w, right_)) > c * tan_half_x_ || std::abs(glm::dot(w, up_)) > c * tan_half_y_)
        return 0.f;
    return 1.f / (film_area_at_unit_distance() * c * c * c);
}

}  // namespace gdr
