// Animation: keyframe interpolation, scenes at a frame, object ids, exact
// motion vectors, per-frame renders from the command line, the temporal
// error of gdr compare --frames, and the scene file's errors for bad keys.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include <fmt/core.h>
#include <glm/gtc/matrix_transform.hpp>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/metrics.h"
#include "gdr/scene/animated_scene.h"
#include "cli_test_util.h"
#include "public_scenes.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

const std::string kCornell = GDR_SOURCE_DIR "/scenes/cornell-box/";

void write_text(const std::string& path, const std::string& text) {
    std::ofstream f(path);
    f << text;
}

// The angle (radians) of the rotation between two unit quaternions.
double angle_between(const Quat& a, const Quat& b) {
    // From the vector part of a^-1 b: an arc cosine of a dot product near 1 would lose half the digits.
    const glm::dquat q = glm::conjugate(glm::dquat(a)) * glm::dquat(b);
    return 2.0 * std::asin(std::min(1.0, std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z)));
}

FrameBuffer render_pt(const Scene& scene, uint64_t seed, long long spp = 4) {
    auto pt = integrator_registry().create("pt", Params("test"));
    RenderSettings st;
    st.spp = spp;
    st.seed = seed;
    FrameBuffer fb;
    pt->render(scene, st, fb, {});
    return fb;
}

bool same_layer(const FrameBuffer& a, const FrameBuffer& b, const std::string& layer) {
    return a.get(layer).values() == b.get(layer).values();
}

// A square of side 2 in the plane z = z0 facing +z, centred on (cx, cy).
std::string quad_obj(float cx, float cy, float z0, float half) {
    return "v " + std::to_string(cx - half) + " " + std::to_string(cy - half) + " " + std::to_string(z0) + "\n" +
           "v " + std::to_string(cx + half) + " " + std::to_string(cy - half) + " " + std::to_string(z0) + "\n" +
           "v " + std::to_string(cx + half) + " " + std::to_string(cy + half) + " " + std::to_string(z0) + "\n" +
           "v " + std::to_string(cx - half) + " " + std::to_string(cy + half) + " " + std::to_string(z0) + "\n" +
           "f 1 2 3\nf 1 3 4\n";
}

// An independent pinhole projection (double precision, look-at convention of camera.h).
struct LookAt {
    glm::dvec3 eye, f, r, u;
    double tx, ty;
    int w, h;
    LookAt(glm::dvec3 e, glm::dvec3 target, glm::dvec3 up, double fov_y_deg, int width, int height)
        : eye(e), w(width), h(height) {
        f = glm::normalize(target - e);
        r = glm::normalize(glm::cross(f, up));
        u = glm::cross(r, f);
        ty = std::tan(0.5 * fov_y_deg * 3.14159265358979323846 / 180.0);
        tx = ty * double(width) / double(height);
    }
    glm::dvec2 project(const glm::dvec3& p) const {
        const glm::dvec3 v = p - eye;
        const double z = glm::dot(v, f);
        return {(glm::dot(v, r) / (z * tx) + 1.0) * 0.5 * w, (1.0 - glm::dot(v, u) / (z * ty)) * 0.5 * h};
    }
    glm::dvec3 direction(double px, double py) const {
        const double sx = 2.0 * px / w - 1.0, sy = 1.0 - 2.0 * py / h;
        return glm::normalize(f + sx * tx * r + sy * ty * u);
    }
};

}  // namespace

TEST_CASE("animation: keys are hit exactly and held outside the track", "[animation]") {
    TransformTrack t;
    TransformValue a, b;
    a.translate = Vec3(0.1f, 0.2f, 0.3f), a.scale = Vec3(1.f, 2.f, 3.f);
    a.rotate = glm::angleAxis(0.3f, glm::normalize(Vec3(1.f, 2.f, 3.f)));
    b.translate = Vec3(-1.7f, 4.f, 0.25f), b.scale = Vec3(3.f);
    b.rotate = glm::angleAxis(1.1f, glm::normalize(Vec3(0.f, 1.f, 0.f)));
    t.keys = {{1.5, a}, {4.0, b}};
    for (double f : {1.5, 4.0, -3.0, 9.0}) {
        const TransformValue& want = f < 3.0 ? a : b;
        const TransformValue got = t.at(f);
        CHECK(got.translate == want.translate);
        CHECK(got.scale == want.scale);
        CHECK(got.rotate == want.rotate);
        CHECK(t.matrix_at(f) == want.matrix());
    }
    CHECK(TransformTrack{}.matrix_at(2.0) == Mat4(1.f));
    // Scale, then rotate, then translate, as a scene file's "transform".
    const Vec3 p(0.3f, -1.2f, 2.f);
    const Vec3 want = a.translate + a.rotate * (a.scale * p);
    CHECK(glm::length(Vec3(t.matrix_at(1.5) * Vec4(p, 1.f)) - want) < 1e-5f);
}

