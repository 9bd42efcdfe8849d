// Scene loading and the Embree scene: every kind of bad input is a gdr::Error
// naming the file (and key), never a crash or a silent default; good input
// gives hits with the documented conventions (winding, one-sided emitters).
#include <catch2/catch.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "gdr/core/error.h"
#include "gdr/core/sampler.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"
#include "gdr/scene/scene.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

const std::string kBad = GDR_SOURCE_DIR "/tests/scenes/bad/";

// The message of the gdr::Error that `f` throws ("" if it throws none).
template <class F>
std::string error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

// A triangle soup from corner triples, all with material 0.
TriangleMesh soup(const std::vector<Vec3>& corners) {
    TriangleMesh m;
    m.positions = corners;
    m.material_ids.assign(corners.size() / 3, 0u);
    return m;
}

std::vector<Material> one_material(Color emission = Color(0.f)) {
    return {Material{"m", make_lambertian(make_constant_texture(Color(0.5f))), emission}};
}

// A fresh directory under the system's temporary one, removed with the object.
struct TempDir {
    std::filesystem::path path;
    explicit TempDir(const std::string& name)
        : path(std::filesystem::temp_directory_path() / ("gdr-test-" + name + "-" + std::to_string(getpid()))) {
        std::filesystem::remove_all(path);
        std::filesystem::create_directories(path);
    }
    ~TempDir() { std::filesystem::remove_all(path); }
    // Writes `text` to the file `name` in it; returns its path.
    std::string write(const std::string& name, const std::string& text) const {
        std::ofstream(path / name, std::ios::binary) << text;
        return (path / name).string();
    }
    std::string operator/(const std::string& name) const { return (path / name).string(); }
};

// The angle in degrees between two directions.
float angle_deg(const Vec3& a, const Vec3& b) {
    return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.f, 1.f)) * 180.f / kPi;
}

}  // namespace

TEST_CASE("scene file: a missing file names the path", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "does-not-exist.json"); });
    CHECK_THAT(msg, Contains("does-not-exist.json") && Contains("not found"));
    CHECK_THROWS_AS(load_scene_file(kBad + "does-not-exist.json"), InputError);
}

TEST_CASE("scene file: malformed JSON names the file and the position", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "malformed.json"); });
    CHECK_THAT(msg, Contains("malformed.json") && Contains("malformed JSON") && Contains("line"));
}

TEST_CASE("scene file: an unknown key is an error naming it and listing the valid ones", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "unknown-key.json"); });
    CHECK_THAT(msg, Contains("unknown-key.json") && Contains("'colour'") && Contains("camera"));
}

TEST_CASE("scene file: an ill-typed value names the key", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "bad-type.json"); });
    CHECK_THAT(msg, Contains("bad-type.json") && Contains("render.spp"));
}

TEST_CASE("scene file: a missing mesh names the OBJ path", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "missing-mesh.json"); });
    CHECK_THAT(msg, Contains("no-such-mesh.obj") && Contains("not found"));
}

TEST_CASE("OBJ: a malformed face line is an error naming the file, the line and the vertex", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "malformed-obj.json"); });
    CHECK_THAT(msg, Contains("malformed.obj") && Contains("line 5") && Contains("'x'"));
}

TEST_CASE("OBJ: a missing MTL library is an error, not grey surfaces", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "missing-mtl-obj.json"); });
    CHECK_THAT(msg, Contains("missing-mtl.obj") && Contains("no-such-file.mtl"));
}

TEST_CASE("scene file: a missing library in meshes[].mtl names the key and the file", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "missing-mtl-override.json"); });
    CHECK_THAT(msg, Contains("missing-mtl-override.json") && Contains("meshes[].mtl") &&
                        Contains("no-such-library.mtl") && Contains("not found"));
}

TEST_CASE("scene file: a directory given as a mesh or a library is an error, not an empty scene", "[scene][errors]") {
    const std::string mesh = error_of([] { load_scene_file(kBad + "directory-mesh.json"); });
    CHECK_THAT(mesh, Contains("directory.obj") && Contains("not a file"));
    const std::string mtl = error_of([] { load_scene_file(kBad + "directory-mtl.json"); });
    CHECK_THAT(mtl, Contains("directory-mtl.json") && Contains("meshes[].mtl") && Contains("not a file"));
}

TEST_CASE("OBJ: a NaN vertex is an error naming file and line, not a vertex at 0", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "nan-vertex-obj.json"); });
    CHECK_THAT(msg, Contains("nan-vertex.obj") && Contains("line 2") && Contains("'nan'"));
    // load_obj directly too.
    TriangleMesh mesh;
    std::vector<Material> mats;
    CHECK_THROWS_AS(load_obj(kBad + "nan-vertex.obj", Mat4(1.f), mesh, mats), InputError);
}

TEST_CASE("scene: an OBJ without faces is an 'empty scene' error naming the scene file", "[scene][errors]") {
    const std::string msg = error_of([] { load_scene_file(kBad + "empty-obj.json"); });
    CHECK_THAT(msg, Contains("empty-obj.json") && Contains("no (non-degenerate) triangles"));
}

TEST_CASE("scene: zero-area triangles are skipped and counted, and the scene renders", "[scene][errors]") {
    const SceneFile sf = load_scene_file(kBad + "degenerate-obj.json");
    CHECK(sf.scene->stats().triangles == 1);
    CHECK(sf.scene->stats().degenerate_skipped == 2);
    auto pt = integrator_registry().create("pt", Params());
    RenderSettings st;
    st.spp = 2;
    FrameBuffer fb;
    const RenderStats rs = pt->render(*sf.scene, st, fb, {});
    CHECK(rs.nonfinite == 0);
    CHECK(fb.get("color").width() == 4);
    // The remaining triangle is hit (it covers the image centre) with its material.
    CHECK(fb.get("albedo").rgb(2, 2).g == Approx(0.5f));
}

