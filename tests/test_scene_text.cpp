// Scenes from JSON text (load_scene_text), as the Python module's load_dict
// gives them: the same scene as the file holding that text, a content hash
// that follows the text, and meshes given by vertex and triangle arrays, whose
// bad entries are errors naming the key.
#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>
#include <string>

#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/mitsuba_xml.h"
#include "gdr/io/scene_file.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

const std::string kSmall = GDR_SOURCE_DIR "/tests/scenes/cornell-small.json";

std::string file_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

// The colour layer of a 2 spp PT render with seed 3.
Image render_pt(const SceneFile& sf) {
    auto pt = integrator_registry().create("pt", Params("test"));
    RenderSettings st;
    st.spp = 2;
    st.seed = 3;
    st.threads = 2;
    FrameBuffer fb;
    pt->render(*sf.scene, st, fb);
    return fb.get("color");
}

// A floor quad and an emitting quad above it, by arrays; `floor` replaces the floor's entry.
std::string quads(const std::string& floor = R"({"vertices": [[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]],
                                                 "triangles": [[0,2,1],[0,3,2]], "material": "floor"})") {
    return R"({"camera": {"position": [0, 1.2, 2.5], "target": [0, 0.3, 0], "up": [0, 1, 0], "fov": 50,
                          "width": 12, "height": 10},
               "meshes": [)" + floor + R"(,
                          {"vertices": [[-0.3,1.5,-0.3],[0.3,1.5,-0.3],[0.3,1.5,0.3],[-0.3,1.5,0.3]],
                           "triangles": [[0,1,2],[0,2,3]], "material": "light"}],
               "materials": {"floor": {"type": "diffuse", "kd": [0.6, 0.5, 0.4]},
                             "light": {"type": "diffuse", "kd": [0, 0, 0], "ke": [8, 8, 8]}}})";
}

}  // namespace

TEST_CASE("a scene from JSON text renders as the file holding that text", "[scene]") {
    const std::string text = file_text(kSmall);
    const SceneFile from_text = load_scene_text(text, kSmall);
    const SceneFile from_file = load_scene_file(kSmall);
    CHECK(from_text.scene->stats().triangles == from_file.scene->stats().triangles);
    const Image a = render_pt(from_text), b = render_pt(from_file);
    REQUIRE(a.values().size() == b.values().size());
    CHECK(a.values() == b.values());
    // The hash follows the text (and the files it names): the same text hashes the same, a changed one not.
    CHECK(load_scene_text(text, kSmall).content_hash == from_text.content_hash);
    std::string moved = text;
    moved.replace(moved.find("\"fov\": 45"), 9, "\"fov\": 46");
    CHECK(load_scene_text(moved, kSmall).content_hash != from_text.content_hash);
    // Relative paths are resolved from the name's directory: elsewhere the OBJ is missing.
    CHECK_THROWS_WITH(load_scene_text(text, "/nonexistent-dir/scene"), Contains("/nonexistent-dir/"));
}

TEST_CASE("meshes given by arrays make triangles with their materials", "[scene]") {
    const SceneFile sf = load_scene_text(quads(), "/tmp/quads");
    CHECK(sf.scene->stats().triangles == 4);
    CHECK(sf.scene->stats().emitters == 2);
    // The lit floor is seen: the image is not black.
    const Image img = render_pt(sf);
    double sum = 0;
    for (float v : img.values()) sum += v;
    CHECK(sum > 0.0);
}

TEST_CASE("bad mesh arrays are errors naming the key", "[scene]") {
    const auto fails_with = [](const std::string& floor, const std::string& what) {
        CHECK_THROWS_AS(load_scene_text(quads(floor), "/tmp/quads"), InputError);
        CHECK_THROWS_WITH(load_scene_text(quads(floor), "/tmp/quads"), Contains(what));
    };
    fails_with(R"({"vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,1,3]], "material": "floor"})",
               "meshes[0].triangles[0]' holds 3, not a vertex index in [0, 2]");
    fails_with(R"({"vertices": [[0,0,0],[1,0],[0,0,1]], "triangles": [[0,1,2]], "material": "floor"})",
               "meshes[0].vertices[1]");
    fails_with(R"({"vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,1]], "material": "floor"})",
               "meshes[0].triangles[0]' must be [i, j, k]");
    fails_with(R"({"vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,1,2]], "material": "steel"})",
               "names 'steel', which 'materials' does not define");
    fails_with(R"({"vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,1,2]], "colour": 1})", "colour");
    fails_with(R"({"vertices": [], "triangles": [[0,1,2]]})", "meshes[0].vertices' must be a non-empty array");
}

namespace {

// `text` with the first `from` replaced by `to` (which must be there).
std::string replaced(std::string text, const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    REQUIRE(at != std::string::npos);
    return text.replace(at, from.size(), to);
}

}  // namespace

