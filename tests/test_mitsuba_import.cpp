// The Mitsuba importer's report and its shapes: strict mode lists every
// unsupported element at once, --lenient groups repeated warnings, a load
// that drops every shape or every emitter is an error in both modes, a file
// named in another case is found, the scene's integrator keeps its path
// length and notes the rest; cylinders, shapegroups and instances; and every
// shared Mitsuba scene and randomised variant loads strictly unless it lacks
// a file of its source, and renders without NaN.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <fmt/core.h>

#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"
#include "gdr/io/exr.h"
#include "gdr/io/mitsuba_xml.h"
#include "gdr/io/png.h"
#include "public_scenes.h"

using namespace gdr;
using namespace gdr::test;

namespace {

const std::string kSensor = R"(
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
  </sensor>)";

struct XmlScene {
    OutDir dir{"mitsuba-import"};
    std::string write(const std::string& name, const std::string& text) const {
        std::ofstream(dir(name), std::ios::binary) << text;
        return dir(name);
    }
    // The sensor takes lines 1 to 5: `body` starts on line 6.
    std::string path(const std::string& body) const {
        return write("scene.xml", "<scene version=\"0.6.0\">" + kSensor + "\n" + body + "\n</scene>\n");
    }
    SceneFile load(const std::string& body, bool lenient = false) const {
        SceneFileOptions o;
        o.lenient = lenient;
        return load_mitsuba_scene(path(body), o);
    }
    std::string error(const std::string& body, bool lenient = false) const {
        try {
            load(body, lenient);
        } catch (const InputError& e) {
            return e.what();
        }
        return "";
    }
};

const std::string kRect = R"(<shape type="rectangle"><emitter type="area"/></shape>)";

size_t count_of(const std::string& s, const std::string& what) {
    size_t n = 0;
    for (size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + 1)) ++n;
    return n;
}

}  // namespace

TEST_CASE("mitsuba import: strict mode lists every unsupported element at once", "[mitsuba][errors]") {
    XmlScene s;
    const std::string body = R"(<shape type="hair" id="fur"/>
<shape type="rectangle"><bsdf type="hanrahan" id="skin"/></shape>
<shape type="rectangle"><bsdf type="diffuse" id="d"><float name="sheen" value="1"/></bsdf></shape>
<emitter type="projector" id="sky"/>
)" + kRect;
    const std::string e = s.error(body);
    const std::string file = s.dir("scene.xml");
    CAPTURE(e);
    CHECK_THAT(e, Catch::StartsWith(file + ": 4 unsupported elements and properties"));
    CHECK_THAT(e, Catch::Contains(file + ":6: <shape type=\"hair\" id=\"fur\">: unsupported shape type 'hair'"));
    CHECK_THAT(e, Catch::Contains(file + ":7: <bsdf type=\"hanrahan\" id=\"skin\">") && Catch::Contains("'hanrahan'"));
    CHECK_THAT(e, Catch::Contains(file + ":8: <float name=\"sheen\">") && Catch::Contains("unsupported property 'sheen'"));
    CHECK_THAT(e, Catch::Contains(file + ":9: <emitter type=\"projector\" id=\"sky\">"));
    // Each says what --lenient would do instead, which it then does.
    CHECK(count_of(e, "--lenient") == 5);  // the heading and the four
    const SceneFile l = s.load(body, true);
    CHECK(l.warnings.size() == 4);
    CHECK(l.scene->mesh().size() == 6);
    // An error that stops the load still names the unsupported elements before it.
    CHECK_THAT(s.error(R"(<shape type="hair" id="fur"/>
<shape type="rectangle"><transform name="toWorld"><matrix value="1 2 3"/></transform></shape>)"),
               Catch::Contains(":7: <matrix>") && Catch::Contains("16 numbers") && Catch::Contains("before it:") &&
                   Catch::Contains(":6: <shape type=\"hair\" id=\"fur\">"));
}

