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
