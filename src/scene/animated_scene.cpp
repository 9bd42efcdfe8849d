#include "gdr/scene/animated_scene.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <memory>
#include <vector>

#include <tbb/parallel_for.h>
#include <utility>

#include "gdr/core/error.h"

namespace gdr {

AnimatedScene::AnimatedScene(std::vector<AnimatedObject> objects, std::vector<Material> materials,
                             const CameraDesc& camera, CameraTrack camera_track,
                             std::shared_ptr<const Environment> environment, AnimationRange range, std::string origin)
    : objects_(std::move(objects)),
      materials_(std::move(materials)),
      camera_(camera),
      camera_track_(std::move(camera_track)),
      environment_(std::move(environment)),
      range_(range),
      origin_(std::move(origin)) {
    if (objects_.empty()) throw InputError(origin_ + ": an animated scene needs at least one object");
    if (range_.last < range_.first)
        throw InputError(origin_ + ": the animation's last frame " + std::to_string(range_.last) +
                         " comes before its first " + std::to_string(range_.first));
    (void)camera_at(range_.first);  // a degenerate camera is refused here, not at the first render
    for (uint32_t id = 0; id < objects_.size(); ++id) {
        const AnimatedObject& o = objects_[id];
        const TriangleMesh& m = o.mesh;
        if (m.normals.size() != m.positions.size() || m.uvs.size() != m.positions.size() ||
            m.positions.size() != 3 * m.size())
            throw InputError(origin_ + ": object " + std::to_string(id) + " (" + o.name +
                             ") needs three corners, normals and uvs per triangle");
        any_moves_ |= !o.track.empty();
    }
    if (!any_moves_) return;
    // Static triangles first, in the objects' order, as every frame's Scene will hold them.
    for (uint32_t id = 0; id < objects_.size(); ++id) {
        const AnimatedObject& o = objects_[id];
        if (!o.track.empty()) continue;
        for (size_t t = 0; t < o.mesh.size(); ++t) {
            const Vec3* p = &o.mesh.positions[3 * t];
            for (int k = 0; k < 3; ++k)
                if (!is_finite(p[k])) throw InputError(origin_ + ": object " + std::to_string(id) + " (" + o.name +
                                                       ") has a non-finite vertex");
            if (zero_area_triangle(p[0], p[1], p[2])) continue;  // as the Scene would drop it
            for (int k = 0; k < 3; ++k) {
                static_mesh_.positions.push_back(p[k]);
                static_mesh_.normals.push_back(o.mesh.normals[3 * t + k]);
                static_mesh_.uvs.push_back(o.mesh.uvs[3 * t + k]);
            }
            static_mesh_.material_ids.push_back(o.mesh.material_ids[t]);
            static_mesh_.object_ids.push_back(id);
        }
    }
    const bool cut_outs =
        std::any_of(materials_.begin(), materials_.end(), [](const Material& m) { return m.opacity != nullptr; });
    if (!cut_outs && static_mesh_.size() > 0) shared_ = std::make_shared<SharedGeometry>(static_mesh_, origin_);
}

void AnimatedScene::set_camera_optics(const CameraDesc& d) {
    CameraDesc c = camera_;
    c.width = d.width, c.height = d.height, c.fov_deg = d.fov_deg, c.fov_axis = d.fov_axis;
    if (camera_track_.empty()) c.position = d.position, c.target = d.target, c.up = d.up;
    (void)Camera(c);  // validates before anything changes
    camera_ = c;
}

Camera AnimatedScene::camera_at(double t) const {
    if (camera_track_.empty()) return Camera(camera_);
    try {
        return Camera(camera_track_.at(t).apply(camera_));
    } catch (const Error& e) {
        throw InputError(origin_ + ": the camera at frame " + std::to_string(t) + ": " + e.what());
    }
}

Mat4 AnimatedScene::object_transform(uint32_t object, double t) const {
    if (object >= objects_.size())
        throw ParameterError("object id " + std::to_string(object) + " out of range (the scene has " +
                             std::to_string(objects_.size()) + " objects)");
    return objects_[object].track.matrix_at(t);
}

namespace {

// Appends object `id`'s triangles to `all`, transformed by `xf` (a copy, bit
// for bit, when it does not move).
void append_object(TriangleMesh& all, const AnimatedObject& o, uint32_t id, double t) {
    const TriangleMesh& m = o.mesh;
    if (o.track.empty()) {
        all.positions.insert(all.positions.end(), m.positions.begin(), m.positions.end());
        all.normals.insert(all.normals.end(), m.normals.begin(), m.normals.end());
        all.uvs.insert(all.uvs.end(), m.uvs.begin(), m.uvs.end());
    } else {
        const Mat4 xf = o.track.matrix_at(t);
        const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(xf)));
        // A mirroring transform reverses the winding, and with it the emitting side.
        const bool flip = glm::determinant(glm::mat3(xf)) < 0.f;
        for (size_t tri = 0; tri < m.size(); ++tri)
            for (int k = 0; k < 3; ++k) {
                const size_t c = 3 * tri + size_t(flip && k ? 3 - k : k);
                all.positions.push_back(Vec3(xf * Vec4(m.positions[c], 1.f)));
                all.normals.push_back(nxf * m.normals[c]);
                all.uvs.push_back(m.uvs[c]);
            }
    }
    all.material_ids.insert(all.material_ids.end(), m.material_ids.begin(), m.material_ids.end());
    all.object_ids.insert(all.object_ids.end(), m.size(), id);
}

}  // namespace