TEST_CASE("animation: translation and scale are linear, rotation is slerp", "[animation]") {
    TransformTrack t;
    TransformValue a, b;
    a.translate = Vec3(0.f), a.scale = Vec3(1.f), a.rotate = Quat(1.f, 0.f, 0.f, 0.f);
    b.translate = Vec3(4.f, -2.f, 8.f), b.scale = Vec3(3.f, 5.f, 1.f);
    b.rotate = glm::angleAxis(glm::radians(120.f), Vec3(0.f, 0.f, 1.f));
    t.keys = {{10.0, a}, {20.0, b}};
    for (double u : {0.25, 0.5, 0.8}) {
        const TransformValue v = t.at(10.0 + 10.0 * u);
        CHECK(v.translate.x == Approx(4.0 * u).margin(1e-6));
        CHECK(v.translate.y == Approx(-2.0 * u).margin(1e-6));
        CHECK(v.scale.y == Approx(1.0 + 4.0 * u).margin(1e-6));
        // Slerp turns at a constant rate: a fraction u of 120 degrees about z
        // (a normalised linear blend would be off by degrees at u = 1/4).
        const Quat want = glm::angleAxis(glm::radians(float(120.0 * u)), Vec3(0.f, 0.f, 1.f));
        CHECK(angle_between(v.rotate, want) < 1e-5);
    }
    // The shorter arc: keys at +170 and -170 degrees turn through 180, not through 0.
    TransformTrack s;
    TransformValue c, d;
    c.rotate = glm::angleAxis(glm::radians(170.f), Vec3(0.f, 1.f, 0.f));
    d.rotate = glm::angleAxis(glm::radians(-170.f), Vec3(0.f, 1.f, 0.f));
    s.keys = {{0.0, c}, {1.0, d}};
    CHECK(angle_between(s.at(0.5).rotate, glm::angleAxis(glm::radians(180.f), Vec3(0.f, 1.f, 0.f))) < 1e-5);
}

TEST_CASE("animation: the camera track interpolates look-at keys", "[animation]") {
    CameraTrack c;
    // Looking along -z at frame 0, turned 90 degrees about y (along +x) at frame 2.
    c.keys = {{0.0, CameraPose::look_at(Vec3(0.f, 0.f, 3.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f))},
              {2.0, CameraPose::look_at(Vec3(2.f, 0.f, 3.f), Vec3(3.f, 0.f, 3.f), Vec3(0.f, 1.f, 0.f))}};
    const CameraDesc mid = c.at(1.0).apply(CameraDesc{});
    CHECK(mid.position.x == Approx(1.0).margin(1e-6));
    const Vec3 fw = glm::normalize(mid.target - mid.position);
    // Halfway through the turn: 45 degrees between -z and +x.
    CHECK(fw.x == Approx(std::sqrt(0.5)).margin(1e-5));
    CHECK(fw.z == Approx(-std::sqrt(0.5)).margin(1e-5));
    CHECK(mid.up.y == Approx(1.0).margin(1e-5));
    const CameraDesc k0 = c.at(0.0).apply(CameraDesc{});
    CHECK(glm::length(glm::normalize(k0.target - k0.position) - Vec3(0.f, 0.f, -1.f)) < 1e-6);
}

TEST_CASE("animation: a scene that does not move renders its frames as the still scene", "[animation]") {
    const test::OutDir dir("anim-still");
    const std::string obj = kCornell + "CornellBox-Original.obj";
    const std::string camera = R"("camera": {"position": [0.3, 1.1, 3.4], "target": [0, 0.9, 0], "width": 24, "height": 20})";
    write_text(dir("still.json"), "{" + camera + R"(, "meshes": [{"file": ")" + obj + R"("}]})");
    // No keys at all, and keys that leave the mesh where it is.
    write_text(dir("anim.json"), "{" + camera + R"(, "animation": {"first": 0, "last": 3}, "meshes": [{"file": ")" +
                                     obj + R"(", "keys": [{"frame": 0}, {"frame": 3, "translate": [0, 0, 0]}]}]})");
    write_text(dir("nokeys.json"), "{" + camera + R"(, "animation": {"first": 0, "last": 3}, "meshes": [{"file": ")" +
                                       obj + R"("}]})");
    const SceneFile still = load_scene_file(dir("still.json"));
    CHECK_FALSE(still.animation);
    const FrameBuffer ref = render_pt(*still.scene, 77);
    for (const char* name : {"anim.json", "nokeys.json"}) {
        SceneFile sf = load_scene_file(dir(name));
        REQUIRE(sf.animation);
        for (int k : {2, 0}) {
            set_frame(sf, k);
            CHECK(sf.frame == k);
            const FrameBuffer fb = render_pt(*sf.scene, 77);
            CHECK(same_layer(fb, ref, "color"));
            CHECK(same_layer(fb, ref, "depth"));
        }
    }
}