TEST_CASE("edits in place render as a fresh load of the edited scene", "[scene]") {
    SceneFile sf = load_scene_text(quads(), "/tmp/quads", true);
    const Scene* before = sf.scene.get();
    const Image original = render_pt(sf);
    edit_material(sf, "floor", R"({"type": "plastic", "kd": [0.2, 0.6, 0.3], "ks": [0.3, 0.3, 0.3], "alpha": 0.15})");
    edit_material(sf, "light", R"({"type": "diffuse", "kd": [0, 0, 0], "ke": [3, 5, 9]})");
    edit_mesh_transform(sf, 1, R"({"translate": [0.1, -0.2, 0.05], "scale": 1.4})");
    edit_environment(sf, R"({"type": "constant", "radiance": [0.1, 0.2, 0.3]})");
    CHECK(sf.scene.get() == before);  // the same Scene, changed
    const MaterialDesc floor = material_description(sf, "floor", R"({"type": "diffuse", "ks": [0.25, 0, 0]})");
    CHECK(floor.ks.r == 0.25f);
    CHECK(floor.kd.g == 0.f);  // an array mesh's material starts from the defaults
    CHECK(floor.pr < 0.f);
    std::string text = replaced(quads(), R"({"type": "diffuse", "kd": [0.6, 0.5, 0.4]})",
                                R"({"type": "plastic", "kd": [0.2, 0.6, 0.3], "ks": [0.3, 0.3, 0.3], "alpha": 0.15})");
    text = replaced(text, R"("ke": [8, 8, 8])", R"("ke": [3, 5, 9])");
    text = replaced(text, R"("material": "light"})",
                    R"("material": "light", "transform": {"translate": [0.1, -0.2, 0.05], "scale": 1.4}})");
    text = replaced(text, R"("materials":)", R"("environment": {"type": "constant", "radiance": [0.1, 0.2, 0.3]},
                                                "materials":)");
    const SceneFile fresh = load_scene_text(text, "/tmp/quads");
    const Image a = render_pt(sf), b = render_pt(fresh);
    REQUIRE(a.values().size() == b.values().size());
    CHECK(a.values() == b.values());
    CHECK(a.values() != original.values());
    CHECK(sf.scene->bounding_radius() == fresh.scene->bounding_radius());
    CHECK(sf.scene->environment_selection() == fresh.scene->environment_selection());
    // The emitting quad, 1.4 times wider, has 1.96 times the area: its density is 1/1.96 of before.
    const SceneFile plain = load_scene_text(quads(), "/tmp/quads");
    const uint32_t light = uint32_t(sf.scene->mesh().size() - 1);
    CHECK(sf.scene->light_pdf_a(light) / (1.f - sf.scene->environment_selection()) ==
          Approx(plain.scene->light_pdf_a(light) / 1.96f).epsilon(1e-5));
}

TEST_CASE("refused edits name the key and leave the scene as it was", "[scene][errors]") {
    SceneFile sf = load_scene_text(quads(), "/tmp/quads", true);
    const Image original = render_pt(sf);
    CHECK_THROWS_WITH(edit_material(sf, "floor", R"({"type": "roughconductor", "alpha": -0.5})"),
                      Contains("materials.floor.alpha"));
    CHECK_THROWS_WITH(edit_material(sf, "floor", R"({"type": "diffuse", "kd": [2, 0, 0]})"),
                      Contains("materials.floor.kd"));
    CHECK_THROWS_WITH(edit_material(sf, "floor", R"({"type": "diffuse", "colour": 1})"), Contains("colour"));
    CHECK_THROWS_WITH(edit_material(sf, "wood", R"({})"), Contains("materials.wood"));
    CHECK_THROWS_AS(edit_mesh_transform(sf, 1, R"({"scale": 0})"), ParameterError);
    CHECK_THROWS_WITH(edit_mesh_transform(sf, 1, R"({"scale": 0})"), Contains("meshes[1].transform"));
    CHECK_THROWS_WITH(edit_mesh_transform(sf, 1, R"({"spin": 3})"), Contains("meshes[1].transform"));
    CHECK_THROWS_WITH(edit_mesh_transform(sf, 1, R"({"scale": [1, -1, 1]})"), Contains("mirroring"));
    CHECK_THROWS_WITH(edit_mesh_transform(sf, 5, "null"), Contains("meshes[5]"));
    CHECK_THROWS_WITH(edit_environment(sf, R"({"type": "constant", "radiance": [-1, 0, 0]})"),
                      Contains("environment.radiance"));
    CHECK_THROWS_AS(sf.scene->set_material(0, nullptr, Color(0.f)), ParameterError);
    CHECK_THROWS_AS(sf.scene->set_material(0, sf.scene->materials()[0].bsdf, Color(-1.f)), ParameterError);
    CHECK(render_pt(sf).values() == original.values());
    // A scene loaded without keeping its untransformed meshes cannot be edited.
    SceneFile fixed = load_scene_text(quads(), "/tmp/quads");
    CHECK_THROWS_WITH(edit_mesh_transform(fixed, 1, "null"), Contains("not loaded editable"));
}

TEST_CASE("a Mitsuba scene's text given in place of its file loads as the file", "[scene][mitsuba]") {
    const std::string xml = R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 1, 3" target="0, 0.5, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="10"/></film></sensor>
  <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="90"/><scale value="0.3"/><translate y="1.5"/></transform>
    <emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>
</scene>
)";
    const std::string path = "/tmp/gdr-test-mitsuba-text.xml";
    {
        std::ofstream out(path, std::ios::binary);
        out << xml;
    }
    SceneFileOptions options;
    options.text = xml;
    const SceneFile from_text = load_mitsuba_scene("/tmp/in-memory.xml", options);
    const SceneFile from_file = load_scene_file(path);
    CHECK(render_pt(from_text).values() == render_pt(from_file).values());
    options.text = replaced(xml, R"(value="5")", R"(value="6")");
    CHECK(load_mitsuba_scene("/tmp/in-memory.xml", options).content_hash != from_text.content_hash);
}