TEST_CASE("mitsuba import: --lenient groups a repeated warning with its count", "[mitsuba][errors]") {
    XmlScene s;
    std::string body = kRect;
    for (int i = 0; i < 12; ++i) body += fmt::format("\n<shape type=\"rectangle\"><bsdf type=\"hanrahan\" id=\"b{}\"/></shape>", i);
    const SceneFile l = s.load(body, true);
    REQUIRE(l.warnings.size() == 1);
    const std::string& w = l.warnings[0];
    CAPTURE(w);
    // The first place in full, the count, 8 more places as file:line, and how many are left.
    CHECK_THAT(w, Catch::Contains(":7: <bsdf type=\"hanrahan\" id=\"b0\">") && Catch::Contains("[12 times; also at ") &&
                      Catch::Contains("scene.xml:9, ") && Catch::Contains(", and 3 more]"));
    // Strictly, every one of the 12 is listed.
    const std::string e = s.error(body);
    CHECK(count_of(e, "<bsdf type=\"hanrahan\"") == 12);
}

TEST_CASE("mitsuba import: dropping every shape or every emitter is an error in both modes", "[mitsuba][errors]") {
    XmlScene s;
    for (bool lenient : {false, true}) {
        INFO("lenient " << lenient);
        const std::string shapes = s.error(R"(<shape type="hair"/><shape type="hair"/>)", lenient);
        CHECK_THAT(shapes, Catch::Contains("unsupported shape type 'hair'"));
        if (lenient) CHECK_THAT(shapes, Catch::Contains("every shape was dropped (2 <shape> elements)"));
        const std::string lights = s.error(R"(<emitter type="projector"/><shape type="rectangle"/>)", lenient);
        CHECK_THAT(lights, Catch::Contains("emitter type 'projector'"));
        if (lenient) CHECK_THAT(lights, Catch::Contains("every emitter was dropped (1 <emitter> element)"));
    }
    // An emitter dropped with its shape counts too.
    CHECK_THAT(s.error(R"(<shape type="hair"><emitter type="area"/></shape><shape type="rectangle"/>)", true),
               Catch::Contains("every emitter was dropped (1 <emitter> element)"));
    // A scene that declares no emitter at all is the author's choice: it loads.
    CHECK_NOTHROW(s.load(R"(<shape type="rectangle"/>)"));
    // One light of two dropped is a warning only.
    const SceneFile l = s.load(R"(<emitter type="projector"/>)" + kRect, true);
    CHECK(l.scene->has_lights());
}

TEST_CASE("mitsuba import: a file named in another case than on disk is used with a warning", "[mitsuba]") {
    XmlScene s;
    std::filesystem::create_directories(s.dir("Meshes"));
    s.write("Meshes/Tri.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const SceneFile sf = s.load(R"(<shape type="obj"><string name="filename" value="meshes\tri.obj"/></shape>)");
    CHECK(sf.scene->mesh().size() == 1);
    REQUIRE(sf.warnings.size() == 1);
    CHECK_THAT(sf.warnings[0], Catch::Contains("is not on disk with this case; using") && Catch::Contains("Meshes/Tri.OBJ"));
    // No file of any case: still "file not found".
    CHECK_THAT(s.error(R"(<shape type="obj"><string name="filename" value="meshes/quad.obj"/></shape>)"),
               Catch::Contains("quad.obj: file not found"));
}

TEST_CASE("mitsuba import: the scene's integrator keeps max_depth and rr_depth and notes the rest", "[mitsuba]") {
    XmlScene s;
    // The shared scenes' integrator with -D method=path: dualBuffer and the photon mapper's settings do not apply.
    const std::string gpm = R"(<integrator type="path"><integer name="maxDepth" value="10"/>
        <integer name="photonCount" value="100000"/><boolean name="dualBuffer" value="false"/></integrator>)";
    const SceneFile p = s.load(gpm + kRect);
    CHECK(p.defaults.integrator == "pt");
    CHECK(p.defaults.params.get_int("max_depth", -99) == 10);
    REQUIRE(p.warnings.size() == 1);
    CHECK_THAT(p.warnings[0], Catch::Contains("dual_buffer, photon_count do not apply"));
    // A wrapper passes on its nested integrator's path length.
    const SceneFile a = s.load(R"(<integrator type="adaptive"><float name="maxError" value="0.05"/>
        <integrator type="bdpt"><integer name="maxDepth" value="7"/><integer name="rrDepth" value="3"/></integrator></integrator>)" +
                               kRect);
    CHECK(a.defaults.integrator == "bdpt");
    CHECK(a.defaults.params.get_int("max_depth", -99) == 7);
    CHECK(a.defaults.params.get_int("rr_depth", -99) == 3);
    CHECK(a.warnings.size() == 1);
    // What changes the image stays an error.
    CHECK_THAT(s.error(R"(<integrator type="path"><boolean name="hideEmitters" value="true"/></integrator>)" + kRect),
               Catch::Contains("hide_emitters"));
}