TEST_CASE("animation: motion vectors of a translating quad are its projected translation", "[animation]") {
    const test::OutDir dir("anim-quad");
    write_text(dir("wall.obj"), quad_obj(0.f, 0.f, -2.f, 20.f));  // object 0: a static wall behind
    write_text(dir("quad.obj"), quad_obj(0.f, 0.f, 0.f, 0.5f));   // object 1: the moving square
    // Per frame the quad moves by (0.1, 0.05) parallel to the image plane, at depth 3.
    write_text(dir("scene.json"), R"({"animation": {"first": 0, "last": 4, "fps": 24},
      "camera": {"position": [0, 0, 3], "target": [0, 0, 0], "fov": 40, "width": 48, "height": 40},
      "meshes": [{"file": "wall.obj"},
                 {"file": "quad.obj", "keys": [{"frame": 0, "translate": [-0.2, -0.1, 0]},
                                              {"frame": 4, "translate": [0.2, 0.1, 0]}]}]})");
    SceneFile sf = load_scene_file(dir("scene.json"));
    set_frame(sf, 2);
    const double f_px = 0.5 * 40 / std::tan(0.5 * 40.0 * 3.14159265358979323846 / 180.0);  // pixels per unit at depth 1
    const double mx = 0.1 * f_px / 3.0, my = -0.05 * f_px / 3.0;  // film y points down
    const LookAt cam(glm::dvec3(0, 0, 3), glm::dvec3(0), glm::dvec3(0, 1, 0), 40.0, 48, 40);
    const MotionLayers m = motion_layers(*sf.animation, *sf.scene, 2);
    int on_quad = 0, wall_moving = 0;
    double worst = 0.0;
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 48; ++x) {
            // Analytically: where the centre ray meets z = 0, and whether that is on the quad at frame 2 (centre 0).
            const glm::dvec3 d = cam.direction(x + 0.5, y + 0.5);
            const glm::dvec3 p = cam.eye + d * (3.0 / -d.z);
            const double margin = 1e-3;
            if (std::abs(std::abs(p.x) - 0.5) < margin || std::abs(std::abs(p.y) - 0.5) < margin) continue;
            const bool quad = std::abs(p.x) < 0.5 && std::abs(p.y) < 0.5;
            REQUIRE(m.object_id.at(x, y) == (quad ? 1.f : 0.f));
            if (!quad) {
                // The static wall seen by a static camera does not move: exactly zero motion.
                for (int c = 0; c < 2; ++c) wall_moving += m.fwd.at(x, y, c) != 0.f || m.bwd.at(x, y, c) != 0.f;
                continue;
            }
            ++on_quad;
            worst = std::max(worst, std::abs(m.fwd.at(x, y, 0) - mx));
            worst = std::max(worst, std::abs(m.fwd.at(x, y, 1) - my));
            worst = std::max(worst, std::abs(m.bwd.at(x, y, 0) + mx));
            worst = std::max(worst, std::abs(m.bwd.at(x, y, 1) + my));
        }
    CHECK(on_quad > 40);
    CHECK(wall_moving == 0);
    CHECK(worst < 1e-3);
    INFO("worst error " << worst << " px");
}

