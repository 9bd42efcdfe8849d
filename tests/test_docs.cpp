// The examples of the README and the manual (docs/) are tests: the blocks
// marked `<!-- test: NAME -->` are written to a temporary folder under NAME
// and used as the text says. Also the two conveniences a first scene relies
// on: an OBJ without an MTL takes its materials from the scene file, and
// "$GDR_SCENES/..." paths find the larger public scenes.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"

using namespace gdr;
using namespace gdr::test;

namespace {

// The blocks of `markdown` (a file of the repository) marked by a line
// `<!-- test: NAME -->` right before their opening fence, by NAME.
std::map<std::string, std::string> marked_blocks(const std::string& markdown) {
    std::ifstream in(std::string(GDR_SOURCE_DIR) + "/" + markdown);
    REQUIRE(in);
    std::map<std::string, std::string> blocks;
    std::string line, name;
    const std::string mark = "<!-- test: ";
    while (std::getline(in, line)) {
        if (line.rfind(mark, 0) == 0) {
            name = line.substr(mark.size(), line.find(" -->") - mark.size());
            continue;
        }
        if (!name.empty() && line.rfind("```", 0) == 0) {
            std::string body;
            while (std::getline(in, line) && line.rfind("```", 0) != 0) body += line + "\n";
            blocks[name] = body;
        }
        name.clear();
    }
    return blocks;
}

// The material of `sf` named `name`.
const Material& material(const SceneFile& sf, const std::string& name) {
    for (const Material& m : sf.scene->materials())
        if (m.name == name) return m;
    FAIL("no material " << name);
    throw;
}

// Sets an environment variable for the lifetime of the object, then restores it.
struct ScopedEnv {
    std::string name, old;
    bool had;
    ScopedEnv(const std::string& n, const std::string& value) : name(n) {
        const char* o = std::getenv(n.c_str());
        had = o != nullptr, old = o ? o : "";
        setenv(n.c_str(), value.c_str(), 1);
    }
    ~ScopedEnv() { had ? setenv(name.c_str(), old.c_str(), 1) : unsetenv(name.c_str()); }
};

}  // namespace

TEST_CASE("docs: the first scene of the README and docs/scenes.md loads without an MTL and renders", "[docs][scene]") {
    // Before an OBJ without a library could take its materials from the
    // scene file, this failed with "first.obj: material [ 'floor' ] not
    // found in .mtl" (the wrong variant: load_obj_impl without
    // library_of_overrides).
    for (const char* doc : {"README.md", "docs/scenes.md"}) {
        INFO(doc);
        const auto blocks = marked_blocks(doc);
        REQUIRE(blocks.count("first.obj"));
        REQUIRE(blocks.count("first.json"));
        OutDir dir("first-scene");
        for (const auto& [name, text] : blocks) std::ofstream(dir(name)) << text;
        SceneFile sf = load_scene_file(dir("first.json"));
        // The override's colour and emission, on a material no MTL defines.
        const Material& floor = material(sf, "floor");
        const Color a = floor.bsdf->albedo(Vec2(0.5f));
        CHECK(a.r == Approx(0.8f));
        CHECK(a.g == Approx(0.3f));
        CHECK(a.b == Approx(0.2f));
        CHECK(floor.emission == Color(0.f));
        const Material& light = material(sf, "light");
        CHECK(light.emission == Color(5.f));
        // Lit: the floor under the light is seen, with no NaN.
        set_resolution(sf, 32, 24);
        Params p;
        auto integ = integrator_registry().create("gpt", p);
        RenderSettings st;
        st.spp = 4;
        FrameBuffer fb;
        const RenderStats rs = integ->render(*sf.scene, st, fb);
        CHECK(rs.nonfinite == 0);
        double red = 0.0, blue = 0.0;
        const Image& c = fb.get("color");
        for (int y = 0; y < c.height(); ++y)
            for (int x = 0; x < c.width(); ++x) red += c.at(x, y, 0), blue += c.at(x, y, 2);
        CHECK(red > 0.0);
        CHECK(red > 2.0 * blue);  // the floor's kd, not the grey of a missing material
        if (std::string(doc) != "README.md") continue;
        // The README's Mitsuba XML of the same scene renders the same image in expectation:
        // block means of the two agree (a 5% darker light would be seen at 16 x 12 blocks).
        REQUIRE(blocks.count("first.xml"));
        SceneFile xml = load_scene_file(dir("first.xml"));
        set_resolution(xml, 32, 24);
        Params pp;
        pp.set("max_depth", 8LL);
        const auto mean = [&](const SceneFile& s) {
            auto pt = integrator_registry().create("pt", pp);
            RenderSettings rs;
            rs.spp = 256;
            rs.seed = 3;
            FrameBuffer out;
            pt->render(*s.scene, rs, out);
            double sum = 0.0;
            for (float v : out.get("color").values()) sum += v;
            return sum / double(out.get("color").values().size());
        };
        const double mj = mean(sf), mx = mean(xml);
        CAPTURE(mj, mx);
        CHECK(mx == Approx(mj).epsilon(0.03));
    }
}

