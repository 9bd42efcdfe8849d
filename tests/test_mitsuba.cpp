// Mitsuba XML scenes: every supported element on small inline scenes, the
// errors of unsupported and malformed ones (file, line, element, id), a
// bounded fuzz of mutated XML, and the shared scenes from their original XML
// against gdr's own scene files of them, in expectation.
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include <fmt/core.h>
#include <stb/stb_image_write.h>

#include "block_stats.h"
#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/io/mitsuba_xml.h"
#include "gdr/io/png.h"
#include "gdr/scene/microfacet.h"
#include "gdr/shift/validate.h"
#include "public_scenes.h"

using namespace gdr;
using namespace gdr::test;

namespace {

const std::string kSource = GDR_SOURCE_DIR;

// A camera at z = 5 looking down -z at a unit scene: the sensor of most inline scenes.
const std::string kSensor = R"(
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
  </sensor>)";

// Writes scene files into a temporary directory and loads them.
struct Xml {
    OutDir dir{"mitsuba"};
    std::string write(const std::string& name, const std::string& text) const {
        std::ofstream(dir(name), std::ios::binary) << text;
        return dir(name);
    }
    // A <scene version="3.0.0"> around `body` (with kSensor unless `sensor` is false).
    std::string scene(const std::string& body, bool sensor = true, const std::string& version = "3.0.0") const {
        return write("scene.xml", "<scene version=\"" + version + "\">" + (sensor ? kSensor : "") + body + "\n</scene>\n");
    }
    SceneFile load(const std::string& body, const SceneFileOptions& o = {}) const {
        return load_scene_file(scene(body), o);
    }
    // The message of the InputError that loading `body` throws ("" if none).
    std::string error(const std::string& body, const SceneFileOptions& o = {}) const {
        try {
            load(body, o);
        } catch (const InputError& e) {
            return e.what();
        }
        return "";
    }
};

SceneFileOptions lenient() {
    SceneFileOptions o;
    o.lenient = true;
    return o;
}

// The bounds of a scene's triangles.
std::pair<Vec3, Vec3> bounds(const Scene& s) {
    Vec3 lo(kInf), hi(-kInf);
    for (const Vec3& p : s.mesh().positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    return {lo, hi};
}

bool near(const Vec3& a, const Vec3& b, float eps = 1e-5f) { return glm::length(a - b) <= eps; }

// A shape holding `bsdf` (its XML), and the BSDF the scene made of it.
const Bsdf& bsdf_of(const SceneFile& sf) { return *sf.scene->materials().at(sf.scene->mesh().material_ids[0]).bsdf; }

// True if `b` is an untextured Lambertian reflector; sets f to its value kd / pi (1/sr).
bool is_lambertian(const Bsdf& b, Color& f) {
    if (b.flags() != (kReflection | kDiffuse)) return false;
    const Color a = b.eval(Vec3(0, 0, 1), Vec3(0.6f, 0, 0.8f), Vec2(0.3f));
    const Color c = b.eval(Vec3(0.8f, 0, 0.6f), Vec3(0, 0.6f, 0.8f), Vec2(0.7f, 0.1f));
    if (!(a == c)) return false;
    f = a;
    return true;
}

std::string rect(const std::string& inner) { return "<shape type=\"rectangle\">" + inner + "</shape>"; }

// `s` on a line of its own after the sensor: line 7 of the scene file.
std::string own_line(std::string s) {
    s.insert(s.begin(), '\n');
    return s;
}

// f |cos| / pdf of a delta BSDF sampled at normal-ish incidence with lobe number u.
Color delta_weight(const Bsdf& b, float u, Vec3* wi = nullptr) {
    const Vec3 wo = glm::normalize(Vec3(0.3f, 0.1f, 1.f));
    const auto s = b.sample(wo, Vec2(0.5f), u, Vec2(0.5f));
    REQUIRE(s);
    if (wi) *wi = s->wi;
    return s->f * std::abs(s->wi.z) / s->pdf;
}

bool any_warning(const SceneFile& sf, const std::string& what) {
    for (const std::string& w : sf.warnings)
        if (w.find(what) != std::string::npos) return true;
    return false;
}

}  // namespace

// ------------------------------------------------------------------ shapes and transforms

TEST_CASE("mitsuba: rectangle, cube, sphere and disk are triangulated with outward fronts", "[mitsuba]") {
    Xml x;
    const SceneFile r = x.load(rect(""));
    REQUIRE(r.scene->mesh().size() == 2);
    CHECK(bounds(*r.scene).first == Vec3(-1, -1, 0));
    CHECK(bounds(*r.scene).second == Vec3(1, 1, 0));
    // The front (emitting) side faces +z.
    const Vec3* p = &r.scene->mesh().positions[0];
    CHECK(glm::cross(p[1] - p[0], p[2] - p[0]).z > 0.f);
    CHECK(r.meshes.at(0).triangles == 2);

    const SceneFile c = x.load("<shape type=\"cube\"/>");
    REQUIRE(c.scene->mesh().size() == 12);
    CHECK(bounds(*c.scene).first == Vec3(-1.f));
    CHECK(bounds(*c.scene).second == Vec3(1.f));
    for (size_t t = 0; t < 12; ++t) {
        const Vec3* q = &c.scene->mesh().positions[3 * t];
        const Vec3 centre = (q[0] + q[1] + q[2]) / 3.f;
        CHECK(glm::dot(glm::cross(q[1] - q[0], q[2] - q[0]), centre) > 0.f);  // outward
    }

    const SceneFile s = x.load(R"(<shape type="sphere"><point name="center" x="1" y="2" z="3"/>
                                   <float name="radius" value="0.5"/></shape>)");
    CHECK(s.scene->mesh().size() == 3968);  // 64 x 32, as the shared scenes' conversions
    for (size_t t = 0; t < s.scene->mesh().size(); t += 97) {
        const Vec3* q = &s.scene->mesh().positions[3 * t];
        for (int k = 0; k < 3; ++k) CHECK(std::abs(glm::length(q[k] - Vec3(1, 2, 3)) - 0.5f) < 1e-5f);
        CHECK(glm::dot(glm::cross(q[1] - q[0], q[2] - q[0]), (q[0] + q[1] + q[2]) / 3.f - Vec3(1, 2, 3)) > 0.f);
    }

    const SceneFile d = x.load(R"(<shape type="disk"><boolean name="flip_normals" value="true"/></shape>)");
    CHECK(d.scene->mesh().size() == 64);
    const Vec3* q = &d.scene->mesh().positions[0];
    CHECK(glm::cross(q[1] - q[0], q[2] - q[0]).z < 0.f);  // flipped: the front faces -z
    CHECK(bounds(*d.scene).second.x == Approx(1.f));
}