TEST_CASE("animation: motion vectors of a moving, turning camera over a static plane match the projection",
          "[animation]") {
    const test::OutDir dir("anim-camera");
    write_text(dir("plane.obj"), quad_obj(0.f, 0.f, 0.f, 50.f));
    write_text(dir("scene.json"), R"({"animation": {"first": 0, "last": 2},
      "camera": {"fov": 50, "width": 40, "height": 32,
                 "keys": [{"frame": 0, "position": [0, 0, 3], "target": [0, 0, 0]},
                          {"frame": 1, "position": [0.3, 0.1, 2.8], "target": [0.2, -0.1, 0], "up": [0.1, 1, 0]},
                          {"frame": 2, "position": [0.5, 0.3, 2.7], "target": [0.6, 0.1, 0]}]},
      "meshes": [{"file": "plane.obj"}]})");
    SceneFile sf = load_scene_file(dir("scene.json"));
    set_frame(sf, 1);
    const LookAt c0(glm::dvec3(0, 0, 3), glm::dvec3(0), glm::dvec3(0, 1, 0), 50.0, 40, 32);
    const LookAt c1(glm::dvec3(0.3, 0.1, 2.8), glm::dvec3(0.2, -0.1, 0), glm::dvec3(0.1, 1, 0), 50.0, 40, 32);
    const LookAt c2(glm::dvec3(0.5, 0.3, 2.7), glm::dvec3(0.6, 0.1, 0), glm::dvec3(0, 1, 0), 50.0, 40, 32);
    const MotionLayers m = motion_layers(*sf.animation, *sf.scene, 1);
    double worst = 0.0;
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 40; ++x) {
            const glm::dvec3 d = c1.direction(x + 0.5, y + 0.5);
            const glm::dvec3 p = c1.eye + d * (-c1.eye.z / d.z);
            const glm::dvec2 centre(x + 0.5, y + 0.5), f = c2.project(p) - centre, b = c0.project(p) - centre;
            REQUIRE(m.object_id.at(x, y) == 0.f);
            worst = std::max({worst, std::abs(m.fwd.at(x, y, 0) - f.x), std::abs(m.fwd.at(x, y, 1) - f.y),
                              std::abs(m.bwd.at(x, y, 0) - b.x), std::abs(m.bwd.at(x, y, 1) - b.y)});
        }
    INFO("worst error " << worst << " px");
    CHECK(worst < 1e-3);
    // A ray that leaves the scene moves with the camera's rotation alone; its object id is -1.
    write_text(dir("small.json"), R"({"animation": {"first": 0, "last": 1},
      "camera": {"fov": 50, "width": 40, "height": 32,
                 "keys": [{"frame": 0, "position": [0, 0, 3], "target": [0, 0, 0]},
                          {"frame": 1, "position": [5, 0, 3], "target": [5.3, 0, 2]}]},
      "meshes": [{"file": "quad.obj"}]})");
    write_text(dir("quad.obj"), quad_obj(0.f, 0.f, -100.f, 0.01f));
    SceneFile s2 = load_scene_file(dir("small.json"));
    const PixelMotion pm = pixel_motion(*s2.animation, *s2.scene, 0, 3, 4);
    CHECK(pm.object == -1);
    const LookAt d1(glm::dvec3(5, 0, 3), glm::dvec3(5.3, 0, 2), glm::dvec3(0, 1, 0), 50.0, 40, 32);
    const glm::dvec2 want = d1.project(d1.eye + c0.direction(3.5, 4.5)) - glm::dvec2(3.5, 4.5);
    CHECK(pm.fwd_valid);
    CHECK(std::abs(pm.fwd.x - want.x) < 1e-3);
    CHECK(std::abs(pm.fwd.y - want.y) < 1e-3);
}

TEST_CASE("animation: every hit knows its object, the scene-file mesh entry", "[animation]") {
    const test::OutDir dir("anim-ids");
    write_text(dir("a.obj"), quad_obj(-1.f, 0.f, 0.f, 0.4f));
    write_text(dir("b.obj"), quad_obj(1.f, 0.f, 0.f, 0.4f));
    const std::string meshes = R"("meshes": [{"file": "a.obj"}, {"file": "b.obj"}, {"file": "a.obj",
        "transform": {"translate": [0, 1, 0]}}])";
    const std::string camera = R"("camera": {"position": [0, 0, 4], "target": [0, 0, 0]})";
    write_text(dir("still.json"), "{" + camera + ", " + meshes + "}");
    write_text(dir("anim.json"), "{" + camera + R"(, "animation": {"first": 0, "last": 1}, )" + meshes + "}");
    for (const char* name : {"still.json", "anim.json"}) {
        const SceneFile sf = load_scene_file(dir(name));
        const std::pair<Vec3, uint32_t> probes[] = {{Vec3(-1.f, 0.f, 0.f), 0}, {Vec3(1.f, 0.f, 0.f), 1},
                                                    {Vec3(-1.f, 1.f, 0.f), 2}};
        for (const auto& [target, id] : probes) {
            SurfaceInteraction si;
            REQUIRE(sf.scene->intersect(Ray{Vec3(target.x, target.y, 4.f), Vec3(0.f, 0.f, -1.f)}, si));
            CHECK(sf.scene->object_id(si.prim) == id);
        }
    }
}

