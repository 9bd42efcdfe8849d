// A scene whose objects and camera move rigidly over time (animation.h): the
// source of a Scene at any frame, and of the exact screen-space motion of the
// surface a pixel sees, which temporal reconstruction needs.
//
// A frame's Scene keeps the BVH of the objects that never move: when some
// object moves, the static objects' triangles are built into one Embree BVH
// once (SharedGeometry), which every frame's Scene instances, and a frame
// builds a BVH only over the moving objects' triangles at their transforms.
// The Scene's per-triangle tables (materials, frames, lights) are still
// rebuilt per frame: they index one flat triangle array.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gdr/core/image.h"
#include "gdr/scene/animation.h"
#include "gdr/scene/scene.h"

namespace gdr {

/// One scene-file mesh entry: its triangles placed by the entry's fixed
/// transform, and the keyframed motion applied on top of that.
struct AnimatedObject {
    std::string name;      ///< The mesh file, for messages.
    TriangleMesh mesh;     ///< Its triangles (object_ids unset); world space when the track is empty.
    TransformTrack track;  ///< Motion (frames); empty for a static object.
};

/// A scene at every time: objects, materials, camera track, environment.
class AnimatedScene {
public:
    /// Takes the parts of a scene; `camera` supplies the optics (resolution,
    /// fov) and, for an empty `camera_track`, the pose. Object i gets object id i.
    /// `origin` names the scene for messages.
    AnimatedScene(std::vector<AnimatedObject> objects, std::vector<Material> materials, const CameraDesc& camera,
                  CameraTrack camera_track, std::shared_ptr<const Environment> environment, AnimationRange range,
                  std::string origin);

    /// The scene at time t (frames): every object at its transform at t, the
    /// camera at its pose at t, object ids set (Scene::object_id()).
    std::unique_ptr<Scene> scene_at(double t) const;
    /// The camera at time t (frames).
    Camera camera_at(double t) const;
    /// Object `object`'s motion transform at time t (frames), applied to its
    /// mesh's coordinates; the identity for a static object.
    Mat4 object_transform(uint32_t object, double t) const;
    /// True if object `object` has keys (its transform may change).
    bool moves(uint32_t object) const { return !objects_.at(object).track.empty(); }
    /// Number of objects (scene-file mesh entries).
    size_t object_count() const { return objects_.size(); }
    /// The frame range and rate of the scene file's `animation` block.
    const AnimationRange& range() const { return range_; }
    /// The camera description whose resolution and field of view every frame uses.
    const CameraDesc& camera_optics() const { return camera_; }
    /// Replaces the resolution and field of view (not the pose) of every frame's camera with `d`'s.
    void set_camera_optics(const CameraDesc& d);
    /// Lights every frame with these delta lights (point, spot, directional;
    /// they do not move). Validated as Scene::set_delta_lights() does, naming
    /// the scene. Not synchronised with scene_at().
    void set_delta_lights(std::vector<DeltaLight> lights);
    /// The camera's keys (empty: a fixed camera).
    const CameraTrack& camera_track() const { return camera_track_; }
    /// True if frames share the static objects' BVH (some object moves, no
    /// material has an alpha cut-out, some static object has triangles).
    bool shares_static_geometry() const { return shared_ != nullptr && share_static_; }
    /// Turns the sharing of the static BVH off (each frame then builds one
    /// BVH over all triangles, in the same order) or back on: for
    /// comparisons of the two. Not synchronised with scene_at().
    void set_static_sharing(bool on) { share_static_ = on; }

private:
    std::vector<AnimatedObject> objects_;
    std::vector<Material> materials_;
    CameraDesc camera_;
    CameraTrack camera_track_;
    std::shared_ptr<const Environment> environment_;
    std::vector<DeltaLight> delta_lights_;  // see set_delta_lights()
    AnimationRange range_;
    std::string origin_;
    bool any_moves_ = false;                  // some object has keys
    TriangleMesh static_mesh_;                // the static objects' triangles (zero-area ones dropped), object ids set
    std::shared_ptr<SharedGeometry> shared_;  // their BVH, or null
    bool share_static_ = true;                // see set_static_sharing()
};

/// What the centre of one pixel sees, and where that surface point appears
/// in the neighbouring frames.
struct PixelMotion {
    int32_t object = -1;    ///< Object id of the primary hit; -1 where the ray leaves the scene.
    Vec3 p{0.f};            ///< The hit point at the frame (scene units); unset on a miss.
    Vec2 fwd{0.f};          ///< Film position in frame k+1 minus the pixel centre (pixels).
    Vec2 bwd{0.f};          ///< Film position in frame k-1 minus the pixel centre (pixels).
    bool fwd_valid = false; ///< False if the point lies behind frame k+1's camera (fwd is then 0).
    bool bwd_valid = false; ///< Likewise for frame k-1.
};

/// The film position (pixels) in the camera at time `t_to` of the surface
/// point `p` of object `object` at time `t_from`, moved with that object's
/// transform; object -1 is a direction at infinity (p - the camera position at
/// t_from), which moves only with the camera. Exact for rigid motion up to
/// rounding. False if the point is behind the camera at t_to.
bool track_point(const AnimatedScene& anim, int32_t object, const Vec3& p, double t_from, double t_to, Vec2& film);

/// What the ray through the centre of pixel (x, y) of `scene` (anim's scene
/// at frame `frame`) sees, with its motion to frames frame + 1 and frame - 1:
/// exactly zero where neither the camera nor the point's object moves.
PixelMotion pixel_motion(const AnimatedScene& anim, const Scene& scene, int frame, int x, int y);

/// Per-pixel motion of a frame: the layers a render of an animation holds.
struct MotionLayers {
    Image fwd;        ///< "motion_fwd": 2 channels, pixels (x right, y down) to frame k+1; 0 where not visible.
    Image bwd;        ///< "motion_bwd": 2 channels, pixels to frame k-1; 0 where not visible.
    Image object_id;  ///< "object_id": 1 channel, the object id, -1 for the environment or nothing.
};

/// pixel_motion() of every pixel of `scene` (anim's scene at `frame`).
MotionLayers motion_layers(const AnimatedScene& anim, const Scene& scene, int frame);

/// Adds motion_layers() to `fb` as the layers "motion_fwd", "motion_bwd" and "object_id".
void add_motion_layers(FrameBuffer& fb, const AnimatedScene& anim, const Scene& scene, int frame);

/// Where frame `frame`'s pixels were in frame `frame` - 1, as temporal
/// seed sharing uses it (FrameSampling::replay; docs/algorithms.md, "Temporal"):
/// 2 channels per pixel, the pixel q = p + round(motion_bwd(p)) of the
/// previous frame (column, row), kept only where the round trip closes
/// (q's forward motion, rounded, lands back on p, so that q's surface is the
/// one visible at q: the nearest wins) and (-1, -1) elsewhere. `scene` is
/// anim's scene at `frame`; the previous frame's scene is built from `anim`.
Image replay_map(const AnimatedScene& anim, const Scene& scene, int frame);

/// The sampler seed of frame `frame` of a render with seed `seed`: a
/// SplitMix64 mix of both (Steele, Lea and Flood, "Fast Splittable
/// Pseudorandom Number Generators", OOPSLA 2014), below 2^63, so that every
/// frame is an independent job whose samples do not depend on which other
/// frames are rendered, or in which order.
uint64_t frame_seed(uint64_t seed, int frame);

}  // namespace gdr