TEST_CASE("mitsuba: ext_eta divides a conductor's eta and k, named or given, and 'none' stays a perfect mirror",
          "[mitsuba]") {
    Xml x;
    const float cos_o = 1.f / std::sqrt(1.1f);  // delta_weight's wo
    // The closed box's mirrors: Mitsuba 0.6's 'none' (eta 0, k 1) in air still reflects everything.
    const std::string none = R"(<bsdf type="conductor" id="metal"><string name="material" value="none"/>
        <string name="extEta" value="air"/><spectrum name="specularReflectance" value="1.0"/></bsdf>)";
    const SceneFile sf = load_scene_file(x.write("none.xml", "<scene version=\"0.6.0\">" + kSensor + rect(none) + "</scene>"));
    CHECK(delta_weight(bsdf_of(sf), 0.5f) == Color(1.f));
    CHECK(sf.warnings.empty());
    // eta and k with ext_eta: both are divided by it (glass-immersed gold is darker than in air).
    const SceneFile ek = x.load(rect(R"(<bsdf type="conductor"><rgb name="eta" value="0.2, 0.9, 1.1"/>
        <rgb name="k" value="3.9, 2.4, 2.1"/><float name="ext_eta" value="1.5"/></bsdf>)"));
    const Color in_glass = delta_weight(bsdf_of(ek), 0.5f);
    const ConductorIor divided{Color(0.2f, 0.9f, 1.1f) / 1.5f, Color(3.9f, 2.4f, 2.1f) / 1.5f};
    CHECK(in_glass.r == Approx(fresnel_conductor(divided, cos_o).r).epsilon(1e-4));
    CHECK(in_glass.r < fresnel_conductor(ConductorIor{Color(0.2f, 0.9f, 1.1f), Color(3.9f, 2.4f, 2.1f)}, cos_o).r);
    // A named metal in water: its tabulated eta and k divided the same way.
    const SceneFile au = x.load(rect(R"(<bsdf type="conductor" id="gold"><string name="material" value="Au"/>
        <float name="ext_eta" value="1.33"/></bsdf>)"));
    CHECK(au.warnings.empty());
    ConductorIor gold;
    REQUIRE(named_conductor_ior("Au", gold));
    const Color w = delta_weight(bsdf_of(au), 0.5f);
    const Color expect = fresnel_conductor(ConductorIor{gold.eta / 1.33f, gold.k / 1.33f}, cos_o);
    for (int c = 0; c < 3; ++c) CHECK(w[c] == Approx(expect[c]).epsilon(1e-4));
    CHECK(w.b < fresnel_conductor(gold, cos_o).b);
}

TEST_CASE("mitsuba: a lookat up within 1e-7 of the viewing axis still sets the roll, and an exactly parallel one is an error",
          "[mitsuba]") {
    Xml x;
    // As the water scene's randomised cameras: looking down -z with up = +z plus a remainder of 1e-7.
    const auto sensor = [](const std::string& up) {
        return R"(<sensor type="perspective"><transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up=")" + up +
               R"("/></transform><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film></sensor>)";
    };
    const std::string light = rect(R"(<emitter type="area"/>)");
    for (const float sign : {1.f, -1.f}) {
        CAPTURE(sign);
        const SceneFile sf = load_scene_file(x.scene(sensor(fmt::format("0, {}, 1", sign * 1e-7f)) + light, false));
        const Vec3 up = sf.scene->camera().desc().up;
        CHECK(up.y == Approx(sign).margin(1e-6));
        CHECK(std::abs(up.x) < 1e-6f);
        CHECK(std::abs(up.z) < 1e-6f);
    }
    CHECK_THROWS_WITH(load_scene_file(x.scene(sensor("0, 0, 1") + light, false)),
                      Catch::Contains("scene.xml:1") && Catch::Contains("up is parallel to the viewing direction"));
}

TEST_CASE("mitsuba: transforms apply translate, rotate, scale, matrix and lookat in order", "[mitsuba]") {
    Xml x;
    // Corner (1, 1, 0) of the rectangle: scaled by 2, then moved by x + 1, then turned 90 degrees about z.
    const SceneFile sf = x.load(rect(R"(<transform name="to_world"><scale value="2"/><translate x="1"/>
                                        <rotate z="1" angle="90"/></transform>)"));
    const auto [lo, hi] = bounds(*sf.scene);
    CHECK(near(lo, Vec3(-2, -1, 0)));
    CHECK(near(hi, Vec3(2, 3, 0)));
    // A matrix is row-major; scale takes x, y, z too.
    const SceneFile m = x.load(rect(R"(<transform name="to_world"><matrix value="1 0 0 10  0 1 0 0  0 0 1 0  0 0 0 1"/>
                                       <scale x="1" y="3" z="1"/></transform>)"));
    CHECK(near(bounds(*m.scene).first, Vec3(9, -3, 0)));
    CHECK(near(bounds(*m.scene).second, Vec3(11, 3, 0)));
    // lookat turns the local +z onto the viewing direction.
    const SceneFile l = x.load(rect(R"(<transform name="to_world"><lookat origin="0 0 0" target="1 0 0" up="0 1 0"/></transform>)"));
    CHECK(near(bounds(*l.scene).first, Vec3(0, -1, -1)));
    CHECK(near(bounds(*l.scene).second, Vec3(0, 1, 1)));
    const Vec3* p = &l.scene->mesh().positions[0];
    CHECK(glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0])).x == Approx(1.f));
    // A mirroring transform keeps the front on the side the normal is carried to.
    const SceneFile f = x.load(rect(R"(<transform name="to_world"><scale z="-1"/></transform>)"));
    const Vec3* q = &f.scene->mesh().positions[0];
    CHECK(glm::cross(q[1] - q[0], q[2] - q[0]).z < 0.f);
}

TEST_CASE("mitsuba: obj and ply shapes load with their normals, uvs and face_normals", "[mitsuba]") {
    Xml x;
    x.write("tri.obj", "mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0.6 0 0.8\n"
                       "usemtl whatever\nf 1/1/1 2/2/2 3/3/3\n");
    x.write("quad.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                        "property float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_indices\n"
                        "end_header\n0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n4 0 1 2 3\n");
    const SceneFile o = x.load(R"(<shape type="obj"><string name="filename" value="tri.obj"/>
                                    <transform name="to_world"><translate z="1"/></transform></shape>)");
    REQUIRE(o.scene->mesh().size() == 1);
    CHECK(o.scene->mesh().positions[1] == Vec3(1, 0, 1));
    CHECK(near(o.scene->mesh().normals[2], Vec3(0.6f, 0, 0.8f)));
    CHECK(o.scene->mesh().uvs[2] == Vec2(0, 1));  // OBJ's v, as gdr's OBJ loader keeps it
    CHECK(o.meshes.at(0).file == x.dir("tri.obj"));
    const SceneFile flat = x.load(R"(<shape type="obj"><string name="filename" value="tri.obj"/>
                                       <boolean name="faceNormals" value="true"/></shape>)");
    CHECK(near(flat.scene->mesh().normals[2], Vec3(0, 0, 1)));
    // Windows path separators are accepted.
    std::filesystem::create_directories(x.dir("models"));
    x.write("models/quad.ply", file_bytes(x.dir("quad.ply")));
    CHECK(x.load(R"(<shape type="ply"><string name="filename" value="models\quad.ply"/></shape>)").scene->mesh().size() == 2);
    const SceneFile p = x.load(R"(<shape type="ply"><string name="filename" value="quad.ply"/></shape>)");
    REQUIRE(p.scene->mesh().size() == 2);
    CHECK(p.scene->mesh().uvs[2] == Vec2(1, 0));  // PLY stores Mitsuba's v (0 at the top): gdr's is 1 - v
    CHECK(near(p.scene->mesh().normals[0], Vec3(0, 0, 1)));
    // The files read are inputs of the scene (its hash changes with them).
    CHECK(std::find(p.inputs.begin(), p.inputs.end(), x.dir("quad.ply")) != p.inputs.end());
}

// ------------------------------------------------------------------ BSDFs

