// Keyframed rigid motion of scene objects and of the camera. Time is measured
// in frames (frame k of an animation is time t = k; seconds are t / fps), and
// keys may sit at fractional frames. Between two keys translation and scale
// are interpolated linearly and rotation by spherical linear interpolation
// (Shoemake, "Animating Rotation with Quaternion Curves", SIGGRAPH 1985)
// along the shorter arc; before the first key and after the last a track
// holds that key's value.
#pragma once

#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>

#include "gdr/core/math.h"
#include "gdr/scene/camera.h"

namespace gdr {

/// A unit quaternion (rotation), GLM's layout: w, then x, y, z.
using Quat = glm::quat;

/// The frames an animation spans and its frame rate.
struct AnimationRange {
    int first = 0;      ///< First frame number (inclusive).
    int last = 0;       ///< Last frame number (inclusive).
    double fps = 24.0;  ///< Frames per second (for playback; time inside gdr is in frames).
    /// Number of frames, last - first + 1.
    int count() const { return last - first + 1; }
};

/// A similarity transform: scale, then rotate, then translate (the order of a
/// scene file's "transform").
struct TransformValue {
    Vec3 translate{0.f};            ///< Translation (scene units).
    Quat rotate{1.f, 0.f, 0.f, 0.f};  ///< Rotation (unit quaternion).
    Vec3 scale{1.f};                ///< Scale per axis (unitless).
    /// The 4x4 matrix T * R * S.
    Mat4 matrix() const;
};

/// A transform at a key frame.
struct TransformKey {
    double frame = 0.0;     ///< Time of the key (frames).
    TransformValue value;   ///< The transform there.
};

/// A keyframed transform; empty means the identity at every time.
struct TransformTrack {
    std::vector<TransformKey> keys;  ///< Strictly increasing in frame.
    /// True if the track has no keys (the object does not move).
    bool empty() const { return keys.empty(); }
    /// The interpolated transform at time t (frames): a key's own value at
    /// its frame, held before the first and after the last key.
    TransformValue at(double t) const;
    /// at(t).matrix(); the identity for an empty track.
    Mat4 matrix_at(double t) const;
};

/// A camera's placement: its eye point and the rotation taking the camera's
/// axes (x right, y up, z backwards, so it looks along -z) to the world.
struct CameraPose {
    Vec3 position{0.f};                   ///< Eye point (scene units).
    Quat orientation{1.f, 0.f, 0.f, 0.f};  ///< Camera-to-world rotation (unit quaternion).
    /// The pose of a look-at camera (the CameraDesc convention); throws
    /// ParameterError if target equals position or up is parallel to the view.
    static CameraPose look_at(const Vec3& position, const Vec3& target, const Vec3& up);
    /// `base` with this pose's position, target (one unit ahead) and up.
    CameraDesc apply(CameraDesc base) const;
};

/// A camera pose at a key frame.
struct CameraKey {
    double frame = 0.0;  ///< Time of the key (frames).
    CameraPose pose;     ///< The pose there.
};

/// A keyframed camera pose; empty means the scene's fixed camera.
struct CameraTrack {
    std::vector<CameraKey> keys;  ///< Strictly increasing in frame.
    /// True if the camera does not move.
    bool empty() const { return keys.empty(); }
    /// The interpolated pose at time t (frames): position linearly,
    /// orientation by slerp; held outside the keys. Requires !empty().
    CameraPose at(double t) const;
};

/// Spherical linear interpolation from a (u = 0, exactly a) to b (u = 1)
/// along the shorter of the two arcs (q and -q are one rotation).
Quat slerp_shortest(const Quat& a, const Quat& b, float u);

}  // namespace gdr