TEST_CASE("scene: non-finite vertices and dangling material ids are errors naming the origin", "[scene][errors]") {
    const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    CHECK_THAT(error_of([&] { Scene(soup({a, b, Vec3(0, nan, 0)}), one_material(), Camera(), "mem"); }),
               Contains("mem") && Contains("non-finite"));
    CHECK_THAT(error_of([&] { Scene(soup({a, b, Vec3(kInf, 0, 0)}), one_material(), Camera(), "mem"); }),
               Contains("non-finite"));
    TriangleMesh m = soup({a, b, c});
    m.material_ids[0] = 7;
    CHECK_THAT(error_of([&] { Scene(m, one_material(), Camera(), "mem"); }), Contains("mem") && Contains("material"));
    CHECK_THAT(error_of([&] { Scene(TriangleMesh{}, one_material(), Camera(), "mem"); }), Contains("no (non-degenerate)"));
    CHECK_THAT(error_of([&] { Scene(soup({a, b, b}), one_material(), Camera(), "mem"); }), Contains("no (non-degenerate)"));
    // Arrays that disagree in length would be read out of bounds.
    TriangleMesh extra = soup({a, b, c});
    extra.material_ids.push_back(0);
    CHECK_THAT(error_of([&] { Scene(extra, one_material(), Camera(), "mem"); }), Contains("mem") && Contains("positions"));
    TriangleMesh few_normals = soup({a, b, c});
    few_normals.normals = {Vec3(0, 0, 1)};
    CHECK_THAT(error_of([&] { Scene(few_normals, one_material(), Camera(), "mem"); }), Contains("normals"));
    TriangleMesh few_uvs = soup({a, b, c});
    few_uvs.uvs = {Vec2(0.f), Vec2(1.f)};
    CHECK_THAT(error_of([&] { Scene(few_uvs, one_material(), Camera(), "mem"); }), Contains("uvs"));
}

TEST_CASE("scene: hits report position, winding normal, material and one-sided emission", "[scene]") {
    // One emitting triangle in the plane z = -2, counter-clockwise seen from +z.
    const Scene scene(soup({Vec3(-1, -1, -2), Vec3(1, -1, -2), Vec3(0, 1, -2)}), one_material(Color(4.f)), Camera(), "mem");
    SurfaceInteraction si;
    REQUIRE(scene.intersect(Ray{Vec3(0.1f, 0.f, 0.f), Vec3(0, 0, -1)}, si));
    CHECK(si.t == Approx(2.f));
    CHECK(si.p.x == Approx(0.1f));
    CHECK(si.p.z == Approx(-2.f));
    CHECK(si.ng.z == Approx(1.f));
    CHECK(si.frame.n.z == Approx(1.f));
    CHECK(si.material == &scene.materials()[0]);
    CHECK(si.is_emitter());
    CHECK(si.emitted(Vec3(0, 0, 1)).r == 4.f);   // towards the front
    CHECK(si.emitted(Vec3(0, 0, -1)).r == 0.f);  // towards the back
    // Misses, tmax and occlusion.
    CHECK_FALSE(scene.intersect(Ray{Vec3(5.f, 0.f, 0.f), Vec3(0, 0, -1)}, si));
    CHECK_FALSE(scene.intersect(Ray{Vec3(0.f, 0.f, 0.f), Vec3(0, 0, -1), 0.f, 1.9f}, si));
    CHECK(scene.occluded(Ray{Vec3(0.f, 0.f, 0.f), Vec3(0, 0, -1)}));
    CHECK_FALSE(scene.occluded(Ray{Vec3(0.f, 0.f, 0.f), Vec3(0, 0, 1)}));
    CHECK_FALSE(scene.visible(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 0, -4), Vec3(0, 0, 1)));
    CHECK(scene.visible(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 0, -1), Vec3(0, 0, 1)));
    CHECK(scene.stats().emitters == 1);
    CHECK(scene.bounding_radius() > 1.f);
}