TEST_CASE("mitsuba import: cylinders lie on their surface, face outwards and have its area", "[mitsuba]") {
    XmlScene s;
    const SceneFile sf = s.load(R"(<shape type="cylinder"><point name="p0" x="1" y="0" z="0"/><point name="p1" x="1" y="0" z="3"/>
        <float name="radius" value="0.5"/><transform name="toWorld"><translate y="2"/></transform></shape>)");
    const TriangleMesh& m = sf.scene->mesh();
    REQUIRE(m.size() == 256);
    double area = 0.0;
    for (size_t t = 0; t < m.size(); ++t) {
        const Vec3 a = m.positions[3 * t], b = m.positions[3 * t + 1], c = m.positions[3 * t + 2];
        const Vec3 g = glm::cross(b - a, c - a);
        area += 0.5 * double(glm::length(g));
        for (int k = 0; k < 3; ++k) {
            const Vec3 q = m.positions[3 * t + k];
            const Vec3 radial = Vec3(q.x - 1.f, q.y - 2.f, 0.f);
            CHECK(glm::length(radial) == Approx(0.5f).margin(1e-5));
            CHECK((q.z > -1e-5f && q.z < 3.f + 1e-5f));
            // The vertex normal is the exact radial direction; the face faces the same way.
            CHECK(glm::length(glm::normalize(m.normals[3 * t + k]) - radial / 0.5f) < 1e-4f);
            CHECK(glm::dot(g, radial) > 0.f);
        }
    }
    // The inscribed prism's area: 2 pi r h sin(pi/128)/(pi/128), within 1e-4 of the true one.
    // (Wound inwards, the cylinder failed the facing check above on all 768 corners.)
    CHECK(area == Approx(2.0 * 3.14159265358979 * 0.5 * 3.0).epsilon(1e-3));
}

TEST_CASE("mitsuba import: a shapegroup renders where its instances place it", "[mitsuba]") {
    XmlScene s;
    const std::string group = R"(<shape type="shapegroup" id="g">
        <shape type="rectangle"><transform name="toWorld"><scale value="0.5"/></transform></shape>
        <shape type="cube"><transform name="toWorld"><scale value="0.1"/><translate z="1"/></transform></shape></shape>)";
    const auto inst = [](float x) {
        return fmt::format(R"(<shape type="instance"><ref id="g"/><transform name="toWorld"><translate x="{}"/></transform></shape>)", x);
    };
    const SceneFile sf = s.load(group + inst(-2.f) + inst(3.f));
    const TriangleMesh& m = sf.scene->mesh();
    REQUIRE(m.size() == 2 * (2 + 12));
    // The first instance's rectangle spans x in [-2.5, -1.5], its cube is at z = 1 around x = -2.
    CHECK(m.positions[0].x == Approx(-2.5f));
    CHECK(m.positions[2 * 3].z == Approx(0.9f).margin(1e-5));
    CHECK(m.positions[14 * 3].x == Approx(2.5f));
    // The group alone renders nothing; an instance must refer to a shapegroup.
    CHECK_THAT(s.error(group), Catch::Contains("the scene has no shapes"));
    CHECK_THAT(s.error(group + R"(<bsdf type="diffuse" id="d"/><shape type="instance"><ref id="d"/></shape>)"),
               Catch::Contains("not a <shape type=\"shapegroup\">"));
}

