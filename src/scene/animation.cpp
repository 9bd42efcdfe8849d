#include "gdr/scene/animation.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include <glm/gtc/matrix_transform.hpp>

#include "gdr/core/error.h"
#include "gdr/scene/coordinates.h"

namespace gdr {

namespace {

// The segment [keys[i], keys[i+1]) holding t and t's fraction u in it, or
// i with u = 0 where t is on or outside a key (then keys[i] applies as it is).
template <class Key>
std::pair<size_t, float> locate(const std::vector<Key>& keys, double t) {
    if (t <= keys.front().frame) return {0, 0.f};
    if (t >= keys.back().frame) return {keys.size() - 1, 0.f};
    const auto it = std::upper_bound(keys.begin(), keys.end(), t, [](double v, const Key& k) { return v < k.frame; });
    const size_t i = size_t(it - keys.begin()) - 1;
    const double u = (t - keys[i].frame) / (keys[i + 1].frame - keys[i].frame);
    return {i, float(u)};
}

// a + u (b - a): exactly a at u = 0.
Vec3 lerp(const Vec3& a, const Vec3& b, float u) { return a + u * (b - a); }

}  // namespace

Mat4 TransformValue::matrix() const {
    return glm::translate(Mat4(1.f), translate) * glm::mat4_cast(rotate) * glm::scale(Mat4(1.f), scale);
}

Quat slerp_shortest(const Quat& a, const Quat& b, float u) {
    if (u == 0.f) return a;
    Quat c = b;
    float d = glm::dot(a, b);
    if (d < 0.f) c = -b, d = -d;
    // Nearly equal rotations: sin(theta) would lose all precision; the chord is as good there.
    if (d > 0.9995f) return glm::normalize(Quat(a.w + u * (c.w - a.w), a.x + u * (c.x - a.x), a.y + u * (c.y - a.y),
                                                a.z + u * (c.z - a.z)));
    const float theta = std::acos(std::min(d, 1.f));
    const float s = std::sin(theta);
    const float wa = std::sin((1.f - u) * theta) / s, wb = std::sin(u * theta) / s;
    return Quat(wa * a.w + wb * c.w, wa * a.x + wb * c.x, wa * a.y + wb * c.y, wa * a.z + wb * c.z);
}

TransformValue TransformTrack::at(double t) const {
    if (keys.empty()) return {};
    const auto [i, u] = locate(keys, t);
    if (u == 0.f) return keys[i].value;
    const TransformValue &a = keys[i].value, &b = keys[i + 1].value;
    return {lerp(a.translate, b.translate, u), slerp_shortest(a.rotate, b.rotate, u), lerp(a.scale, b.scale, u)};
}

Mat4 TransformTrack::matrix_at(double t) const { return keys.empty() ? Mat4(1.f) : at(t).matrix(); }

CameraPose CameraPose::look_at(const Vec3& position, const Vec3& target, const Vec3& up) {
    // As Camera's constructor: far-away points overflow the differences below.
    for (const auto& [key, v] : {std::pair<const char*, Vec3>{"position", position}, {"target", target}, {"up", up}})
        if (!within_coordinate_range(v))
            throw ParameterError("camera: " + std::string(key) + " must be finite and within +-1e15 on every axis");
    const Vec3 f = target - position;
    if (!(glm::length(f) > 0.f)) throw ParameterError("camera: position and target coincide");
    const Vec3 fw = glm::normalize(f);
    const Vec3 r = glm::cross(fw, up);
    if (!(glm::length(r) > 1e-6f)) throw ParameterError("camera: up is parallel to the viewing direction");
    const Vec3 right = glm::normalize(r), u = glm::cross(right, fw);
    glm::mat3 m(right, u, -fw);  // columns: the camera's x, y and z axes in the world
    return {position, glm::normalize(glm::quat_cast(m))};
}

CameraDesc CameraPose::apply(CameraDesc base) const {
    const glm::mat3 m = glm::mat3_cast(orientation);
    base.position = position;
    base.target = position - m[2];
    base.up = m[1];
    return base;
}

CameraPose CameraTrack::at(double t) const {
    if (keys.empty()) throw ParameterError("CameraTrack::at: the track has no keys");
    const auto [i, u] = locate(keys, t);
    if (u == 0.f) return keys[i].pose;
    const CameraPose &a = keys[i].pose, &b = keys[i + 1].pose;
    return {lerp(a.position, b.position, u), slerp_shortest(a.orientation, b.orientation, u)};
}

}  // namespace gdr