TEST_CASE("scene: flat hits get the face's unit normal and frame, from the table or computed", "[scene]") {
    // Small scenes read flat triangles' frames from a table built at load;
    // big ones (over 1 MiB of frames) compute them per hit from Embree's
    // normal. Both must give the unit winding normal and an orthonormal
    // frame around it, for the single-ray and the packet query alike.
    const Vec3 a(-1, -1, -2), b(1, -1, -2), c(0.2f, 1, -2.5f);  // tilted, so no axis-aligned shortcut
    const Vec3 n = glm::normalize(glm::cross(b - a, c - a));
    for (const size_t fillers : {size_t(0), size_t(40000)}) {
        std::vector<Vec3> corners = {a, b, c};
        for (size_t i = 0; i < fillers; ++i) {  // tiny triangles far behind the camera
            const Vec3 o(float(i % 200), float(i / 200), 50.f);
            corners.insert(corners.end(), {o, o + Vec3(0.1f, 0, 0), o + Vec3(0, 0.1f, 0)});
        }
        const Scene scene(soup(corners), one_material(), Camera(), "mem");
        const Ray rays[8] = {{Vec3(0.1f, 0.f, 0.f), Vec3(0, 0, -1)}, {Vec3(-0.2f, -0.3f, 0.f), Vec3(0, 0, -1)},
                             {Vec3(0.f), Vec3(0, 0, -1)}, {Vec3(0.f), Vec3(0, 0, -1)},
                             {Vec3(0.f), Vec3(0, 0, -1)}, {Vec3(0.f), Vec3(0, 0, -1)},
                             {Vec3(0.f), Vec3(0, 0, -1)}, {Vec3(0.f), Vec3(0, 0, -1)}};
        SurfaceInteraction single, packet[8];
        SurfaceInteraction* const sp[8] = {packet, packet + 1, packet + 2, packet + 3,
                                           packet + 4, packet + 5, packet + 6, packet + 7};
        const bool active[8] = {true, true, false, false, false, false, false, false};
        bool hit[8];
        scene.intersect8(rays, active, sp, hit);
        for (int i = 0; i < 2; ++i) {
            INFO("fillers " << fillers << ", ray " << i);
            REQUIRE(scene.intersect(rays[i], single));
            REQUIRE(hit[i]);
            for (const SurfaceInteraction* si : {&single, &packet[i]}) {
                CHECK(glm::length(si->ng - n) < 1e-6f);
                CHECK(glm::length(si->frame.n - n) < 1e-6f);
                CHECK(std::abs(glm::dot(si->frame.s, si->frame.t)) < 1e-6f);
                CHECK(std::abs(glm::dot(si->frame.s, si->frame.n)) < 1e-6f);
                CHECK(std::abs(glm::length(si->frame.s) - 1.f) < 1e-6f);
                CHECK(std::abs(glm::length(si->frame.t) - 1.f) < 1e-6f);
                // Right-handed, as Frame builds it: s x t = n.
                CHECK(glm::length(glm::cross(si->frame.s, si->frame.t) - si->frame.n) < 1e-5f);
            }
        }
    }
}

TEST_CASE("scene: a mirroring transform keeps emitters facing the same way", "[scene]") {
    // Scaling x by -1 reverses the winding; the loader must swap corners so the
    // emitting side (the +z side of the wall) stays the emitting side.
    TriangleMesh mesh;
    std::vector<Material> mats;
    load_obj(GDR_SOURCE_DIR "/tests/scenes/emitter-wall/wall.obj", glm::scale(Mat4(1.f), Vec3(-1, 1, 1)), mesh, mats);
    const Scene scene(std::move(mesh), std::move(mats), Camera(), "mirrored");
    SurfaceInteraction si;
    REQUIRE(scene.intersect(Ray{Vec3(0.f), Vec3(0, 0, -1)}, si));
    CHECK(si.ng.z == Approx(1.f));
    CHECK(si.emitted(Vec3(0, 0, 1)).r == 3.f);
}

TEST_CASE("scene file: the Cornell box loads with its light and camera", "[scene]") {
    const SceneFile sf = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/scene.json");
    CHECK(sf.scene->stats().triangles == 36);
    CHECK(sf.scene->stats().emitters == 2);
    CHECK(sf.scene->camera().width() == 512);
    CHECK(sf.defaults.integrator == "pt");
    CHECK(sf.defaults.spp == 64);
    // The camera looks into the box [-1, 1] x [0, 2] x [-1, 1]: central rays hit inside it.
    for (float x : {100.f, 256.f, 412.f})
        for (float y : {100.f, 256.f, 412.f}) {
            SurfaceInteraction si;
            REQUIRE(sf.scene->intersect(sf.scene->camera().generate_ray(Vec2(x, y)), si));
            CHECK(std::abs(si.p.x) < 1.1f);
            CHECK(si.p.y > -0.1f);
            CHECK(si.p.y < 2.1f);
            CHECK(si.p.z > -1.1f);
        }
}

TEST_CASE("scene file: meshes[].mtl replaces the OBJ's own material library", "[scene]") {
    // The archive's Glossy-Floor OBJ names the Glossy library; glossy-floor.json
    // gives it its own, with a glossy floor (Ks 0.3, Ns 32) and a light of Ke 1.
    const auto material = [](const SceneFile& sf, const std::string& name) -> const Material& {
        for (const Material& m : sf.scene->materials())
            if (m.name == name) return m;
        FAIL("no material " << name);
        return sf.scene->materials().front();
    };
    const SceneFile own = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/glossy.json");
    const SceneFile given = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/glossy-floor.json");
    CHECK(material(own, "floor").min_roughness == 1.f);
    CHECK(material(given, "floor").min_roughness == Approx(std::sqrt(2.f / 34.f)).epsilon(1e-4));
    CHECK(material(own, "light").emission == Color(10.f));
    CHECK(material(given, "light").emission == Color(1.f));
    CHECK(given.scene->stats().triangles == own.scene->stats().triangles);
    // An OBJ that names no library gets the given one too.
    const SceneFile plain = load_scene_file(GDR_SOURCE_DIR "/tests/scenes/mtl-given/scene.json");
    CHECK(material(plain, "glow").emission == Color(2.f, 3.f, 4.f));
    CHECK(plain.scene->stats().emitters == 1);
}