TEST_CASE("mitsuba: diffuse and twosided become Lambertian, roughdiffuse Oren-Nayar", "[mitsuba]") {
    Xml x;
    Color f;
    const SceneFile d = x.load(rect(R"(<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf></bsdf>)"));
    REQUIRE(is_lambertian(bsdf_of(d), f));
    CHECK(f.g * kPi == Approx(0.4f));
    CHECK(d.warnings.empty());
    // roughdiffuse is Oren-Nayar (tests/test_mitsuba_bsdf.cpp), not Lambertian.
    const SceneFile r = x.load(rect(R"(<bsdf type="roughdiffuse"><float name="alpha" value="0.3"/></bsdf>)"));
    CHECK_FALSE(is_lambertian(bsdf_of(r), f));
    CHECK(bsdf_of(r).albedo(Vec2(0.f)).r == Approx(0.5f));  // Mitsuba's default reflectance
    CHECK(r.warnings.empty());
    // 0.6's other name of the reflectance.
    REQUIRE(is_lambertian(bsdf_of(x.load(rect(R"(<bsdf type="diffuse"><rgb name="diffuseReflectance" value="0.3"/></bsdf>)"))), f));
    CHECK(f.r * kPi == Approx(0.3f));
    // No BSDF: Mitsuba's default diffuse 0.5.
    REQUIRE(is_lambertian(bsdf_of(x.load(rect(""))), f));
    CHECK(f.b * kPi == Approx(0.5f));
}