std::unique_ptr<Scene> AnimatedScene::scene_at(double t) const {
    TriangleMesh all;
    if (any_moves_) {
        // The static triangles first (those of the shared BVH), the moving ones after.
        all = static_mesh_;
        for (uint32_t id = 0; id < objects_.size(); ++id)
            if (!objects_[id].track.empty()) append_object(all, objects_[id], id, t);
    } else {
        // In the file's order: a still camera makes the still scene's Scene, bit for bit.
        for (uint32_t id = 0; id < objects_.size(); ++id) append_object(all, objects_[id], id, t);
    }
    auto scene = std::make_unique<Scene>(std::move(all), materials_, camera_at(t), origin_,
                                         share_static_ ? shared_ : nullptr);
    if (environment_) scene->set_environment(environment_);
    if (!delta_lights_.empty()) scene->set_delta_lights(delta_lights_, origin_);
    return scene;
}

void AnimatedScene::set_delta_lights(std::vector<DeltaLight> lights) {
    check_delta_lights(lights, origin_);
    delta_lights_ = std::move(lights);
}

bool track_point(const AnimatedScene& anim, int32_t object, const Vec3& p, double t_from, double t_to, Vec2& film) {
    const Camera to = anim.camera_at(t_to);
    if (object < 0) {
        const Camera from = anim.camera_at(t_from);
        return to.project(to.position() + glm::normalize(p - from.position()), film);
    }
    // Through the object's own coordinates, in double: the point keeps its
    // place on the object whatever the two transforms are.
    const glm::dmat4 a(anim.object_transform(uint32_t(object), t_from)), b(anim.object_transform(uint32_t(object), t_to));
    const glm::dvec4 q = b * (glm::inverse(a) * glm::dvec4(glm::dvec3(p), 1.0));
    return to.project(Vec3(glm::dvec3(q) / q.w), film);
}

namespace {

// True if nothing that moves the point seen through a pixel changes between
// the two times: the camera and the point's object stand still. Its motion
// is then exactly zero, which the rounding of a reprojection would blur.
bool stands_still(const AnimatedScene& anim, int32_t object, double t_from, double t_to) {
    const CameraDesc a = anim.camera_at(t_from).desc(), b = anim.camera_at(t_to).desc();
    if (a.position != b.position || a.target != b.target || a.up != b.up) return false;
    return object < 0 || anim.object_transform(uint32_t(object), t_from) == anim.object_transform(uint32_t(object), t_to);
}

}  // namespace