TEST_CASE("scene: visible8 agrees with visible on batches of 0 to 8 segments", "[scene]") {
    // Segments between random surface points of the Cornell box (its two
    // boxes block many) and its light, plus degenerate ones (an end on
    // itself), in batches of every size. Embree's packet kernel may round a
    // grazing segment differently from the single-ray one; none do here, but
    // 1 in 1000 is allowed so that the test does not hinge on that.
    SceneFile sf = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/scene.json");
    Scene& scene = *sf.scene;
    struct Counter final : RayObserver {
        void on_intersect(const Ray&) override {}
        void on_occluded(const Ray&) override { ++n; }
        long n = 0;
    } counter;
    Sampler rng(SampleKey{7, 0, 0, 0});
    struct Segment {
        Vec3 p0, n0, p1, n1;
    };
    const auto surface_point = [&](Vec3& p, Vec3& n) {
        SurfaceInteraction si;
        while (!scene.intersect(scene.camera().generate_ray(Vec2(rng.next1d() * 512.f, rng.next1d() * 512.f)), si)) {
        }
        p = si.p, n = si.ng;
    };
    long total = 0, disagree = 0, blocked = 0, expected_rays = 0;
    for (int round = 0; round < 400; ++round) {
        for (int n = 0; n <= 8; ++n) {
            Segment q[8];
            VisibilityBatch batch;
            for (int i = 0; i < n; ++i) {
                surface_point(q[i].p0, q[i].n0);
                const float kind = rng.next1d();
                if (kind < 0.1f) {
                    q[i].p1 = q[i].p0, q[i].n1 = q[i].n0;  // degenerate: visible, no ray
                } else if (kind < 0.4f) {
                    const LightSample ls = scene.sample_light(q[i].p0, rng.next1d(), rng.next2d());
                    q[i].p1 = ls.p, q[i].n1 = ls.n;
                } else {
                    surface_point(q[i].p1, q[i].n1);
                }
                batch.add(q[i].p0, q[i].n0, q[i].p1, q[i].n1);
            }
            bool got[8];
            scene.set_ray_observer(&counter);
            scene.visible8(batch, got);
            scene.set_ray_observer(nullptr);
            for (int i = 0; i < n; ++i) {
                const bool want = scene.visible(q[i].p0, q[i].n0, q[i].p1, q[i].n1);
                ++total;
                disagree += got[i] != want;
                blocked += !want;
                expected_rays += q[i].p1 != q[i].p0;
            }
        }
    }
    INFO(disagree << " of " << total << " disagree");
    CHECK(total == 400 * 36);
    CHECK(blocked > total / 10);  // the test sees both outcomes
    CHECK(blocked < total * 9 / 10);
    CHECK(disagree * 1000 <= total);
    CHECK(counter.n == expected_rays);  // the observer sees each traced segment once
}

TEST_CASE("scene file: unphysical material values are errors naming where they came from", "[scene][errors]") {
    namespace fs = std::filesystem;
    const fs::path dir = fs::temp_directory_path() / ("gdr-test-materials-" + std::to_string(getpid()));
    fs::create_directories(dir);
    const auto write = [&](const std::string& name, const std::string& text) { std::ofstream(dir / name) << text; };
    write("quad.obj", "mtllib quad.mtl\nv -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nusemtl wall\nf 1 2 3\n");
    write("quad.mtl", "newmtl wall\nKd 0.5 0.5 0.5\n");
    write("bright.obj", "mtllib bright.mtl\nv -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nusemtl wall\nf 1 2 3\n");
    write("bright.mtl", "newmtl wall\nKd 1.5 0.5 0.5\n");
    const auto scene_with = [&](const std::string& name, const std::string& materials, const std::string& obj = "quad.obj") {
        write(name, R"({"camera": {"width": 4, "height": 4}, "meshes": [")" + obj + R"("], "materials": )" + materials + "}");
        return error_of([&] { load_scene_file((dir / name).string()); });
    };
    // The override's own keys, named in full.
    CHECK_THAT(scene_with("alpha.json", R"({"wall": {"type": "roughconductor", "alpha": -1}})"),
               Contains("alpha.json") && Contains("materials.wall.alpha"));
    CHECK_THAT(scene_with("eta.json", R"({"wall": {"type": "dielectric", "eta": 0}})"),
               Contains("eta.json") && Contains("materials.wall.eta"));
    CHECK_THAT(scene_with("ns.json", R"({"wall": {"ns": -3}})"), Contains("materials.wall.ns"));
    // Colours: above 1 a reflectance creates energy; negative emission is no light.
    CHECK_THAT(scene_with("kd.json", R"({"wall": {"type": "diffuse", "kd": [2, 2, 2]}})"),
               Contains("kd.json") && Contains("materials.wall") && Contains("Kd"));
    CHECK_THAT(scene_with("ks.json", R"({"wall": {"type": "mirror", "ks": [1, -0.5, 1]}})"), Contains("Ks"));
    CHECK_THAT(scene_with("metal.json", R"({"wall": {"metal": 1}})"), Contains("materials.wall.metal"));
    CHECK_THAT(scene_with("map.json", R"({"wall": {"map_kd": 3}})"), Contains("materials.wall.map_kd"));
    // A conductor's complex index: both parts, finite and >= 0.
    CHECK_THAT(scene_with("eta-only.json", R"({"wall": {"conductor_eta": [0.2, 0.9, 1.1]}})"),
               Contains("materials.wall") && Contains("conductor_k"));
    CHECK_THAT(scene_with("k-neg.json", R"({"wall": {"conductor_eta": [0.2, 0.9, 1.1], "conductor_k": [3, -2, 2]}})"),
               Contains("k-neg.json") && Contains("materials.wall"));
    CHECK(scene_with("copper.json", R"({"wall": {"conductor_eta": [0.2, 0.9, 1.1], "conductor_k": [3.9, 2.5, 2.1], "alpha": 0.2}})")
              .empty());
    CHECK_THAT(scene_with("ke.json", R"({"wall": {"ke": [-1, 0, 0]}})"), Contains("ke.json") && Contains("Ke"));
    // The same rule for an MTL file's own values, named by the OBJ and the material.
    CHECK_THAT(scene_with("mtl.json", "{}", "bright.obj"), Contains("bright.obj") && Contains("'wall'") && Contains("Kd"));
    // tinyobjloader would read an unparsable MTL number as 0 (a black colour, a sharp lobe).
    write("nan.obj", "mtllib nan.mtl\nv -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nusemtl wall\nf 1 2 3\n");
    write("nan.mtl", "newmtl wall\n# a comment\nKd nan 0.5 0.5\n");
    CHECK_THAT(scene_with("nan-mtl.json", "{}", "nan.obj"), Contains("nan.mtl") && Contains("line 3") && Contains("Kd"));
    write("x.mtl", "newmtl wall\nNs x\n");
    write("given.json", R"({"camera": {"width": 4, "height": 4}, "meshes": [{"file": "quad.obj", "mtl": "x.mtl"}]})");
    CHECK_THAT(error_of([&] { load_scene_file((dir / "given.json").string()); }), Contains("x.mtl") && Contains("Ns"));
    // Values at the limits load.
    CHECK(scene_with("fine.json", R"({"wall": {"type": "roughconductor", "ks": [1, 1, 1], "alpha": 0}})").empty());
    fs::remove_all(dir);
}