TEST_CASE("mitsuba import: every shared Mitsuba scene and variant whose files are complete loads strictly and renders "
          "without NaN",
          "[mitsuba][shared]") {
    namespace fs = std::filesystem;
    GDR_PUBLIC_SCENE_OR_SKIP(kSharedMitsuba, "mitsuba");
    // Every scene.xml and every randomised variant (*_rand_scene*.xml) of every folder.
    std::vector<fs::path> files;
    for (const auto& d : fs::directory_iterator(kSharedMitsuba)) {
        if (!d.is_directory()) continue;
        for (const auto& f : fs::directory_iterator(d.path())) {
            const std::string name = f.path().filename().string();
            if (name == "scene.xml" || (name.find("_rand_scene") != std::string::npos && f.path().extension() == ".xml"))
                files.push_back(f.path());
        }
    }
    std::sort(files.begin(), files.end());
    REQUIRE(files.size() >= 11);
    // With --lenient, what a strict load rejects becomes a warning ending in
    // "(--lenient)". The only ones allowed: files missing from the scenes'
    // source.
    const auto lenient_only = [](const SceneFile& sf) {
        std::vector<std::string> w;
        for (const std::string& s : sf.warnings)
            if (s.find("(--lenient)") != std::string::npos) w.push_back(s);
        return w;
    };
    size_t strict = 0, missing = 0;
    std::set<std::string> strict_scenes;
    for (const fs::path& path : files) {
        const std::string rel = path.parent_path().filename().string() + "/" + path.filename().string();
        INFO(rel);
        SceneFileOptions o;
        o.lenient = true;
        SceneFile sf = load_mitsuba_scene(path.string(), o);
        const std::vector<std::string> dropped = lenient_only(sf);
        bool lacks_file = false;
        for (const std::string& w : dropped) {
            INFO(w);
            const bool file = w.find("file not found") != std::string::npos;
            CHECK(file);
            lacks_file |= file;
        }
        strict += dropped.empty();
        if (dropped.empty() && path.filename() == "scene.xml") strict_scenes.insert(path.parent_path().filename().string());
        missing += lacks_file;
        // The scenes themselves: the strict load agrees with the lenient one's
        // warnings, and a failure names the file and line.
        if (path.filename() == "scene.xml") {
            SceneFileOptions so;
            if (dropped.empty()) {
                CHECK_NOTHROW(load_mitsuba_scene(path.string(), so));
            } else {
                CHECK_THROWS_WITH(load_mitsuba_scene(path.string(), so),
                                  Catch::Contains(path.string() + ":") && Catch::Contains("file not found"));
            }
        }
        set_resolution(sf, 16, 12);
        Params p;
        p.set("max_depth", 6LL);
        auto integ = integrator_registry().create("pt", p);
        RenderSettings st;
        st.spp = 1;
        FrameBuffer fb;
        const RenderStats rs = integ->render(*sf.scene, st, fb);
        CHECK(rs.nonfinite == 0);
        bool finite = true;
        for (float v : fb.get("color").values()) finite &= std::isfinite(v);
        CHECK(finite);
    }
    // Of the eleven scenes, all but the two with meshes missing from their
    // source (spaceship, water) load strictly.
    for (const char* name : {"box", "classroom", "dining-room", "living-room", "sponza", "torus", "veach-bidir",
                             "veach-lamp"}) {
        INFO(name);
        if (fs::exists(kSharedMitsuba + "/" + name + "/scene.xml")) CHECK(strict_scenes.count(name) == 1);
    }
    WARN(fmt::format("shared Mitsuba scenes: {} files, {} load strictly, {} lack a file of the source", files.size(),
                     strict, missing));
}

TEST_CASE("mitsuba import: an envmap reads Radiance .hdr as linear and 8-bit files by their gamma", "[mitsuba][environment]") {
    XmlScene s;
    // A uniform 8 x 4 Radiance file of (0.5, 0.25, 1): RGBE bytes (64, 32, 128, 129), flat (unencoded) scanlines.
    {
        std::ofstream f(s.dir("sky.hdr"), std::ios::binary);
        f << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n";
        for (int i = 0; i < 32; ++i) f << char(64) << char(32) << char(128) << char(129);
    }
    // A uniform 8-bit PNG of the sRGB encoding of linear (0.2, 0.5, 0.8).
    Image png(8, 4, 3);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 8; ++x) png.set_rgb(x, y, Color(0.2f, 0.5f, 0.8f));
    write_png_preview(s.dir("sky.png"), png);
    const std::vector<uint8_t> b = preview_bytes(png);
    const auto env = [&](const std::string& file, const std::string& extra) {
        const SceneFile sf = s.load(R"(<shape type="rectangle"/><emitter type="envmap"><string name="filename" value=")" + file +
                                    R"("/><float name="scale" value="2"/>)" + extra + "</emitter>");
        REQUIRE(sf.scene->environment());
        return sf.scene->environment()->eval(glm::normalize(Vec3(0.3f, 0.5f, -0.8f)));
    };
    CHECK(env("sky.hdr", "") == Color(1.f, 0.5f, 2.f));
    // 8-bit: sRGB by default (as Mitsuba), linear with gamma 1, a power law otherwise.
    for (int k = 0; k < 3; ++k) {
        CAPTURE(k);
        const float v = float(b[size_t(k)]) / 255.f;
        CHECK(env("sky.png", "")[k] == Approx(2.f * srgb_to_linear(v)).epsilon(1e-5));
        CHECK(env("sky.png", R"(<float name="gamma" value="1"/>)")[k] == Approx(2.f * v).epsilon(1e-5));
        CHECK(env("sky.png", R"(<float name="gamma" value="2.2"/>)")[k] == Approx(2.f * std::pow(v, 2.2f)).epsilon(1e-5));
    }
    CHECK(env("sky.png", "")[1] == Approx(1.f).epsilon(0.02));  // the decoded PNG is the linear 0.5 it encodes, times 2
    CHECK_THAT(s.error(R"(<shape type="rectangle"/><emitter type="envmap"><string name="filename" value="sky.png"/>
                          <float name="gamma" value="0"/></emitter>)"),
               Catch::Contains("scene.xml:7") && Catch::Contains("gamma must be positive"));
}