TEST_CASE("animation: bad keys are errors naming the file and the key", "[animation][errors]") {
    const test::OutDir dir("anim-bad");
    write_text(dir("q.obj"), quad_obj(0.f, 0.f, 0.f, 1.f));
    const auto error_for = [&](const std::string& body) {
        write_text(dir("s.json"), "{" + body + "}");
        try {
            load_scene_file(dir("s.json"));
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    const std::string cam = R"("camera": {"position": [0, 0, 4], "target": [0, 0, 0]}, )";
    const std::string anim = R"("animation": {"first": 0, "last": 9}, )";
    const auto mesh_keys = [&](const std::string& keys) {
        return error_for(cam + anim + R"("meshes": [{"file": "q.obj", "keys": )" + keys + "}]");
    };
    CHECK_THAT(mesh_keys(R"([{"frame": 3}, {"frame": 3}])"),
               Contains(dir("s.json")) && Contains("meshes[0].keys[1].frame") && Contains("increasing"));
    CHECK_THAT(mesh_keys(R"([{"frame": 5}, {"frame": 2}])"), Contains("meshes[0].keys[1].frame"));
    CHECK_THAT(mesh_keys(R"([{"frame": 1, "spin": 3}])"), Contains("unknown key 'spin'") && Contains("meshes[0].keys[0]"));
    CHECK_THAT(mesh_keys(R"([{"translate": [1, 2, 3]}])"), Contains("meshes[0].keys[0] needs a 'frame'"));
    CHECK_THAT(mesh_keys(R"([{"frame": 0, "quaternion": [1, 1, 0, 0]}])"),
               Contains("meshes[0].keys[0].quaternion") && Contains("norm"));
    CHECK_THAT(mesh_keys(R"([{"frame": 0, "quaternion": [1, 0, 0]}])"), Contains("meshes[0].keys[0].quaternion"));
    CHECK_THAT(mesh_keys(R"([{"frame": 0, "quaternion": [1, 0, 0, 0], "rotate": [0, 1, 0, 9]}])"),
               Contains("both 'rotate' and 'quaternion'"));
    CHECK_THAT(mesh_keys(R"([{"frame": 0, "rotate": [0, 0, 0, 9]}])"), Contains("zero axis"));
    CHECK_THAT(mesh_keys(R"([{"frame": 0, "scale": 0}])"), Contains("meshes[0].keys[0].scale"));
    CHECK_THAT(mesh_keys("[]"), Contains("meshes[0].keys"));
    CHECK(mesh_keys(R"([{"frame": 0, "quaternion": [0.70710678, 0, 0.70710678, 0]}, {"frame": 2.5}])").empty());
    // Keys need the animation block; the block is checked.
    CHECK_THAT(error_for(cam + R"("meshes": [{"file": "q.obj", "keys": [{"frame": 0}]}])"),
               Contains("no 'animation' block"));
    CHECK_THAT(error_for(cam + R"("animation": {"first": 4, "last": 2}, "meshes": ["q.obj"])"),
               Contains("animation.last"));
    CHECK_THAT(error_for(cam + R"("animation": {"first": 0, "last": 2, "rate": 3}, "meshes": ["q.obj"])"),
               Contains("unknown key 'rate' in animation"));
    CHECK_THAT(error_for(cam + R"("animation": {"first": 0.5, "last": 2}, "meshes": ["q.obj"])"),
               Contains("animation.first"));
    // Camera keys.
    const auto camera_keys = [&](const std::string& keys) {
        return error_for(R"("camera": {"keys": )" + keys + "}, " + anim + R"("meshes": ["q.obj"])");
    };
    CHECK_THAT(camera_keys(R"([{"frame": 0, "position": [0, 0, 4]}])"), Contains("camera.keys[0]") && Contains("target"));
    CHECK_THAT(camera_keys(R"([{"frame": 0, "position": [0, 0, 4], "target": [0, 0, 4]}])"),
               Contains("camera.keys[0]") && Contains("coincide"));
    CHECK_THAT(camera_keys(R"([{"frame": 0, "matrix": [2,0,0,0, 0,1,0,0, 0,0,1,4, 0,0,0,1]}])"),
               Contains("camera.keys[0].matrix") && Contains("rotation"));
    CHECK_THAT(camera_keys(R"([{"frame": 0, "position": [0, 0, 4], "target": [0, 0, 0]}, {"frame": -1,
        "position": [0, 0, 4], "target": [0, 0, 0]}])"), Contains("camera.keys[1].frame"));
    CHECK(camera_keys(R"([{"frame": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,4, 0,0,0,1]}])").empty());
    CHECK_THAT(error_for(R"("camera": {"position": [0, 0, 4], "keys": [{"frame": 0, "position": [0, 0, 4],
        "target": [0, 0, 0]}]}, )" + anim + R"("meshes": ["q.obj"])"), Contains("'camera.position' is ignored"));
    // A frame outside the range.
    write_text(dir("ok.json"), "{" + cam + anim + R"("meshes": ["q.obj"]})");
    SceneFile sf = load_scene_file(dir("ok.json"));
    CHECK_THROWS_WITH(set_frame(sf, 10), Contains("frame 10") && Contains("0 to 9"));
}