TEST_CASE("OBJ: bad normals and texture coordinates are errors naming the file, not silent zeros", "[scene][errors]") {
    namespace fs = std::filesystem;
    const fs::path dir = fs::temp_directory_path() / ("gdr-test-attributes-" + std::to_string(getpid()));
    fs::create_directories(dir);
    const auto load_obj_text = [&](const std::string& name, const std::string& body) {
        std::ofstream(dir / (name + ".obj")) << "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\n" << body;
        std::ofstream(dir / (name + ".json")) << R"({"camera": {"width": 4, "height": 4}, "meshes": [")" << name << R"(.obj"]})";
        return error_of([&] { load_scene_file((dir / (name + ".json")).string()); });
    };
    // tinyobjloader would read these as 0: a tilted normal, a wrong texel.
    CHECK_THAT(load_obj_text("nan-normal", "vn nan 0 1\nf 1//1 2//1 3//1\n"),
               Contains("nan-normal.obj") && Contains("line 4") && Contains("normal"));
    CHECK_THAT(load_obj_text("bad-uv", "vt 0.5 x\nf 1/1 2/1 3/1\n"),
               Contains("bad-uv.obj") && Contains("line 4") && Contains("texture coordinate"));
    CHECK_THAT(load_obj_text("short-normal", "vn 0 1\nf 1//1 2//1 3//1\n"), Contains("short-normal.obj") && Contains("line 4"));
    // Indices past the end are malformed faces, not absent attributes.
    CHECK_THAT(load_obj_text("missing-normal", "vn 0 0 1\nf 1//1 2//2 3//1\n"),
               Contains("missing-normal.obj") && Contains("missing normal"));
    CHECK_THAT(load_obj_text("missing-uv", "vt 0 0\nf 1/1 2/3 3/1\n"),
               Contains("missing-uv.obj") && Contains("missing texture coordinate"));
    // Well-formed attributes, including a one-number vt, load.
    CHECK(load_obj_text("fine", "vt 0.25\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\n").empty());
    fs::remove_all(dir);
}

TEST_CASE("OBJ: a face index out of range is an error naming file, line and vertex, not a dropped face", "[scene][errors]") {
    // The reader would drop the quad and load the other 10 triangles of the box.
    const std::string msg = error_of([] { load_scene_file(kBad + "face-index-obj.json"); });
    CHECK_THAT(msg, Contains("face-index.obj") && Contains("line 15") && Contains("'999'") && Contains("missing vertex"));
    TriangleMesh mesh;
    std::vector<Material> mats;
    CHECK_THROWS_AS(load_obj(kBad + "face-index.obj", Mat4(1.f), mesh, mats), InputError);

    TempDir dir("face-index");
    const auto load = [&](const std::string& name, const std::string& faces) {
        dir.write(name + ".obj", "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nvt 0 0\nvn 0 0 1\n" + faces);
        dir.write(name + ".json", R"({"camera": {"width": 4, "height": 4}, "meshes": [")" + name + R"(.obj"]})");
        return error_of([&] { load_scene_file(dir / (name + ".json")); });
    };
    CHECK_THAT(load("high", "f 1 2 3\nf 1 2 999\n"),
               Contains("high.obj") && Contains("line 7") && Contains("'999'") && Contains("3 vertices"));
    CHECK_THAT(load("low", "f -999 2 3\n"),
               Contains("low.obj") && Contains("line 6") && Contains("'-999'") && Contains("missing vertex"));
    CHECK_THAT(load("zero", "f 0 1 2\n"), Contains("zero.obj") && Contains("line 6") && Contains("index 0"));
    CHECK_THAT(load("two", "f 1 2 3\nf 1 2\n"), Contains("two.obj") && Contains("line 7") && Contains("at least 3"));
    CHECK_THAT(load("none", "f \n"), Contains("none.obj") && Contains("line 6") && Contains("got 0"));
    CHECK_THAT(load("uv", "f 1/999/1 2/1/1 3/1/1\n"),
               Contains("uv.obj") && Contains("line 6") && Contains("'1/999/1'") && Contains("missing texture coordinate"));
    CHECK_THAT(load("normal", "f 1//1 2//-2 3//1\n"),
               Contains("normal.obj") && Contains("line 6") && Contains("'2//-2'") && Contains("missing normal"));
    // atoi would read these as 3 and 1 and carry on.
    CHECK_THAT(load("suffix", "f 1 2 3x\n"), Contains("suffix.obj") && Contains("line 6") && Contains("'3x'"));
    CHECK_THAT(load("fraction", "f 1.5 2 3\n"), Contains("fraction.obj") && Contains("'1.5'"));
    CHECK_THAT(load("slashes", "f 1/1/1/1 2 3\n"), Contains("slashes.obj") && Contains("'1/1/1/1'"));
    CHECK_THAT(load("huge", "f 1 2 99999999999999999999\n"), Contains("huge.obj") && Contains("missing vertex"));
    // A negative index counts back from the latest vertex *so far*: -3 on
    // line 6 is vertex 1, but before the third vertex it is out of range.
    CHECK(load("back", "f -3 -2 -1\n").empty());
    // A positive index may name a later vertex, but the reader triangulates
    // a quad at the next group, before vertex 4 exists, and drops it.
    CHECK_THAT(load("group", "f 1 2 3\nf 1 2 3 4\ng other\nv 0 1 -2\n"),
               Contains("group.obj") && Contains("make 3 triangles") && Contains("kept 1"));
    CHECK_THAT(load("early", "f 1 2 3\nv 0 0 -3\nf -5 -4 -3\n"), Contains("early.obj") && Contains("line 8") &&
                                                                     Contains("'-5'") && Contains("4 vertices"));
}