TEST_CASE("mitsuba import: an EXR bitmap is a linear texture oriented as an 8-bit one", "[mitsuba][texture]") {
    XmlScene s;
    // Four different texels; the PNG holds them as bytes read linearly (gamma 1), the EXR as those values.
    Image img(2, 2, 3);
    const Color c[4] = {Color(0.2f, 0.4f, 0.6f), Color(0.8f, 0.1f, 0.3f), Color(0.5f, 0.9f, 0.05f), Color(0.3f, 0.3f, 0.7f)};
    for (int k = 0; k < 4; ++k) img.set_rgb(k % 2, k / 2, c[k]);
    write_png_preview(s.dir("t.png"), img);
    const std::vector<uint8_t> b = preview_bytes(img);
    Image lin(2, 2, 3);
    for (int k = 0; k < 4; ++k)
        lin.set_rgb(k % 2, k / 2, Color(b[size_t(3 * k)], b[size_t(3 * k + 1)], b[size_t(3 * k + 2)]) / 255.f);
    write_exr_image(s.dir("t.exr"), lin);
    const auto kd = [&](const std::string& file, const std::string& extra, const Vec2& uv) {
        const SceneFile sf = s.load(R"(<shape type="rectangle"><emitter type="area"/></shape><shape type="cube"><bsdf type="diffuse">
            <texture type="bitmap" name="reflectance"><string name="filename" value=")" + file + R"("/>
            <string name="filter_type" value="nearest"/>)" + extra + "</texture></bsdf></shape>");
        const Material& m = sf.scene->materials().at(sf.scene->mesh().material_ids.back());
        return m.bsdf->eval(Vec3(0.f, 0.f, 1.f), Vec3(0.f, 0.f, 1.f), uv) * kPi;
    };
    for (const Vec2 uv : {Vec2(0.25f, 0.25f), Vec2(0.75f, 0.25f), Vec2(0.25f, 0.75f), Vec2(0.75f, 0.75f)}) {
        CAPTURE(uv.x, uv.y);
        const Color e = kd("t.exr", "", uv), p = kd("t.png", R"(<float name="gamma" value="1"/>)", uv);
        for (int k = 0; k < 3; ++k) CHECK(e[k] == Approx(p[k]).epsilon(1e-3));
    }
    // Mitsuba's uv (0.25, 0.25) is the image's top-left texel.
    CHECK(kd("t.exr", "", Vec2(0.25f, 0.75f)).g == Approx(float(b[1]) / 255.f).epsilon(1e-3));
    // Its gamma cannot apply to linear floats: a warning; an EXR opacity map is unsupported.
    const SceneFile g = s.load(R"(<shape type="rectangle"><bsdf type="diffuse"><texture type="bitmap" name="reflectance">
        <string name="filename" value="t.exr"/><float name="gamma" value="2.2"/></texture></bsdf><emitter type="area"/></shape>)");
    CHECK(std::any_of(g.warnings.begin(), g.warnings.end(),
                      [](const std::string& w) { return w.find("gamma 2.2 is ignored") != std::string::npos; }));
    CHECK_THAT(s.error(R"(<shape type="rectangle"><bsdf type="mask"><texture type="bitmap" name="opacity">
        <string name="filename" value="t.exr"/></texture><bsdf type="diffuse"/></bsdf><emitter type="area"/></shape>)"),
               Catch::Contains("scene.xml:6") && Catch::Contains("EXR opacity map"));
}