TEST_CASE("animation: a camera matrix key equals the look-at key it encodes", "[animation]") {
    const test::OutDir dir("anim-matrix");
    write_text(dir("q.obj"), quad_obj(0.f, 0.f, 0.f, 1.f));
    // Camera-to-world: columns right, up, backwards and the eye point, turned 90 degrees about y (looking along -x).
    write_text(dir("m.json"), R"({"animation": {"first": 0, "last": 0}, "camera": {"keys": [{"frame": 0,
        "matrix": [0,0,1,5, 0,1,0,1, -1,0,0,2, 0,0,0,1]}]}, "meshes": ["q.obj"]})");
    const SceneFile sf = load_scene_file(dir("m.json"));
    const Camera& c = sf.scene->camera();
    CHECK(glm::length(c.position() - Vec3(5.f, 1.f, 2.f)) < 1e-6f);
    CHECK(glm::length(c.forward() - Vec3(-1.f, 0.f, 0.f)) < 1e-6f);
}

TEST_CASE("animation: frame seeds depend on the seed and the frame only", "[animation]") {
    CHECK(frame_seed(0, 0) == frame_seed(0, 0));
    CHECK(frame_seed(0, 0) != frame_seed(0, 1));
    CHECK(frame_seed(0, 1) != frame_seed(1, 1));
    CHECK(frame_seed(7, -3) != frame_seed(7, 3));
    CHECK(frame_seed(~0ull, 12) < (1ull << 63));
}

TEST_CASE("cli: frames rendered in any order or in separate runs are the same files", "[animation][cli]") {
    const test::OutDir dir("anim-cli");
    const std::string anim = kCornell + "animation.json";
    const std::vector<std::string> common = {"--resolution", "20x20", "--spp", "2", "--seed", "4"};
    const auto run = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = {"render", anim};
        args.insert(args.end(), common.begin(), common.end());
        args.insert(args.end(), extra.begin(), extra.end());
        return cli::run(args);
    };
    REQUIRE(run({"--frames", "3:5", "-o", dir("a.%04d.exr")}) == 0);
    REQUIRE(run({"--frame", "5", "-o", dir("b.%04d.exr")}) == 0);
    REQUIRE(run({"--frames", "3:4", "-o", dir("b.%04d.exr")}) == 0);
    for (int k = 3; k <= 5; ++k) {
        const std::string name = fmt::format(".{:04d}.exr", k);
        const FrameBuffer a = read_exr(dir("a" + name)), b = read_exr(dir("b" + name));
        for (const char* layer : {"color", "variance", "motion_fwd", "motion_bwd", "object_id"})
            CHECK(same_layer(a, b, layer));
        CHECK(a.metadata().at("seed") == b.metadata().at("seed"));
        CHECK(a.metadata().at("frame") == std::to_string(k));
        CHECK(a.metadata().at("seed") == std::to_string(frame_seed(4, k)));
    }
    // Frames are independent renders: their noise differs even where the image does not.
    const FrameBuffer f3 = read_exr(dir("a.0003.exr")), f4 = read_exr(dir("a.0004.exr"));
    CHECK_FALSE(same_layer(f3, f4, "color"));
    // A frame pattern is required for several frames; an input is never overwritten.
    CHECK_THAT(test::error_of({"render", anim, "--frames", "0:1", "-o", dir("x.exr")}), Contains("frame number pattern"));
    CHECK_THAT(test::error_of({"render", anim, "--frames", "0:1", "-o", dir("x.%04d.%d.exr")}), Contains("two"));
    CHECK_THAT(test::error_of({"render", anim, "--frames", "3:4", "--resume", dir("a.%04d.exr"), "-o", dir("a.%04d.exr")}),
               Contains("a.0003.exr"));
    CHECK_THAT(test::error_of({"render", anim, "--frame", "48", "-o", dir("x.exr")}), Contains("frame 48"));
    CHECK_THAT(test::error_of({"submit", anim, "--parts", "2", "--dry-run", "-o", dir("s.exr")}),
               Contains("is an animation"));
    CHECK_THAT(test::error_of({"render", GDR_SOURCE_DIR "/scenes/cornell-box/scene.json", "--frame", "0", "-o",
                               dir("x.exr")}),
               Contains("animation"));
}