TEST_CASE("OBJ: relative indices and faces before their vertices load as the reader resolves them", "[scene]") {
    TriangleMesh mesh;
    std::vector<Material> mats;
    load_obj(kBad + "relative-faces.obj", Mat4(1.f), mesh, mats);
    REQUIRE(mesh.size() == 3);
    // Face 1 (4 5 6, before any vertex) and face 3 (-3 -2 -1 after six) are
    // the z = -3 triangle; face 2 (-3 -2 -1 after three) the z = -2 one.
    CHECK(mesh.positions[0] == Vec3(-1, -1, -3));
    CHECK(mesh.positions[3] == Vec3(-1, -1, -2));
    CHECK(mesh.positions[5] == Vec3(0, 1, -2));
    CHECK(mesh.positions[6] == Vec3(-1, -1, -3));
    CHECK(mesh.positions[8] == Vec3(0, 1, -3));
    CHECK(mesh.normals[3] == Vec3(0, 0, 1));  // vn -1 of the second face
}

TEST_CASE("scene file: per-mesh triangle counts show how much of each OBJ was read", "[scene]") {
    const SceneFile sf = load_scene_file(kBad + "mesh-counts.json");
    REQUIRE(sf.meshes.size() == 3);
    CHECK(sf.meshes[0].file == kBad + "triangle.obj");
    CHECK(sf.meshes[1].file == kBad + "degenerate.obj");
    CHECK(sf.meshes[2].file == kBad + "relative-faces.obj");
    CHECK(sf.meshes[0].triangles == 1);
    CHECK(sf.meshes[0].degenerate_skipped == 0);
    CHECK(sf.meshes[1].triangles == 3);
    CHECK(sf.meshes[1].degenerate_skipped == 2);
    CHECK(sf.meshes[2].triangles == 3);
    CHECK(sf.meshes[2].degenerate_skipped == 0);
    CHECK(sf.scene->stats().triangles == 5);
    CHECK(sf.scene->stats().degenerate_skipped == 2);
    // The Cornell box's one OBJ holds 36 triangles, all kept.
    const SceneFile box = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/scene.json");
    REQUIRE(box.meshes.size() == 1);
    CHECK(box.meshes[0].file == GDR_SOURCE_DIR "/scenes/cornell-box/CornellBox-Original.obj");
    CHECK(box.meshes[0].triangles == 36);
    CHECK(box.meshes[0].degenerate_skipped == 0);
}

TEST_CASE("scene file: a key given twice is an error naming the file and the key", "[scene][errors]") {
    CHECK_THAT(error_of([] { load_scene_file(kBad + "duplicate-key.json"); }),
               Contains("duplicate-key.json") && Contains("'render.spp'") && Contains("duplicate key"));
    TempDir dir("duplicate-key");
    dir.write("tri.obj", "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1 2 3\n");
    const auto load = [&](const std::string& name, const std::string& text) {
        dir.write(name, text);
        return error_of([&] { load_scene_file(dir / name); });
    };
    CHECK_THAT(load("camera.json", R"({"camera": {"width": 4}, "camera": {"width": 8}, "meshes": ["tri.obj"]})"),
               Contains("camera.json") && Contains("'camera'"));
    CHECK_THAT(load("nested.json", R"({"camera": {"width": 4, "height": 4},
                 "meshes": [{"file": "tri.obj"}, {"file": "tri.obj", "transform": {"scale": 2, "scale": 3}}]})"),
               Contains("nested.json") && Contains("'meshes[].transform.scale'"));
    CHECK_THAT(load("params.json", R"({"camera": {"width": 4, "height": 4}, "meshes": ["tri.obj"],
                 "render": {"params": {"max_depth": 3, "max_depth": 5}}})"),
               Contains("'render.params.max_depth'"));
    // In a camera file, named with the scene file that reads it.
    dir.write("cam.json", R"({"position": [0, 0, 0], "target": [0, 0, -1], "width": 8, "height": 8, "width": 4})");
    CHECK_THAT(load("camfile.json", R"({"camera": {"file": "cam.json"}, "meshes": ["tri.obj"]})"),
               Contains("camfile.json") && Contains("cam.json") && Contains("'width'") && Contains("duplicate key"));
    // The same key in different objects is no duplicate.
    CHECK(load("fine.json", R"({"camera": {"width": 4, "height": 4}, "meshes": [{"file": "tri.obj"}, {"file": "tri.obj"}],
                 "render": {"seed": 1, "params": {"seed": 2}}})").empty());
}