TEST_CASE("mitsuba import: subsurface scattering is an error naming it, and --lenient renders the shape without it",
          "[mitsuba][errors]") {
    XmlScene s;
    const std::string body = kRect + "\n" + R"(<shape type="sphere"><subsurface type="dipole"/></shape>)" + "\n" +
                             R"(<subsurface type="dipole" id="skin"/>)";
    const std::string e = s.error(body);
    CHECK_THAT(e, Catch::Contains("scene.xml:7: <subsurface type=\"dipole\">") &&
                      Catch::Contains("scene.xml:8: <subsurface type=\"dipole\" id=\"skin\">") && Catch::Contains("--lenient"));
    const SceneFile l = s.load(body, true);
    CHECK(l.scene->mesh().size() > 2);  // the sphere is there
}

TEST_CASE("mitsuba import: the sky's stretch and extend light the directions below the horizon", "[mitsuba][sky]") {
    XmlScene s;
    const auto sky = [](const std::string& props) {
        return "<shape type=\"rectangle\"/>\n<emitter type=\"sky\" id=\"daylight\"><integer name=\"resolution\" value=\"16\"/>" +
               props + "</emitter>";
    };
    const Vec3 below = glm::normalize(Vec3(0.3f, -0.2f, 0.5f));  // 11.5 degrees under the horizon
    const SceneFile plain = s.load(sky(R"(<float name="stretch" value="1"/><boolean name="extend" value="false"/>)"));
    CHECK(plain.warnings.empty());
    CHECK(luminance(plain.scene->environment()->eval(below)) == 0.f);
    // Stretched by 1.5 the sky reaches 135 degrees from the zenith; extended it reaches the nadir.
    const SceneFile stretched = s.load(sky(R"(<float name="stretch" value="1.5"/>)"));
    CHECK(stretched.warnings.empty());
    CHECK(luminance(stretched.scene->environment()->eval(below)) > 0.f);
    CHECK(luminance(stretched.scene->environment()->eval(Vec3(0.f, -1.f, 0.f))) == 0.f);
    const SceneFile extended = s.load(sky(R"(<boolean name="extend" value="true"/>)"));
    CHECK(luminance(extended.scene->environment()->eval(below)) > 0.f);
    // Out of Mitsuba's range [1, 2]: an error naming line and element.
    CHECK_THAT(s.error(sky(R"(<float name="stretch" value="2.5"/>)")),
               Catch::Contains("scene.xml:7: <emitter type=\"sky\" id=\"daylight\">") && Catch::Contains("'stretch' 2.5"));
}

TEST_CASE("mitsuba import: a mirroring sensor to_world shows the world mirrored", "[mitsuba]") {
    XmlScene s;
    // An asymmetric scene: an emitting rectangle right of the axis, a cube above it.
    const std::string body = R"(<shape type="rectangle"><transform name="toWorld"><scale value="0.3"/><translate x="1" y="0.2"/></transform>
        <emitter type="area"/></shape>
        <shape type="cube"><transform name="toWorld"><scale value="0.2"/><translate x="0.5" y="1"/></transform></shape>)";
    const auto at = [&](const std::string& transform) {
        return s.write("m.xml", "<scene version=\"0.6.0\"><sensor type=\"perspective\"><transform name=\"toWorld\">" + transform +
                                    R"(</transform><film type="hdrfilm"><integer name="width" value="40"/>
            <integer name="height" value="30"/></film></sensor>)" + body + "</scene>");
    };
    const std::string look = R"(<lookat origin="0.37, 0.1, 5" target="0.2, 0.3, 0" up="0.1, 1, 0"/>)";
    const SceneFile plain = load_mitsuba_scene(at(look), {});
    const SceneFile mirrored = load_mitsuba_scene(at("<scale x=\"-1\"/>" + look), {});
    REQUIRE(plain.scene->mesh().size() == mirrored.scene->mesh().size());
    const Camera& a = plain.scene->camera();
    const Camera& b = mirrored.scene->camera();
    // Every corner lands at the mirror image (x -> width - x) of where it lands
    // unmirrored, and each triangle keeps its front towards the same side.
    for (size_t t = 0; t < plain.scene->mesh().size(); ++t) {
        const auto& pa = plain.scene->mesh().positions;
        const auto& pb = mirrored.scene->mesh().positions;
        const int perm[3] = {0, 2, 1};  // the mirrored triangle's corners 1 and 2 are swapped
        for (int k = 0; k < 3; ++k) {
            Vec2 fa, fb;
            REQUIRE(a.project(pa[3 * t + k], fa));
            REQUIRE(b.project(pb[3 * t + perm[k]], fb));
            CHECK(fb.x == Approx(40.f - fa.x).margin(1e-3));
            CHECK(fb.y == Approx(fa.y).margin(1e-3));
        }
        const auto facing = [](const std::vector<Vec3>& p, size_t tri, const Vec3& eye) {
            return glm::dot(glm::cross(p[3 * tri + 1] - p[3 * tri], p[3 * tri + 2] - p[3 * tri]), eye - p[3 * tri]) > 0.f;
        };
        CHECK(facing(pa, t, Vec3(0.37f, 0.1f, 5.f)) == facing(pb, t, Vec3(0.37f, 0.1f, 5.f)));
    }
}