PixelMotion pixel_motion(const AnimatedScene& anim, const Scene& scene, int frame, int x, int y) {
    const Vec2 centre(float(x) + 0.5f, float(y) + 0.5f);
    const Ray ray = scene.camera().generate_ray(centre);
    PixelMotion m;
    SurfaceInteraction si;
    Vec3 p;
    if (scene.intersect(ray, si)) {
        m.object = int32_t(scene.object_id(si.prim));
        m.p = p = si.p;
    } else {
        p = ray.o + ray.d;  // a direction: track_point takes it relative to the eye
    }
    Vec2 f;
    if (stands_still(anim, m.object, frame, frame + 1.0)) m.fwd_valid = true;
    else if (track_point(anim, m.object, p, frame, frame + 1.0, f)) m.fwd = f - centre, m.fwd_valid = true;
    if (stands_still(anim, m.object, frame, frame - 1.0)) m.bwd_valid = true;
    else if (track_point(anim, m.object, p, frame, frame - 1.0, f)) m.bwd = f - centre, m.bwd_valid = true;
    // A point far behind the eye can project to an overflowing film position.
    if (!is_finite(Vec3(m.fwd, 0.f))) m.fwd = Vec2(0.f), m.fwd_valid = false;
    if (!is_finite(Vec3(m.bwd, 0.f))) m.bwd = Vec2(0.f), m.bwd_valid = false;
    return m;
}

MotionLayers motion_layers(const AnimatedScene& anim, const Scene& scene, int frame) {
    const int w = scene.camera().width(), h = scene.camera().height();
    MotionLayers out{Image(w, h, 2), Image(w, h, 2), Image(w, h, 1)};
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const PixelMotion m = pixel_motion(anim, scene, frame, x, y);
            out.fwd.at(x, y, 0) = m.fwd.x, out.fwd.at(x, y, 1) = m.fwd.y;
            out.bwd.at(x, y, 0) = m.bwd.x, out.bwd.at(x, y, 1) = m.bwd.y;
            out.object_id.at(x, y, 0) = float(m.object);
        }
    return out;
}

void add_motion_layers(FrameBuffer& fb, const AnimatedScene& anim, const Scene& scene, int frame) {
    MotionLayers m = motion_layers(anim, scene, frame);
    fb.set("motion_fwd", std::move(m.fwd));
    fb.set("motion_bwd", std::move(m.bwd));
    fb.set("object_id", std::move(m.object_id));
}

Image replay_map(const AnimatedScene& anim, const Scene& scene, int frame) {
    const int w = scene.camera().width(), h = scene.camera().height();
    const std::unique_ptr<Scene> previous = anim.scene_at(double(frame) - 1.0);
    // The previous frame's forward motion, rounded, per pixel (INT_MIN: none).
    std::vector<std::pair<int, int>> fwd(size_t(w) * size_t(h), {INT_MIN, INT_MIN});
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const PixelMotion m = pixel_motion(anim, *previous, frame - 1, x, y);
            if (m.fwd_valid) fwd[size_t(y) * w + x] = {int(std::lround(m.fwd.x)), int(std::lround(m.fwd.y))};
        }
    });
    Image out(w, h, 2);
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            out.at(x, y, 0) = -1.f, out.at(x, y, 1) = -1.f;
            const PixelMotion m = pixel_motion(anim, scene, frame, x, y);
            if (!m.bwd_valid) continue;
            const int qx = x + int(std::lround(m.bwd.x)), qy = y + int(std::lround(m.bwd.y));
            if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
            const auto [fx, fy] = fwd[size_t(qy) * w + qx];
            if (fx == INT_MIN || qx + fx != x || qy + fy != y) continue;
            out.at(x, y, 0) = float(qx), out.at(x, y, 1) = float(qy);
        }
    });
    return out;
}

uint64_t frame_seed(uint64_t seed, int frame) {
    const auto mix = [](uint64_t z) {
        z += 0x9e3779b97f4a7c15ull;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    };
    return mix(mix(seed) ^ uint64_t(int64_t(frame))) & 0x7fffffffffffffffull;
}

}  // namespace gdr