TEST_CASE("scene file: an oversized or invalid resolution names the key and the value as given", "[scene][errors]") {
    TempDir dir("resolution");
    dir.write("tri.obj", "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1 2 3\n");
    const auto load = [&](const std::string& camera) {
        dir.write("s.json", R"({"camera": )" + camera + R"(, "meshes": ["tri.obj"]})");
        return error_of([&] { load_scene_file(dir / "s.json"); });
    };
    // Once clamped silently, and then reported as "1048576".
    CHECK_THAT(load(R"({"width": 1e9, "height": 4})"), Contains("'camera.width'") && Contains("1000000000"));
    CHECK_THAT(load(R"({"width": 4, "height": 0})"), Contains("'camera.height'") && Contains("got 0"));
    CHECK_THAT(load(R"({"width": 4.5, "height": 4})"), Contains("'camera.width'") && Contains("4.5"));
    CHECK(load(R"({"width": 1048576, "height": 1})").find("camera.width") == std::string::npos);
}

TEST_CASE("scene file: a directory given as the scene is an error saying so", "[scene][errors]") {
    CHECK_THAT(error_of([] { load_scene_file(kBad); }), Contains(kBad) && Contains("is a directory"));
    CHECK_THAT(error_of([] { load_scene_file(kBad + "directory.obj"); }),
               Contains("directory.obj") && Contains("is a directory"));
    // One holding a scene.json points to it.
    const std::string box = GDR_SOURCE_DIR "/scenes/cornell-box/";
    CHECK_THAT(error_of([&] { load_scene_file(box); }), Contains("is a directory") && Contains(box + "scene.json"));
    // A camera file that is a directory, too.
    TempDir dir("directory-camera");
    dir.write("tri.obj", "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1 2 3\n");
    std::filesystem::create_directories(dir.path / "cam.json");
    dir.write("scene.json", R"({"camera": {"file": "cam.json"}, "meshes": ["tri.obj"]})");
    CHECK_THAT(error_of([&] { load_scene_file(dir / "scene.json"); }),
               Contains("scene.json") && Contains("cam.json") && Contains("directory"));
}

TEST_CASE("scene file: overriding one side of a camera file keeps the file's aspect ratio", "[scene]") {
    TempDir dir("camera-aspect");
    dir.write("tri.obj", "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1 2 3\n");
    // As the shared scenes write them: fov_deg, a forward direction and a note.
    dir.write("cam.json", R"({"position": [0, 0, 0], "forward": [0, 0, -1], "target": [0, 0, -1], "up": [0, 1, 0],
                             "fov_deg": 40, "fov_axis": "x", "width": 400, "height": 300, "note": "text"})");
    const auto camera = [&](const std::string& overrides) {
        dir.write("scene.json", R"({"camera": {"file": "cam.json")" + overrides + R"(}, "meshes": ["tri.obj"]})");
        return load_scene_file(dir / "scene.json").scene->camera().desc();
    };
    const auto size = [](const CameraDesc& d) { return std::to_string(d.width) + "x" + std::to_string(d.height); };
    CHECK(size(camera("")) == "400x300");
    CHECK(size(camera(R"(, "width": 200)")) == "200x150");
    CHECK(size(camera(R"(, "height": 30)")) == "40x30");
    CHECK(size(camera(R"(, "width": 100, "height": 100)")) == "100x100");  // both: as given
    CHECK(size(camera(R"(, "width": 201)")) == "201x151");                 // 150.75 rounds up
    CHECK(size(camera(R"(, "width": 1)")) == "1x1");                       // 0.75: at least 1
    CHECK(camera(R"(, "width": 200)").fov_deg == 40.f);
    // An override's fov replaces the file's fov_deg.
    CHECK(camera(R"(, "fov": 25)").fov_deg == 25.f);
    CHECK(camera(R"(, "fov": 25)").fov_axis == 'x');
    // A camera without a file has no aspect ratio to keep: the other side is the default.
    dir.write("plain.json", R"({"camera": {"width": 200}, "meshes": ["tri.obj"]})");
    CHECK(load_scene_file(dir / "plain.json").scene->camera().height() == 512);
    // Bad values are still named.
    dir.write("scene.json", R"({"camera": {"file": "cam.json", "width": 0}, "meshes": ["tri.obj"]})");
    CHECK_THAT(error_of([&] { load_scene_file(dir / "scene.json"); }), Contains("camera.width"));
    dir.write("cam.json", R"({"fov": 30, "fov_deg": 40})");
    dir.write("scene.json", R"({"camera": {"file": "cam.json"}, "meshes": ["tri.obj"]})");
    CHECK_THAT(error_of([&] { load_scene_file(dir / "scene.json"); }),
               Contains("cam.json") && Contains("'fov'") && Contains("'fov_deg'"));
}