TEST_CASE("cli: --resume and merge work per frame and refuse another frame", "[animation][cli]") {
    const test::OutDir dir("anim-resume");
    const std::string anim = kCornell + "animation.json";
    const std::vector<std::string> c = {"render", anim, "--resolution", "16x16", "--seed", "2"};
    const auto run = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = c;
        args.insert(args.end(), extra.begin(), extra.end());
        return cli::run(args);
    };
    REQUIRE(run({"--frames", "6:7", "--spp", "2", "-o", dir("p.%02d.exr")}) == 0);
    REQUIRE(run({"--frames", "6:7", "--spp", "4", "--resume", dir("p.%02d.exr"), "-o", dir("r.%02d.exr")}) == 0);
    REQUIRE(run({"--frames", "6:7", "--spp", "4", "-o", dir("full.%02d.exr")}) == 0);
    for (const char* k : {"06", "07"}) {
        const FrameBuffer r = read_exr(dir(std::string("r.") + k + ".exr")), f = read_exr(dir(std::string("full.") + k + ".exr"));
        double worst = 0.0;
        for (size_t i = 0; i < f.get("color").values().size(); ++i)
            worst = std::max(worst, std::abs(double(r.get("color").values()[i]) - f.get("color").values()[i]) /
                                        (std::abs(double(f.get("color").values()[i])) + 1e-6));
        CHECK(worst < 1e-5);
        CHECK(same_layer(r, f, "motion_fwd"));
        CHECK(same_layer(r, f, "object_id"));
    }
    CHECK_THAT(test::error_of({"render", anim, "--resolution", "16x16", "--frame", "7", "--spp", "4", "--resume",
                               dir("p.06.exr"), "-o", dir("bad.exr")}),
               Contains("'frame'") && Contains("frame 6"));
    // Merging a second seed per frame; another frame is refused.
    REQUIRE(cli::run({"render", anim, "--resolution", "16x16", "--seed", "3", "--frames", "6:7", "--spp", "2", "-o",
                      dir("q.%02d.exr")}) == 0);
    REQUIRE(cli::run({"merge", "--frames", "6:7", dir("p.%02d.exr"), dir("q.%02d.exr"), "-o", dir("m.%02d.exr")}) == 0);
    const FrameBuffer m = read_exr(dir("m.07.exr")), p = read_exr(dir("p.07.exr"));
    CHECK(m.metadata().at("spp") == "4");
    CHECK(same_layer(m, p, "motion_bwd"));
    CHECK_THAT(test::error_of({"merge", dir("p.06.exr"), dir("q.07.exr"), "-o", dir("bad.exr")}), Contains("'frame'"));
}

TEST_CASE("compare --frames: per-frame and temporal relMSE of constructed sequences", "[animation][cli]") {
    const test::OutDir dir("anim-compare");
    // Constant images: reference 1, 1, 2; image 1.25, 0.75, 2.
    const float ref[] = {1.f, 1.f, 2.f}, img[] = {1.25f, 0.75f, 2.f};
    std::vector<Image> is, rs;
    for (int k = 0; k < 3; ++k) {
        FrameBuffer a(4, 3), b(4, 3);
        a.set("color", Image(4, 3, 3, img[k]));
        b.set("color", Image(4, 3, 3, ref[k]));
        write_exr(dir("i." + std::to_string(k) + ".exr"), a);
        write_exr(dir("r." + std::to_string(k) + ".exr"), b);
        is.push_back(a.get("color")), rs.push_back(b.get("color"));
    }
    // By hand: frames 0.0625/1.01 (twice) and 0; pairs (-0.5)^2/1.01 and 0.25^2/(1.5^2+0.01).
    const double e0 = 0.0625 / 1.01, t = 0.5 * (0.25 / 1.01 + 0.0625 / 2.26);
    CHECK(temporal_relmse(is, rs) == Approx(t).epsilon(1e-6));
    const std::string text = test::stdout_of([&] {
        cli::run({"compare", "--frames", dir("i.%d.exr"), dir("r.%d.exr"), "0:2"});
    });
    const auto number = [&](const std::string& label) {
        std::smatch m;
        REQUIRE(std::regex_search(text, m, std::regex(label + "\\s+([0-9.e+-]+)")));
        return std::stod(m[1]);
    };
    CHECK(number("frame 0: relMSE") == Approx(e0).epsilon(1e-5));
    CHECK(number("frame 1: relMSE") == Approx(e0).epsilon(1e-5));
    CHECK(number("frame 2: relMSE") == 0.0);
    CHECK(number("mean relMSE:") == Approx(2.0 * e0 / 3.0).epsilon(1e-5));
    CHECK(number("temporal relMSE:") == Approx(t).epsilon(1e-5));
    // A sequence that is off by a constant has no flicker.
    std::vector<Image> shifted;
    for (const Image& r : rs) {
        Image s = r;
        for (float& v : s.values()) v += 0.3f;
        shifted.push_back(s);
    }
    CHECK(temporal_relmse(shifted, rs) == Approx(0.0).margin(1e-12));
    CHECK_THROWS_AS(temporal_relmse({is[0]}, {rs[0]}), ParameterError);
    CHECK_THAT(test::error_of({"compare", "--frames", dir("i.exr"), dir("r.%d.exr"), "0:2"}),
               Contains("frame number pattern"));
}