TEST_CASE("scene files: an OBJ without an MTL takes only the materials the scene file names", "[scene]") {
    OutDir dir("no-mtl");
    std::ofstream(dir("two.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl a\nf 1 2 3\nusemtl b\nf 1 3 4\n";
    const auto scene = [&](const std::string& materials) {
        std::ofstream(dir("s.json")) << R"({"camera": {"position": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0],
            "fov": 40, "width": 8, "height": 8}, "meshes": ["two.obj"], "materials": {)" + materials + "}}";
        return dir("s.json");
    };
    // Both named: both taken, the unnamed keys grey diffuse.
    const SceneFile sf = load_scene_file(scene(R"("a": {"kd": [0.1, 0.2, 0.3]}, "b": {"ke": [1, 2, 3]})"));
    CHECK(material(sf, "a").bsdf->albedo(Vec2(0.f)).b == Approx(0.3f));
    CHECK(material(sf, "b").emission == Color(1.f, 2.f, 3.f));
    CHECK(material(sf, "b").bsdf->albedo(Vec2(0.f)).r == Approx(0.5f));
    // One missing: an error naming the OBJ, the material and what to do.
    try {
        load_scene_file(scene(R"("a": {"kd": [0.1, 0.2, 0.3]})"));
        FAIL("a material neither in an MTL nor in the scene file was accepted");
    } catch (const InputError& e) {
        const std::string m = e.what();
        CHECK(m.find("two.obj") != std::string::npos);
        CHECK(m.find("'b'") != std::string::npos);
        CHECK(m.find("\"materials\"") != std::string::npos);
    }
}

TEST_CASE("scene files: $GDR_SCENES/ paths are found in scenes_dir(), and an absent one says how to get it", "[scene]") {
    OutDir dir("gdr-scenes");
    std::filesystem::create_directories(dir("public/box"));
    std::ofstream(dir("public/box/tri.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    std::ofstream(dir("s.json")) << R"({"camera": {"position": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0],
        "fov": 40, "width": 8, "height": 8}, "meshes": [{"file": "$GDR_SCENES/box/tri.obj"}]})";
    {
        const ScopedEnv env("GDR_SCENES", dir("public"));
        CHECK(scenes_dir() == dir("public"));
        CHECK(load_scene_file(dir("s.json")).scene->mesh().size() == 1);
    }
    const ScopedEnv env("GDR_SCENES", dir("nowhere"));
    CHECK_THROWS_WITH(load_scene_file(dir("s.json")),
                      Catch::Contains("meshes[0].file") && Catch::Contains("GDR_SCENES") &&
                          Catch::Contains(dir("nowhere")) && Catch::Contains("docs/scenes.md"));
}