TEST_CASE("mitsuba import: max_smooth_angle on an OBJ mesh makes creases sharper than the angle", "[mitsuba]") {
    XmlScene s;
    std::string obj;
    for (int i = 0; i < 8; ++i) obj += fmt::format("v {} {} {}\n", i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1);
    // A cube of 8 shared vertices wound outwards, without normals.
    obj += "f 1 3 4\nf 1 4 2\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\nf 3 7 8\nf 3 8 4\nf 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\n";
    s.write("cube.obj", obj);
    const auto load = [&](const std::string& extra) {
        return s.load(R"(<shape type="obj"><string name="filename" value="cube.obj"/>)" + extra + "</shape>");
    };
    const auto all_faceted = [](const TriangleMesh& m) {
        for (size_t t = 0; t < m.size(); ++t) {
            const Vec3 g = glm::normalize(glm::cross(m.positions[3 * t + 1] - m.positions[3 * t], m.positions[3 * t + 2] - m.positions[3 * t]));
            for (int k = 0; k < 3; ++k)
                if (glm::length(glm::normalize(m.normals[3 * t + k]) - g) > 1e-5f) return false;
        }
        return true;
    };
    CHECK(all_faceted(load(R"(<float name="maxSmoothAngle" value="30"/>)").scene->mesh()));
    // The cube's edges are 90 degrees: at 100 every corner is smooth again; without the property too.
    CHECK_FALSE(all_faceted(load(R"(<float name="maxSmoothAngle" value="100"/>)").scene->mesh()));
    // Without it, Mitsuba's angle-weighted normals: a cube's corners point along its diagonals
    // (weighting by area instead tilts the corners shared by two triangles of a face).
    const SceneFile plain = load("");
    CHECK_FALSE(all_faceted(plain.scene->mesh()));
    for (size_t c = 0; c < 36; ++c)
        CHECK(glm::length(glm::normalize(plain.scene->mesh().normals[c]) -
                          glm::sign(plain.scene->mesh().positions[c]) / std::sqrt(3.f)) < 1e-5f);
    // A uv seam splits the normals, as Mitsuba's OBJ vertices are (position, uv) pairs: a
    // roof of two faces at 90 degrees, sharing its ridge's positions but not their uvs.
    s.write("roof.obj", "v -1 0 0\nv 0 1 0\nv 0 1 1\nv -1 0 1\nv 1 0 0\nv 1 0 1\n"
                        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\nvt 0.2 0.2\n"
                        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/1 6/4\nf 2/5 6/4 3/6\n");
    const SceneFile roof = s.load(R"(<shape type="obj"><string name="filename" value="roof.obj"/></shape>)");
    CHECK(all_faceted(roof.scene->mesh()));  // (keyed by position alone, the ridge was smoothed: this failed)
    s.write("roof1.obj", "v -1 0 0\nv 0 1 0\nv 0 1 1\nv -1 0 1\nv 1 0 0\nv 1 0 1\n"
                         "f 1 2 3\nf 1 3 4\nf 2 5 6\nf 2 6 3\n");
    const SceneFile joined = s.load(R"(<shape type="obj"><string name="filename" value="roof1.obj"/></shape>)");
    // Without uvs the ridge's corners are shared: their normal bisects the two faces'.
    CHECK(std::abs(glm::normalize(joined.scene->mesh().normals[1]).y) > 1.f - 1e-5f);
    CHECK_THAT(s.error(R"(<shape type="obj"><string name="filename" value="cube.obj"/><boolean name="faceNormals" value="true"/>
        <float name="maxSmoothAngle" value="30"/></shape>)"),
               Catch::Contains("either face_normals or max_smooth_angle"));
}