TEST_CASE("mitsuba: conductors reflect the exact Fresnel reflectance of their eta and k", "[mitsuba]") {
    Xml x;
    const float cos_o = 1.f / std::sqrt(1.1f);  // delta_weight's wo
    // Explicit eta and k, scaled by specular_reflectance.
    const ConductorIor copper{Color(0.200438f, 0.924033f, 1.10221f), Color(3.91295f, 2.45285f, 2.14219f)};
    const SceneFile e = x.load(rect(R"(<bsdf type="conductor"><rgb name="eta" value="0.200438, 0.924033, 1.10221"/>
        <rgb name="k" value="3.91295, 2.45285, 2.14219"/><rgb name="specular_reflectance" value="0.3"/></bsdf>)"));
    const Color w = delta_weight(bsdf_of(e), 0.5f);
    for (int c = 0; c < 3; ++c) CHECK(w[c] == Approx(0.3f * fresnel_conductor(copper, cos_o)[c]).epsilon(1e-4));
    // At normal incidence: veach-mis's converted Ks.
    CHECK(0.3f * fresnel_conductor(copper, 1.f).r == Approx(0.2856f).epsilon(1e-3));
    CHECK(0.3f * fresnel_conductor(copper, 1.f).g == Approx(0.1859f).epsilon(1e-3));
    // Named metals (gold's normal-incidence blue 0.3240); the default is
    // Mitsuba 3's perfect mirror, and 0.6's copper.
    Color au0;
    REQUIRE(named_conductor_reflectance("Au", au0));
    CHECK(au0.b == Approx(0.3240f).epsilon(1e-3));
    ConductorIor gold, cu;
    REQUIRE(named_conductor_ior("Au", gold));
    CHECK(delta_weight(bsdf_of(x.load(rect(R"(<bsdf type="conductor"><string name="material" value="Au"/></bsdf>)"))), 0.5f).b ==
          Approx(fresnel_conductor(gold, cos_o).b).epsilon(1e-4));
    CHECK(delta_weight(bsdf_of(x.load(rect(R"(<bsdf type="conductor"/>)"))), 0.5f) == Color(1.f));
    REQUIRE(named_conductor_ior("Cu", cu));
    const SceneFile old = load_scene_file(x.write("old.xml", "<scene version=\"0.6.0\">" + kSensor + rect("<bsdf type=\"conductor\"/>") + "</scene>"));
    CHECK(delta_weight(bsdf_of(old), 0.5f).g == Approx(fresnel_conductor(cu, cos_o).g).epsilon(1e-4));
    // Rough: Mitsuba's default distribution, Beckmann, of the given alpha (no warning).
    const SceneFile rc = x.load(rect(R"(<bsdf type="roughconductor"><float name="alpha" value="0.2"/><string name="material" value="Al"/></bsdf>)"));
    CHECK(bsdf_of(rc).min_roughness() == Approx(0.2f));
    CHECK((bsdf_of(rc).flags() & kGlossy) != 0);
    CHECK(rc.warnings.empty());
    const SceneFile g = x.load(rect(R"(<bsdf type="roughconductor"><string name="distribution" value="ggx"/>
        <float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.4"/></bsdf>)"));
    CHECK(bsdf_of(g).min_roughness() == Approx(0.2f));
    CHECK(any_warning(g, "anisotropic"));
    CHECK_THAT(x.error(rect(R"(<bsdf type="conductor" id="m"><string name="material" value="Unobtainium"/></bsdf>)")),
               Catch::Contains("unknown conductor material 'Unobtainium'") && Catch::Contains("id=\"m\""));
}

TEST_CASE("mitsuba: dielectric, thindielectric and roughdielectric take int_ior / ext_ior", "[mitsuba]") {
    Xml x;
    const SceneFile d = x.load(rect(R"(<bsdf type="dielectric"><float name="int_ior" value="1.5"/><string name="ext_ior" value="water"/></bsdf>)"));
    CHECK(bsdf_of(d).eta() == Approx(1.5f / 1.333f));
    CHECK(bsdf_of(d).is_pure_delta());
    // 0.6 spelling, named glass.
    const SceneFile old = x.load(rect(R"(<bsdf type="dielectric"><string name="intIOR" value="bk7"/></bsdf>)"));
    CHECK(bsdf_of(old).eta() == Approx(1.5046f / 1.00028f));
    // A thin sheet: straight-through transmission, reflection R' = 2R / (1 + R), nothing absorbed.
    const SceneFile t = x.load(rect(R"(<bsdf type="thindielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>)"));
    const Bsdf& thin = bsdf_of(t);
    CHECK(thin.eta() == 1.f);
    const Vec3 wo = glm::normalize(Vec3(0.3f, 0.1f, 1.f));
    const float r1 = fresnel_dielectric(wo.z, 1.5f), r = 2.f * r1 / (1.f + r1);
    Vec3 wi;
    CHECK(delta_weight(thin, 0.999f, &wi) == Color(1.f));
    CHECK(near(wi, -wo));
    const auto refl = thin.sample(wo, Vec2(0.f), 0.f, Vec2(0.f));
    REQUIRE(refl);
    CHECK(refl->pdf == Approx(r));
    CHECK(refl->wi.z > 0.f);
    const auto e = thin.eval_delta(wo, -wo, Vec2(0.f));
    REQUIRE(e);
    CHECK(e->pdf == Approx(1.f - r));
    const SceneFile rd = x.load(rect(R"(<bsdf type="roughdielectric"><float name="alpha" value="0.3"/><string name="distribution" value="ggx"/></bsdf>)"));
    CHECK(bsdf_of(rd).min_roughness() == Approx(0.3f));
    CHECK((bsdf_of(rd).flags() & kTransmission) != 0);
    CHECK_THAT(x.error(rect(R"(<bsdf type="dielectric"><string name="int_ior" value="unobtainium"/></bsdf>)")),
               Catch::Contains("unknown index of refraction"));
}

TEST_CASE("mitsuba: plastic and roughplastic are diffuse + GGX with the coating's Fresnel weights", "[mitsuba]") {
    Xml x;
    const SceneFile p = x.load(rect(R"(<bsdf type="roughplastic"><float name="alpha" value="0.2"/><string name="distribution" value="ggx"/>
        <rgb name="diffuse_reflectance" value="0.5"/><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>)"));
    const Bsdf& b = bsdf_of(p);
    CHECK((b.flags() & kDiffuse) != 0);
    CHECK((b.flags() & kGlossy) != 0);
    CHECK(b.min_roughness() == Approx(0.2f));
    // The diffuse albedo seen through the coating: (1 - F0)^2 / eta^2 kd / (1 - Fdr) with F0 = 0.04 and Fdr about 0.596.
    const Color a = b.albedo(Vec2(0.f));
    CHECK(a.r > 0.45f);
    CHECK(a.r < 0.60f);
    // nonlinear lowers it (kd / (1 - kd Fdr)); smooth plastic is a sharp GGX lobe.
    const SceneFile n = x.load(rect(R"(<bsdf type="plastic"><boolean name="nonlinear" value="true"/></bsdf>)"));
    CHECK(bsdf_of(n).albedo(Vec2(0.f)).r < a.r);
    CHECK(bsdf_of(n).min_roughness() < 0.05f);
}

TEST_CASE("mitsuba: a conductor loads in any outer medium", "[mitsuba]") {
    // material "none" reflects everything whatever ext_eta is (the shared box's
    // mirrors name extEta "air"); a named metal's eta and k are divided by it.
    Xml x;
    const SceneFile m = x.load(rect(R"(<bsdf type="conductor"><string name="material" value="none"/>
        <string name="ext_eta" value="air"/></bsdf>)"));
    CHECK(bsdf_of(m).is_pure_delta());
    const SceneFile cu = x.load(rect(R"(<bsdf type="roughconductor"><string name="material" value="Cu"/>
        <string name="ext_eta" value="air"/></bsdf>)"));
    CHECK(cu.warnings.empty());
    // A negative index is an error naming the element.
    CHECK_THAT(x.error(rect(R"(<bsdf type="conductor"><rgb name="eta" value="-1, 1, 1"/><rgb name="k" value="1"/></bsdf>)")),
               Catch::Contains("eta") && Catch::Contains("conductor"));
}

TEST_CASE("mitsuba: a 0.x bitmap opacity is its colour, a 3.x one its alpha channel", "[mitsuba]") {
    // Mitsuba 0.6 drops a bitmap's alpha: a white texel of alpha 0 (a cut-out
    // leaf's background) is opaque there; Mitsuba 3 reads the alpha.
    Xml x;
    const unsigned char px[8] = {255, 255, 255, 0, 255, 255, 255, 0};
    REQUIRE(stbi_write_png(x.dir("card.png").c_str(), 2, 1, 4, px, 8) != 0);
    const std::string body = R"(<shape type="rectangle"><bsdf type="mask"><texture name="opacity" type="bitmap">
        <string name="filename" value="card.png"/></texture><bsdf type="diffuse"/></bsdf></shape>)";
    for (const std::string version : {"0.6.0", "3.0.0"}) {
        const SceneFile sf = load_scene_file(x.scene(body, true, version));
        const auto& o = sf.scene->materials().at(0).opacity;
        REQUIRE(o);
        INFO("version " << version);
        CHECK(luminance(o->eval(Vec2(0.25f, 0.5f))) == Approx(version == "0.6.0" ? 1.f : 0.f).margin(1e-3));
    }
}

TEST_CASE("mitsuba: mask cuts holes where its opacity is 0 and passes 1 - opacity of the rays elsewhere", "[mitsuba]") {
    Xml x;
    // A checkerboard opacity over the rectangle: the quarter around Mitsuba uv (0.75, 0.75) is opaque.
    const SceneFile m = x.load(rect(R"(<bsdf type="mask"><texture name="opacity" type="checkerboard">
        <float name="color0" value="1"/><float name="color1" value="0"/></texture><bsdf type="diffuse"/></bsdf>)"));
    const Scene& s = *m.scene;
    REQUIRE(s.materials().at(0).opacity);
    // Rays down the z axis through the four quadrants.
    const auto hits = [&](float px, float py) {
        SurfaceInteraction si;
        return s.intersect(Ray{Vec3(px, py, 1.f), Vec3(0, 0, -1), 0.f, kInf}, si);
    };
    // Mitsuba uv (u, v) = ((x + 1) / 2, (y + 1) / 2); color0 where both halves agree.
    CHECK(hits(0.5f, 0.5f));
    CHECK(hits(-0.5f, -0.5f));
    CHECK_FALSE(hits(-0.5f, 0.5f));
    CHECK_FALSE(hits(0.5f, -0.5f));
    CHECK_FALSE(s.occluded(Ray{Vec3(-0.5f, 0.5f, 1.f), Vec3(0, 0, -1), 0.f, 2.f}));
    CHECK(s.occluded(Ray{Vec3(0.5f, 0.5f, 1.f), Vec3(0, 0, -1), 0.f, 2.f}));
    // Packets see the same holes.
    const Ray rays[4] = {{Vec3(0.5f, 0.5f, 1), Vec3(0, 0, -1)}, {Vec3(-0.5f, 0.5f, 1), Vec3(0, 0, -1)},
                         {Vec3(-0.5f, -0.5f, 1), Vec3(0, 0, -1)}, {Vec3(0.5f, -0.5f, 1), Vec3(0, 0, -1)}};
    const bool active[4] = {true, true, true, true};
    SurfaceInteraction si[4];
    SurfaceInteraction* const sp[4] = {&si[0], &si[1], &si[2], &si[3]};
    bool hit[4];
    s.intersect4(rays, active, sp, hit);
    CHECK(hit[0]);
    CHECK_FALSE(hit[1]);
    CHECK(hit[2]);
    CHECK_FALSE(hit[3]);
    // A fractional opacity stops that share of the rays (Mitsuba's mask), each
    // ray always with the same outcome, in intersection and occlusion alike.
    // Binomial z-test on 20000 rays: |z| < 5. A threshold at 1/2 (the
    // earlier cut-out rule) stops none of them at opacity 0.3: z = -93.
    const SceneFile c = x.load(rect(R"(<bsdf type="mask"><float name="opacity" value="0.3"/><bsdf type="diffuse"/></bsdf>)"));
    CHECK(c.warnings.empty());
    const int n = 20000;
    int stopped = 0;
    for (int i = 0; i < n; ++i) {
        const float px = -0.9f + 1.8f * float(i % 200) / 200.f, py = -0.9f + 1.8f * float(i / 200) / 100.f;
        const Ray r{Vec3(px, py, 1.f), Vec3(0, 0, -1), 0.f, kInf};
        const bool h = c.scene->intersect(r, *sp[0]);
        REQUIRE(h == c.scene->intersect(r, *sp[1]));
        REQUIRE(h == c.scene->occluded(Ray{Vec3(px, py, 1.f), Vec3(0, 0, -1), 0.f, 2.f}));
        stopped += h;
    }
    const double z = (stopped - 0.3 * n) / std::sqrt(n * 0.3 * 0.7);
    INFO(stopped << " of " << n << " stopped, z = " << z);
    CHECK(std::abs(z) < 5.0);
}

TEST_CASE("mitsuba: every built-in shift passes the validator through thin glass, plastic and a mask", "[mitsuba][shift]") {
    // A closed box seen from inside, lit from its ceiling, holding a thin
    // glass pane, a rough plastic sphere and a checkerboard cut-out: the BSDFs
    // and the alpha test this importer adds, under every shift.
    Xml x;
    const SceneFile sf = load_scene_file(x.write("shifts.xml", R"XML(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="90"/>
    <transform name="to_world"><lookat origin="0, 1, 0.97" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/></film></sensor>
  <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.7"/></bsdf>
  <shape type="cube"><transform name="to_world"><scale value="1"/><translate y="1"/></transform><boolean name="flip_normals" value="true"/><ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="1.98"/></transform>
    <emitter type="area"><rgb name="radiance" value="15"/></emitter></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.5"/><translate x="-0.3" y="0.8" z="0.5"/></transform>
    <bsdf type="thindielectric"/></shape>
  <shape type="sphere"><point name="center" x="0.4" y="0.4" z="0"/><float name="radius" value="0.35"/>
    <bsdf type="roughplastic"><float name="alpha" value="0.05"/><rgb name="diffuse_reflectance" value="0.3, 0.5, 0.2"/></bsdf></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.4"/><translate x="0.3" y="1.2" z="-0.5"/></transform>
    <bsdf type="mask"><texture name="opacity" type="checkerboard"><float name="color0" value="1"/><float name="color1" value="0"/>
      <transform name="to_uv"><scale value="3"/></transform></texture><bsdf type="diffuse"/></bsdf></shape>
</scene>
)XML"));
    for (const char* name : {"half-vector", "reconnection", "replay", "replay-reconnect"}) {
        ValidateOptions opt;
        opt.paths = 3000;
        const auto shift = shift_registry().create(name, Params());
        const ShiftReport rep = validate_shift(*sf.scene, *shift, ShiftConfig{}, opt);
        INFO(rep.summary());
        CHECK(rep.passed);
        CHECK(rep.base_paths > 1000);
    }
}

// ------------------------------------------------------------------ textures

TEST_CASE("mitsuba: bitmap and checkerboard textures with to_uv", "[mitsuba]") {
    Xml x;
    // A 2x2 image: top row red, green; bottom row blue, white.
    Image img(2, 2, 3);
    const Color px[4] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
    for (int i = 0; i < 4; ++i)
        for (int c = 0; c < 3; ++c) img.data()[3 * i + c] = px[i][c];
    write_png_preview(x.dir("tex.png"), img);
    const SceneFile b = x.load(rect(R"(<bsdf type="diffuse"><texture name="reflectance" type="bitmap">
        <string name="filename" value="tex.png"/><string name="filter_type" value="nearest"/></texture></bsdf>)"));
    const Bsdf& d = bsdf_of(b);
    const Vec3 up(0, 0, 1);
    // gdr uv (0.25, 0.75) is Mitsuba's (0.25, 0.25): the top-left texel.
    CHECK(d.eval(up, up, Vec2(0.25f, 0.75f)).r * kPi == Approx(1.f).margin(0.01));
    CHECK(d.eval(up, up, Vec2(0.25f, 0.25f)).b * kPi == Approx(1.f).margin(0.01));
    CHECK(std::find(b.inputs.begin(), b.inputs.end(), x.dir("tex.png")) != b.inputs.end());
    // to_uv: a shift by half the image in u swaps left and right.
    const SceneFile t = x.load(rect(R"(<bsdf type="diffuse"><texture name="reflectance" type="bitmap">
        <string name="filename" value="tex.png"/><string name="filter_type" value="nearest"/>
        <transform name="to_uv"><translate x="0.5"/></transform></texture></bsdf>)"));
    CHECK(bsdf_of(t).eval(up, up, Vec2(0.25f, 0.75f)).g * kPi == Approx(1.f).margin(0.01));
    // 0.6's uoffset does the same.
    const SceneFile o = x.load(rect(R"(<bsdf type="diffuse"><texture name="reflectance" type="bitmap">
        <string name="filename" value="tex.png"/><string name="filterType" value="nearest"/>
        <float name="uoffset" value="0.5"/></texture></bsdf>)"));
    CHECK(bsdf_of(o).eval(up, up, Vec2(0.25f, 0.75f)).g * kPi == Approx(1.f).margin(0.01));
    // Checkerboard, with a to_uv scale of 2 (four cells per unit), referenced by id.
    const SceneFile c = x.load(R"(<texture type="checkerboard" id="check"><rgb name="color0" value="0.8"/>
        <rgb name="color1" value="0.1"/><transform name="to_uv"><scale value="2"/></transform></texture>)" +
                               rect(R"(<bsdf type="plastic"><ref name="diffuse_reflectance" id="check"/></bsdf>)"));
    const Bsdf& p = bsdf_of(c);
    const Vec3 off = glm::normalize(Vec3(0.7f, 0.f, 1.f));  // far from the sharp specular lobe
    const float hi = p.eval(up, off, Vec2(0.1f, 0.9f)).r;  // Mitsuba uv (0.1, 0.1) -> (0.2, 0.2): color0
    const float lo = p.eval(up, off, Vec2(0.3f, 0.9f)).r;  // (0.6, 0.2): color1
    CHECK(hi > 4.f * lo);
    CHECK_THAT(x.error(rect(R"(<bsdf type="diffuse"><texture name="reflectance" type="bitmap" id="t">
        <string name="filename" value="missing.png"/></texture></bsdf>)")),
               Catch::Contains("id=\"t\"") && Catch::Contains("missing.png"));
}

// ------------------------------------------------------------------ emitters, sensor, integrator

TEST_CASE("mitsuba: area emitters emit their radiance from the shape's front", "[mitsuba]") {
    Xml x;
    const SceneFile e = x.load(rect(R"(<emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>)") +
                               "<shape type=\"cube\"><transform name=\"to_world\"><translate z=\"-3\"/></transform></shape>");
    CHECK(e.scene->stats().emitters == 2);
    SurfaceInteraction si;
    REQUIRE(e.scene->intersect(Ray{Vec3(0, 0, 1), Vec3(0, 0, -1), 0.f, kInf}, si));
    CHECK(si.emitted(Vec3(0, 0, 1)) == Color(1, 2, 3));
    CHECK(si.emitted(Vec3(0, 0, -1)) == Color(0.f));
    CHECK(si.material->name.find("rectangle") != std::string::npos);
    // A shape's emitter other than area, and area emitters outside shapes.
    CHECK_THAT(x.error(R"(<emitter type="area"/>)"), Catch::Contains("belongs inside a <shape>"));
    CHECK_THAT(x.error(rect(R"(<emitter type="point" id="p"/>)")), Catch::Contains("'point'") && Catch::Contains("id=\"p\""));
}

TEST_CASE("mitsuba: the perspective sensor's fov, fov_axis and film", "[mitsuba]") {
    Xml x;
    const auto camera = [&](const std::string& fov) {
        const std::string s = R"(<sensor type="perspective">)" + fov + R"(
            <transform name="to_world"><lookat origin="1, 2, 3" target="1, 2, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="20"/><rfilter type="box"/></film>
            <sampler type="independent"><integer name="sample_count" value="7"/></sampler></sensor>)";
        return load_scene_file(x.write("cam.xml", "<scene version=\"3.0.0\">" + s + rect("") + "</scene>"));
    };
    const SceneFile a = camera(R"(<float name="fov" value="60"/>)");
    const CameraDesc& d = a.scene->camera().desc();
    CHECK(d.position == Vec3(1, 2, 3));
    CHECK(near(d.target - d.position, Vec3(0, 0, -1)));
    CHECK(d.fov_axis == 'x');  // Mitsuba's default
    CHECK(d.fov_deg == Approx(60.f));
    CHECK(d.width == 40);
    CHECK(d.height == 20);
    CHECK(a.defaults.spp == 7);
    CHECK(a.warnings.empty());
    CHECK(camera(R"(<float name="fov" value="30"/><string name="fov_axis" value="y"/>)").scene->camera().desc().fov_axis == 'y');
    CHECK(camera(R"(<float name="fov" value="30"/><string name="fov_axis" value="smaller"/>)").scene->camera().desc().fov_axis == 'y');
    CHECK(camera(R"(<float name="fov" value="30"/><string name="fov_axis" value="larger"/>)").scene->camera().desc().fov_axis == 'x');
    // The diagonal's field of view: tan(x / 2) = tan(d / 2) * 40 / sqrt(40^2 + 20^2).
    const CameraDesc g = camera(R"(<float name="fov" value="50"/><string name="fov_axis" value="diagonal"/>)").scene->camera().desc();
    CHECK(std::tan(g.fov_deg * kPi / 360.f) == Approx(std::tan(50.f * kPi / 360.f) * 40.f / std::sqrt(2000.f)));
    // The image's right is Mitsuba's -x: a point at +x of the camera lands on the right half.
    Vec2 film;
    REQUIRE(a.scene->camera().project(Vec3(1.5f, 2, 0), film));
    CHECK(film.x > 20.f);
    REQUIRE(a.scene->camera().project(Vec3(1, 2.5f, 0), film));
    CHECK(film.y < 10.f);
    // Filters other than box are replaced, with a warning naming the substitution.
    const SceneFile t = load_scene_file(
        x.scene(R"(<sensor type="perspective"><film type="hdrfilm"><rfilter type="gaussian"/></film></sensor>)" + rect(""), false));
    CHECK(any_warning(t, "'gaussian' is replaced by gdr's box filter"));
    CHECK(t.scene->camera().width() == 768);  // film defaults
    // No fov: Mitsuba's 50 mm lens, whose field of view is along the diagonal of 36 x 24 mm film.
    const float tan_x = std::tan(t.scene->camera().desc().fov_deg * kPi / 360.f);
    CHECK(tan_x == Approx(std::sqrt(36.f * 36.f + 24.f * 24.f) / 100.f * 768.f / std::sqrt(768.f * 768.f + 576.f * 576.f)));
    CHECK(t.scene->camera().desc().fov_axis == 'x');
    CHECK_THROWS_WITH(load_scene_file(x.scene(R"(<sensor type="perspective"><string name="fov_axis" value="z"/></sensor>)" + rect(""), false)),
                      Catch::Contains("unknown fov_axis 'z'"));
}

TEST_CASE("mitsuba: the integrator's max_depth and rr_depth, and its type", "[mitsuba]") {
    Xml x;
    const SceneFile p = x.load(R"(<integrator type="path"><integer name="max_depth" value="6"/><integer name="rr_depth" value="3"/></integrator>)" + rect(""));
    CHECK(p.defaults.integrator == "pt");
    CHECK(p.defaults.params.get_int("max_depth", -99) == 6);
    CHECK(p.defaults.params.get_int("rr_depth", -99) == 3);
    CHECK(x.load(R"(<integrator type="bdpt"/>)" + rect("")).defaults.integrator == "bdpt");
    CHECK(x.load(R"(<integrator type="gpt"><integer name="maxDepth" value="4"/></integrator>)" + rect("")).defaults.integrator == "gpt");
    // Another estimator of the same image: pt, said in a warning.
    const SceneFile s = x.load(R"(<integrator type="sppm"><integer name="photon_count" value="10"/><integer name="max_depth" value="5"/></integrator>)" + rect(""));
    CHECK(s.defaults.integrator == "pt");
    CHECK(any_warning(s, "'sppm' is rendered with gdr's pt"));
    CHECK(s.defaults.params.get_int("max_depth", -99) == 5);
    CHECK_THAT(x.error(R"(<integrator type="path"><boolean name="hide_emitters" value="true"/></integrator>)" + rect("")),
               Catch::Contains("unsupported property 'hide_emitters'"));
}

// ------------------------------------------------------------------ parameters, include, ref

TEST_CASE("mitsuba: default and $parameters, -D overrides, include and ref", "[mitsuba]") {
    Xml x;
    x.write("part.xml", R"(<scene version="3.0.0"><bsdf type="diffuse" id="grey"><rgb name="reflectance" value="$level"/></bsdf></scene>)");
    const std::string body = R"(<default name="level" value="0.25"/><default name="res" value="16"/>
        <include filename="part.xml"/>
        <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/></film></sensor>
        <shape type="rectangle"><ref id="grey"/></shape>)";
    const SceneFile a = load_scene_file(x.scene(body, false));
    Color f;
    REQUIRE(is_lambertian(bsdf_of(a), f));
    CHECK(f.r * kPi == Approx(0.25f));
    CHECK(a.scene->camera().width() == 16);
    CHECK(a.inputs.size() == 2);  // the scene and the included file
    SceneFileOptions o;
    o.defines = {{"level", "0.5"}, {"res", "8"}};
    const SceneFile b = load_scene_file(x.scene(body, false), o);
    REQUIRE(is_lambertian(bsdf_of(b), f));
    CHECK(f.r * kPi == Approx(0.5f));
    CHECK(b.scene->camera().height() == 8);
    // Another value makes another scene of the same files: --resume and merge tell them apart by the hash.
    CHECK(b.content_hash != a.content_hash);
    // An unused -D, an undefined parameter, an unknown id, an id given twice.
    o.defines = {{"levle", "0.5"}};
    CHECK_THROWS_WITH(load_scene_file(x.scene(body, false), o), Catch::Contains("-D levle=0.5") && Catch::Contains("no parameter"));
    o.defines = {{"unused", "1"}};
    CHECK_THROWS_WITH(load_scene_file(x.scene("<default name=\"unused\" value=\"0\"/>" + body, false), o),
                      Catch::Contains("declares $unused but uses it nowhere"));
    CHECK_THAT(x.error(rect(R"(<bsdf type="diffuse"><rgb name="reflectance" value="$nothing"/></bsdf>)")),
               Catch::Contains("$nothing has no value") && Catch::Contains("-D nothing="));
    CHECK_THAT(x.error(own_line(rect(R"(<ref id="nobody"/>)"))), Catch::Contains("no element has id 'nobody'") && Catch::Contains(":7:"));
    CHECK_THAT(x.error(R"(<bsdf type="diffuse" id="a"/><bsdf type="diffuse" id="a"/>)" + rect("")),
               Catch::Contains("id 'a' is given twice"));
    CHECK_THAT(x.error(R"(<include filename="absent.xml"/>)"), Catch::Contains("absent.xml") && Catch::Contains("not found"));
    // -D is for XML scenes only.
    o.defines = {{"x", "1"}};
    CHECK_THROWS_WITH(load_scene_file(std::string(GDR_SOURCE_DIR) + "/tests/scenes/cornell-small.json", o),
                      Catch::Contains("Mitsuba XML scenes only"));
}

// ------------------------------------------------------------------ errors and --lenient

TEST_CASE("mitsuba: unsupported elements are errors naming file, line, element and id, and warnings with --lenient", "[mitsuba][errors]") {
    Xml x;
    const std::string file = x.dir("scene.xml");
    // The sensor takes lines 1 to 6, so the shape starts on line 7.
    const std::string hair = "\n<shape type=\"hair\" id=\"fur\"/>";
    CHECK_THAT(x.error(hair), Catch::StartsWith(file + ":7: <shape type=\"hair\" id=\"fur\">") &&
                                   Catch::Contains("unsupported shape type 'hair'") && Catch::Contains("--lenient"));
    const std::string both = hair + rect("");
    const SceneFile l = x.load(both, lenient());
    CHECK(l.scene->mesh().size() == 2);
    REQUIRE(l.warnings.size() == 1);
    CHECK_THAT(l.warnings[0], Catch::Contains(":7:") && Catch::Contains("fur") && Catch::Contains("skips it"));
    // An unsupported BSDF: lenient renders grey diffuse.
    CHECK_THAT(x.error(rect(R"(<bsdf type="hanrahan" id="skin"/>)")), Catch::Contains("id=\"skin\"") && Catch::Contains("'hanrahan'"));
    Color f;
    CHECK(is_lambertian(bsdf_of(x.load(rect(R"(<bsdf type="hanrahan" id="skin"/>)"), lenient())), f));
    // Wrappers keep their nested BSDF.
    const SceneFile bump = x.load(rect(R"(<bsdf type="bumpmap"><texture type="bitmap"><string name="filename" value="x.png"/></texture>
        <bsdf type="roughconductor"/></bsdf>)"), lenient());
    CHECK((bsdf_of(bump).flags() & kGlossy) != 0);
    // Unknown properties are named, with their owner.
    CHECK_THAT(x.error(rect(R"(<bsdf type="diffuse" id="d"><float name="sheen" value="1"/></bsdf>)")),
               Catch::Contains("<float name=\"sheen\"> in <bsdf type=\"diffuse\" id=\"d\">") &&
                   Catch::Contains("unsupported property 'sheen'"));
    // Sun and sky emitters are environments (test_sky.cpp); a second one is refused.
    for (const char* env : {"sunsky", "sky", "sun"}) {
        INFO(env);
        const std::string e = std::string("\n<emitter type=\"") + env + "\" id=\"sky\"/>";
        CHECK(x.load(e + rect("")).scene->environment() != nullptr);
        CHECK_THAT(x.error(e + "<emitter type=\"constant\"/>" + rect("")), Catch::Contains("one environment"));
    }
    // constant and envmap are environments (test_environment.cpp).
    CHECK(x.load("\n<emitter type=\"constant\"/>" + rect("")).scene->environment() != nullptr);
    // A mesh file that is missing: an error, or with --lenient the shape skipped.
    const std::string gone = R"(<shape type="obj" id="gone"><string name="filename" value="gone.obj"/></shape>)";
    CHECK_THAT(x.error(gone + rect("")), Catch::Contains("id=\"gone\"") && Catch::Contains("gone.obj: file not found"));
    CHECK(x.load(gone + rect(""), lenient()).scene->mesh().size() == 2);
    // A texture file that is missing: an error, or with --lenient mid-grey with a warning.
    const std::string tex = R"(<bsdf type="diffuse" id="paper"><texture type="bitmap" name="reflectance">
        <string name="filename" value="gone.jpg"/></texture></bsdf>)";
    CHECK_THAT(x.error(rect(tex)), Catch::Contains("gone.jpg: file not found") && Catch::Contains("--lenient"));
    const SceneFile grey_paper = x.load(rect(tex), lenient());
    CHECK(any_warning(grey_paper, "mid-grey"));
    CHECK(is_lambertian(bsdf_of(grey_paper), f));
    CHECK(f.r == Approx(0.5f / 3.14159265f));  // f = albedo / pi
}

TEST_CASE("mitsuba: malformed XML and values are errors naming the line", "[mitsuba][errors]") {
    Xml x;
    const std::string file = x.dir("scene.xml");
    CHECK_THAT(x.error("\n<shape type=\"cube\">"), Catch::StartsWith(file + ":") && Catch::Contains("malformed XML"));
    CHECK_THROWS_WITH(load_scene_file(x.write("notscene.xml", "<?xml version=\"1.0\"?>\n<sceen/>")),
                      Catch::Contains("notscene.xml:2") && Catch::Contains("not <scene>"));
    CHECK_THAT(x.error(own_line(rect(R"(<transform name="to_world"><matrix value="1 2 3"/></transform>)"))),
               Catch::Contains(":7:") && Catch::Contains("16 numbers"));
    CHECK_THAT(x.error(rect(R"(<bsdf type="diffuse"><rgb name="reflectance" value="0.5, x, 1"/></bsdf>)")),
               Catch::Contains("finite number") && Catch::Contains("'x'"));
    CHECK_THAT(x.error(rect(R"(<bsdf type="diffuse"><float name="reflectance" value="1"/><float name="reflectance" value="2"/></bsdf>)")),
               Catch::Contains("given twice"));
    CHECK_THAT(x.error("<shape type=\"cube\"><boolean name=\"flip_normals\" value=\"maybe\"/></shape>"),
               Catch::Contains("true or false"));
    CHECK_THAT(x.error("<shape type=\"cube\"><wobble/></shape>"), Catch::Contains("unknown element <wobble>"));
    CHECK_THROWS_WITH(load_scene_file(x.write("nocam.xml", "<scene version=\"3.0.0\">" + rect("") + "</scene>")),
                      Catch::Contains("no <sensor>"));
    CHECK_THROWS_WITH(load_scene_file(x.write("v9.xml", "<scene version=\"9.0.0\">" + kSensor + rect("") + "</scene>")),
                      Catch::Contains("unsupported scene version '9.0.0'"));
}

TEST_CASE("mitsuba: mutated scene files never crash the loader", "[mitsuba][errors]") {
    // A fixed-seed fuzz: byte flips, deleted and duplicated spans of a scene
    // that uses most elements. Each load either succeeds or throws gdr::Error.
    Xml x;
    Image img(2, 2, 3);
    write_png_preview(x.dir("t.png"), img);
    x.write("m.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    const std::string base = R"(<scene version="3.0.0"><default name="d" value="0.5"/>
<integrator type="path"><integer name="max_depth" value="4"/></integrator>
<sensor type="perspective"><float name="fov" value="40"/><transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film>
<sampler type="independent"><integer name="sample_count" value="4"/></sampler></sensor>
<texture type="bitmap" id="t"><string name="filename" value="t.png"/><transform name="to_uv"><scale value="2"/></transform></texture>
<bsdf type="twosided" id="a"><bsdf type="roughplastic"><ref name="diffuse_reflectance" id="t"/><float name="alpha" value="$d"/></bsdf></bsdf>
<bsdf type="mask" id="m"><texture name="opacity" type="checkerboard"/><bsdf type="roughconductor"><string name="material" value="Au"/></bsdf></bsdf>
<shape type="rectangle"><ref id="a"/><emitter type="area"><rgb name="radiance" value="1,2,3"/></emitter></shape>
<shape type="sphere"><float name="radius" value="0.5"/><bsdf type="dielectric"/></shape>
<shape type="ply"><string name="filename" value="m.ply"/><ref id="m"/><transform name="to_world"><rotate y="1" angle="30"/><translate x="1"/></transform></shape>
<shape type="cube"><bsdf type="thindielectric"/></shape>
</scene>)";
    std::mt19937 rng(26);
    const std::string junk = "<>/\"=$# 0.-e1xyzabc\n";
    int loaded = 0, errors = 0;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < 120; ++i) {
        std::string s = base;
        const int edits = 1 + int(rng() % 4);
        for (int e = 0; e < edits; ++e) {
            const size_t at = rng() % s.size(), len = 1 + rng() % 12;
            switch (rng() % 4) {
            case 0: s[at] = junk[rng() % junk.size()]; break;
            case 1: s.erase(at, len); break;
            case 2: s.insert(at, s.substr(rng() % s.size(), len)); break;
            default: {
                // An attribute value replaced by an odd one.
                static const char* const kValues[] = {"", "-1", "0", "1e30", "nan", "inf", "x", "$d", "1 2", "-0.5, 2, 1e-30"};
                const size_t open = s.find('"', at), close = open == std::string::npos ? open : s.find('"', open + 1);
                if (close != std::string::npos) s.replace(open + 1, close - open - 1, kValues[rng() % 10]);
            }
            }
        }
        try {
            load_scene_file(x.write("fuzz.xml", s), i % 2 ? lenient() : SceneFileOptions{});
            ++loaded;
        } catch (const Error&) {
            ++errors;
        }
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    CAPTURE(loaded, errors, seconds);
    CHECK(loaded > 0);
    CHECK(errors > 0);
    CHECK(seconds < 2.0);
}

// ------------------------------------------------------------------ the shared scenes

namespace {

SceneFile at_res(const std::string& path, int w, int h, const SceneFileOptions& o = {}) {
    SceneFile sf = load_scene_file(path, o);
    set_resolution(sf, w, h);
    return sf;
}

}  // namespace

TEST_CASE("mitsuba: the Cornell box's cameras from XML and camera.json agree exactly", "[mitsuba]") {
    const SceneFile xml = load_scene_file(kSource + "/scenes/cornell-box-cc0/original-mitsuba-scene.xml");
    const SceneFile json = load_scene_file(std::string(GDR_SOURCE_DIR) + "/scenes/cornell-box-cc0/scene.json");
    const Camera& a = xml.scene->camera();
    const Camera& b = json.scene->camera();
    REQUIRE(a.width() == b.width());
    REQUIRE(a.height() == b.height());
    // The room's corners and the boxes' vertices: every vertex of the XML scene.
    const auto [lo, hi] = bounds(*xml.scene);
    std::vector<Vec3> points = xml.scene->mesh().positions;
    for (int c = 0; c < 8; ++c) points.push_back(Vec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z));
    double worst = 0.0;
    for (const Vec3& p : points) {
        Vec2 fa, fb;
        REQUIRE(a.project(p, fa) == b.project(p, fb));
        worst = std::max(worst, double(glm::length(fa - fb)));
    }
    CAPTURE(worst);
    CHECK(worst < 1e-3);  // pixels of the 1024 x 1024 image
    // And the geometry is the converted OBJ's.
    const auto [jlo, jhi] = bounds(*json.scene);
    CHECK(near(lo, jlo, 1e-4f));
    CHECK(near(hi, jhi, 1e-4f));
}

TEST_CASE("mitsuba: the shared scenes' XML renders equal gdr's scene files of them in expectation",
          "[mitsuba][shared][statistical]") {
    struct Case {
        const char* name;
        std::string xml, json;
        int w, h, block;
        long long spp;
        long long max_depth;
    };
    const std::string src = GDR_SOURCE_DIR;
    // veach-mis's plates are Beckmann in the XML, and GGX in gdr's converted
    // scene file (its MTL roughness): the two now differ (z = 9.7 measured),
    // so the XML is compared with its distribution switched to GGX. The file
    // names no other file, so a copy elsewhere loads the same.
    OutDir tmp("mitsuba-shared");
    std::ifstream in(kSource + "/scenes/veach-mis/original-mitsuba-scene.xml", std::ios::binary);
    std::string mis((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (size_t at; (at = mis.find("value=\"beckmann\"")) != std::string::npos;) mis.replace(at, 16, "value=\"ggx\"");
    std::ofstream(tmp("veach-mis-ggx.xml"), std::ios::binary) << mis;
    const Case cases[] = {
        {"cornell-box-cc0", kSource + "/scenes/cornell-box-cc0/original-mitsuba-scene.xml",
         src + "/scenes/cornell-box-cc0/scene.json", 24, 24, 6, 32, 30},
        {"veach-mis", tmp("veach-mis-ggx.xml"), src + "/scenes/veach-mis/scene.json", 40, 24, 8, 32, 3},
        {"veach-bidir", public_scene("mitsuba/veach-bidir/scene.xml"), src + "/scenes/veach-bidir/scene.json", 24,
         24, 12, 128, 7},
    };
    const int runs = 8;
    for (const Case& c : cases) {
        INFO(c.name);
        if (c.xml.empty()) {  // a public scene outside the repository
            WARN(public_scene_missing("mitsuba/veach-bidir", false));
            continue;
        }
        const SceneFile x = at_res(c.xml, c.w, c.h), j = at_res(c.json, c.w, c.h);
        // The XML's own max_depth, given to both.
        REQUIRE(x.defaults.params.get_int("max_depth", -99) == c.max_depth);
        Params p;
        p.set("max_depth", c.max_depth);
        const BlockStats bx = grey_stats(render_runs(*x.scene, "pt", p, c.spp, runs, 100), "color", c.block);
        const BlockStats bj = grey_stats(render_runs(*j.scene, "pt", p, c.spp, runs, 500), "color", c.block);
        const double z = max_z(bx, bj), z_dark = max_z(scaled(bx, 0.95), bj);
        CAPTURE(z, z_dark);
        CHECK(z < 4.5);
        CHECK(z_dark > 4.5);  // power: 5% too dark is seen
    }
}

TEST_CASE("mitsuba: the published scenes load (with --lenient for the missing meshes) and render without NaN",
          "[mitsuba][shared]") {
    // The classroom is lit by a sunsky alone: an environment.
    if (const std::string classroom = gdr::test::public_scene("mitsuba/classroom/scene.xml"); !classroom.empty())
        CHECK(load_scene_file(classroom, lenient()).scene->environment() != nullptr);
    for (const char* s : {"living-room", "spaceship"}) {
        INFO(s);
        GDR_PUBLIC_SCENE_OR_SKIP(path, std::string("mitsuba/") + s + "/scene.xml");
        // The spaceship lacks two meshes (MISSING.txt): it needs --lenient.
        // The living room's envmap and the spaceship's constant environment are gdr's.
        const bool living = std::string(s) == "living-room";
        if (!living)
            CHECK_THROWS_WITH(load_scene_file(path), Catch::Contains("not supported") || Catch::Contains("file not found"));
        const SceneFile sf = at_res(path, 32, 18, living ? SceneFileOptions{} : lenient());
        CHECK(sf.scene->mesh().size() > 100000);
        CHECK(sf.scene->environment() != nullptr);
        Params p;
        p.set("max_depth", 8LL);
        auto integ = integrator_registry().create("pt", p);
        RenderSettings st;
        st.spp = 2;
        FrameBuffer fb;
        const RenderStats rs = integ->render(*sf.scene, st, fb);
        CHECK(rs.nonfinite == 0);
        const Image& albedo = fb.get("albedo");
        double sum = 0.0;
        for (float v : albedo.values()) sum += v;
        CHECK(sum > 0.0);  // geometry and materials are there, even where no light reaches
    }
    // The living room's leaves are cut out of their quads by the mask.
    const SceneFile lr = load_scene_file(public_scene("mitsuba/living-room/scene.xml"), lenient());
    CHECK(std::any_of(lr.scene->materials().begin(), lr.scene->materials().end(),
                      [](const Material& m) { return m.opacity != nullptr; }));
}