TEST_CASE("scene file: set_resolution and set_fov rebuild the camera around the same view", "[scene]") {
    SceneFile sf = load_scene_file(GDR_SOURCE_DIR "/tests/scenes/emitter-wall/scene.json");  // 10x8, 60 degrees in y
    const Camera& cam = sf.scene->camera();
    const Vec3 forward = cam.forward();
    const auto top = [&] { return cam.generate_ray(Vec2(0.5f * float(cam.width()), 0.f)).d; };
    const auto left = [&] { return cam.generate_ray(Vec2(0.f, 0.5f * float(cam.height()))).d; };
    REQUIRE(angle_deg(top(), forward) == Approx(30.f));
    set_resolution(sf, 20, 0);  // a height of 0 keeps the aspect ratio
    CHECK(cam.width() == 20);
    CHECK(cam.height() == 16);
    CHECK(angle_deg(top(), forward) == Approx(30.f));  // the vertical field of view is kept
    CHECK(glm::length(cam.forward() - forward) < 1e-6f);
    set_resolution(sf, 0, 4);
    CHECK(cam.width() == 5);
    CHECK(cam.height() == 4);
    set_resolution(sf, 30, 10);  // both: as given, wider at the same vertical angle
    CHECK(cam.width() == 30);
    CHECK(cam.height() == 10);
    CHECK(angle_deg(top(), forward) == Approx(30.f));
    CHECK(angle_deg(left(), forward) > 30.f);
    CHECK_THROWS_AS(set_resolution(sf, -1, 10), ParameterError);
    CHECK_THROWS_AS(set_resolution(sf, 0, 0), ParameterError);
    CHECK_THROWS_AS(set_resolution(sf, 70000, 10), ParameterError);
    CHECK(cam.width() == 30);  // a rejected resolution changes nothing
    // Field of view, along the camera's own axis or the one given.
    set_fov(sf, 40.f);
    CHECK(cam.desc().fov_axis == 'y');
    CHECK(angle_deg(top(), forward) == Approx(20.f));
    set_fov(sf, 50.f, 'x');
    CHECK(angle_deg(left(), forward) == Approx(25.f));
    CHECK(cam.width() == 30);
    CHECK(cam.height() == 10);
    CHECK_THROWS_AS(set_fov(sf, 180.f), ParameterError);
    CHECK_THROWS_AS(set_fov(sf, 0.f), ParameterError);
    CHECK_THROWS_AS(set_fov(sf, 30.f, 'z'), ParameterError);
    CHECK(angle_deg(left(), forward) == Approx(25.f));
}

TEST_CASE("scene file: the content hash covers every file read, wherever the scene lies", "[scene]") {
    // A scene reading a camera file, an OBJ, its MTL and a texture, in two places.
    const auto make = [](const TempDir& dir) {
        dir.write("scene.json", R"({"camera": {"file": "cam.json"}, "meshes": ["quad.obj", "quad.obj"]})");
        dir.write("cam.json", R"({"position": [0, 0, 0], "target": [0, 0, -1], "width": 4, "height": 4})");
        dir.write("quad.obj", "mtllib quad.mtl\nv -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nvt 0 0\nusemtl wall\nf 1/1 2/1 3/1\n");
        dir.write("quad.mtl", "newmtl wall\nKd 0.5 0.5 0.5\nmap_Kd tex.ppm\n");
        dir.write("tex.ppm", std::string("P6\n2 2\n255\n") + std::string(12, char(200)));
    };
    TempDir a("hash-a"), b("hash-b");
    make(a), make(b);
    const SceneFile sa = load_scene_file(a / "scene.json");
    // Each file once, in the order read.
    CHECK(sa.inputs ==
          std::vector<std::string>{a / "scene.json", a / "cam.json", a / "quad.obj", a / "quad.mtl", a / "tex.ppm"});
    REQUIRE(sa.content_hash.size() == 16);
    CHECK(sa.content_hash.find_first_not_of("0123456789abcdef") == std::string::npos);
    CHECK(load_scene_file(a / "scene.json").content_hash == sa.content_hash);
    CHECK(load_scene_file(b / "scene.json").content_hash == sa.content_hash);
    // One byte of any input changes it.
    const auto changed = [&](const std::string& file, const std::string& from, const std::string& to) {
        std::ifstream in(b / file, std::ios::binary);
        std::string text((std::istreambuf_iterator<char>(in)), {});
        const std::string original = text;
        REQUIRE(text.find(from) != std::string::npos);
        text.replace(text.find(from), from.size(), to);
        b.write(file, text);
        const std::string h = load_scene_file(b / "scene.json").content_hash;
        b.write(file, original);
        return h != sa.content_hash;
    };
    CHECK(changed("quad.mtl", "Kd 0.5", "Kd 0.6"));
    CHECK(changed("tex.ppm", std::string(1, char(200)), std::string(1, char(201))));
    CHECK(changed("cam.json", "\"width\": 4", "\"width\": 8"));
    CHECK(changed("quad.obj", "v 0 1 -2", "v 0 2 -2"));
    CHECK(changed("scene.json", "\"quad.obj\"]", "\"./quad.obj\"]"));
    CHECK(load_scene_file(b / "scene.json").content_hash == sa.content_hash);
    // A bundled scene: the OBJ's own library is an input too.
    const std::string wall = GDR_SOURCE_DIR "/tests/scenes/emitter-wall/";
    CHECK(load_scene_file(wall + "scene.json").inputs ==
          std::vector<std::string>{wall + "scene.json", wall + "wall.obj", wall + "wall.mtl"});
    // The documented layout, so stored hashes stay comparable: FNV-1a 64 over
    // each file's relative name, a zero byte, its size (8 bytes, little-endian) and its bytes.
    a.write("x.txt", "abc");
    uint64_t h = 0xcbf29ce484222325ull;
    const std::string bytes = std::string("x.txt") + '\0' + std::string("\3\0\0\0\0\0\0\0abc", 11);
    for (unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ull;
    std::ostringstream hex;
    hex << std::hex;
    hex.width(16);
    hex.fill('0');
    hex << h;
    CHECK(scene_content_hash(a / "scene.json", {a / "x.txt"}) == hex.str());
    CHECK_THROWS_AS(scene_content_hash(a / "scene.json", {a / "no-such-file"}), InputError);
}