TEST_CASE("animation: the bundled animations span 48 frames and move what they say", "[animation]") {
    SceneFile cam = load_scene_file(kCornell + "animation.json");
    REQUIRE(cam.animation);
    CHECK(cam.animation->range().count() == 48);
    CHECK(cam.animation->range().fps == 24.0);
    // A resolution chosen after loading holds for every frame, from the animation itself too.
    set_resolution(cam, 40, 30);
    CHECK(cam.animation->scene_at(5.0)->camera().width() == 40);
    set_frame(cam, 3);
    CHECK(cam.scene->camera().height() == 30);
    set_resolution(cam, 256, 256);
    CHECK_FALSE(cam.animation->moves(0));
    // The camera moves: the back wall's centre pixel has motion, the object ids are the box's.
    set_frame(cam, 10);
    const int w = cam.scene->camera().width(), h = cam.scene->camera().height();
    const PixelMotion c = pixel_motion(*cam.animation, *cam.scene, 10, w / 2, h / 2);
    CHECK(c.object == 0);
    CHECK(glm::length(c.fwd) > 0.05f);
    CHECK(glm::length(c.fwd) < 5.f);

    const std::string moving = kCornell + "moving-object.json";
    SceneFile mo = load_scene_file(moving);
    REQUIRE(mo.animation);
    CHECK(mo.animation->range().count() == 48);
    CHECK(mo.animation->moves(1));
    CHECK_FALSE(mo.animation->moves(0));
    set_frame(mo, 20);
    const MotionLayers m = motion_layers(*mo.animation, *mo.scene, 20);
    int cow = 0, box = 0, box_moving = 0;
    for (int y = 0; y < m.object_id.height(); ++y)
        for (int x = 0; x < m.object_id.width(); ++x) {
            const float id = m.object_id.at(x, y);
            const float speed = std::hypot(m.fwd.at(x, y, 0), m.fwd.at(x, y, 1));
            if (id == 1.f) cow += speed > 0.1f;
            if (id == 0.f) ++box, box_moving += speed != 0.f;
        }
    CHECK(cow > 1000);  // the cow covers thousands of the 256x256 pixels, all moving
    CHECK(box > 10000);
    CHECK(box_moving == 0);  // the box and the camera stand still
}

TEST_CASE("animation: frames on the shared static BVH render as frames with one BVH over all", "[animation]") {
    const test::OutDir dir("anim-shared");
    write_text(dir("quad.obj"), quad_obj(0.f, 0.f, 0.f, 0.25f));
    write_text(dir("scene.json"), R"({"animation": {"first": 0, "last": 4},
      "camera": {"position": [0, 1, 3.5], "target": [0, 1, 0], "width": 24, "height": 24},
      "meshes": [{"file": ")" + kCornell + R"(CornellBox-Original.obj"},
                 {"file": "quad.obj", "keys": [{"frame": 0, "translate": [-0.5, 0.5, 0.3], "rotate": [0, 1, 0, 20]},
                                              {"frame": 4, "translate": [0.5, 1.2, 0.1], "rotate": [1, 1, 0, 80]}]}]})");
    SceneFile sf = load_scene_file(dir("scene.json"));
    REQUIRE(sf.animation->shares_static_geometry());
    for (const char* integrator : {"pt", "gpt"}) {
        for (double t : {1.0, 2.5}) {
            sf.animation->set_static_sharing(true);
            const auto shared = sf.animation->scene_at(t);
            sf.animation->set_static_sharing(false);
            const auto flat = sf.animation->scene_at(t);
            sf.animation->set_static_sharing(true);
            auto in = integrator_registry().create(integrator, Params("test"));
            RenderSettings st;
            st.spp = 2, st.seed = 5;
            FrameBuffer a, b;
            in->render(*shared, st, a, {});
            in->render(*flat, st, b, {});
            INFO(integrator << " at t = " << t);
            for (const std::string& layer : a.names()) CHECK(same_layer(a, b, layer));
            // The moving quad is there, at its place of the frame: object 1 is hit.
            const MotionLayers m = motion_layers(*sf.animation, *shared, int(t));
            int quad = 0;
            for (float id : m.object_id.values()) quad += id == 1.f;
            CHECK(quad > 0);
        }
    }
}
