// The gdr tool never loses a user's work: an output never replaces an input,
// resume and merge refuse renders that are not of one scene, integrator,
// parameter set and resolution, damaged render files are errors naming what
// is wrong, and the command line behaves as a renderer's does.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "cli_test_util.h"

using namespace gdr;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {

const std::string kScenes = GDR_SOURCE_DIR "/tests/scenes/";
const std::string kSmall = kScenes + "cornell-small.json";

std::string out(const std::string& name) {
    static const test::OutDir dir("safety");
    return dir(name);
}
using test::error_of;
using test::stdout_of;
std::string bytes(const std::string& path) { return test::file_bytes(path); }

// A copy of the small Cornell box scene (its OBJ and MTL too) in `dir`, so that a test may change it.
std::string copy_small_scene(const std::string& dir) {
    fs::create_directories(dir);
    const std::string box = GDR_SOURCE_DIR "/scenes/cornell-box/";
    fs::copy_file(box + "CornellBox-Original.obj", dir + "/box.obj", fs::copy_options::overwrite_existing);
    fs::copy_file(box + "CornellBox-Original.mtl", dir + "/CornellBox-Original.mtl", fs::copy_options::overwrite_existing);
    std::ofstream(dir + "/scene.json")
        << R"({"camera": {"position": [0, 1, 3.5], "target": [0, 1, 0], "up": [0, 1, 0], "fov": 45, "width": 24, "height": 24},
              "meshes": ["box.obj"]})";
    return dir + "/scene.json";
}

}  // namespace

TEST_CASE("safety: an output that is an input is refused before any work, naming both", "[cli][safety]") {
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "-o", out("a.exr")}) == 0);
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "2", "-o", out("b.exr")}) == 0);
    REQUIRE(cli::run({"render", kSmall, "--integrator", "gpt", "--spp", "1", "-o", out("g.exr")}) == 0);
    const std::string a = bytes(out("a.exr")), g = bytes(out("g.exr")), scene = bytes(kSmall);

    // Once replaced the resumed file, the 14-layer render and a part.
    CHECK_THAT(error_of({"render", kSmall, "--spp", "2", "--resume", out("a.exr"), "-o", out("a.exr")}),
               Contains("a.exr") && Contains("input"));
    CHECK_THAT(error_of({"reconstruct", out("g.exr"), "-o", out("g.exr")}), Contains("g.exr") && Contains("input"));
    CHECK_THAT(error_of({"merge", out("a.exr"), out("b.exr"), "-o", out("a.exr")}), Contains("a.exr") && Contains("input"));
    // Through a symbolic link, too.
    fs::create_symlink(out("g.exr"), out("link.exr"));
    CHECK_THAT(error_of({"reconstruct", out("g.exr"), "-o", out("link.exr")}), Contains("link.exr") && Contains("g.exr"));
    // The scene file: once replaced by an EXR.
    CHECK_FALSE(error_of({"render", kSmall, "-o", kSmall}).empty());
    CHECK(bytes(out("a.exr")) == a);
    CHECK(bytes(out("g.exr")) == g);
    CHECK(bytes(kSmall) == scene);
    // The preview beside the output counts too: OUT.png must not be an input.
    std::ofstream(out("tex.png")) << "not really a texture";
    CHECK_THROWS_WITH(cli::check_not_an_input(out("tex.exr"), {out("tex.png")}), Contains("tex.png") && Contains("preview"));
    CHECK_NOTHROW(cli::check_not_an_input(out("fresh.exr"), {out("a.exr"), kSmall}));
}

TEST_CASE("safety: -o must be an EXR, the PNG preview never replaces it", "[cli][safety]") {
    // Once wrote the EXR to out.png and then the PNG over it.
    CHECK_THAT(error_of({"render", kSmall, "--spp", "1", "-o", out("out.png")}), Contains("out.png") && Contains(".exr"));
    CHECK_FALSE(fs::exists(out("out.png")));
    CHECK_THAT(error_of({"merge", out("x.exr"), out("y.exr"), "-o", out("m.tif")}), Contains(".exr"));
    // A device takes the EXR and gets no preview.
    CHECK(cli::run({"render", kSmall, "--spp", "1", "-o", "/dev/null"}) == 0);
}

TEST_CASE("safety: resume refuses another scene, a changed scene, another resolution, before rendering",
          "[cli][safety]") {
    const std::string dir = out("scene-copy");
    const std::string scene = copy_small_scene(dir);
    REQUIRE(cli::run({"render", scene, "--spp", "2", "-o", out("copy.exr")}) == 0);
    CHECK_FALSE(read_exr(out("copy.exr")).metadata().at("scene_hash").empty());
    // Another scene at the same resolution once blended into the render, rc 0.
    const std::string msg = error_of({"render", kScenes + "emitter-wall/scene.json", "--resolution", "24x24", "--spp", "4",
                                      "--resume", out("copy.exr"), "-o", out("mixed.exr")});
    CHECK_THAT(msg, Contains("scene_hash") && Contains("copy.exr"));
    CHECK_FALSE(fs::exists(out("mixed.exr")));
    // The same scene moved elsewhere is the same scene.
    const std::string moved = copy_small_scene(out("scene-moved"));
    CHECK(cli::run({"render", moved, "--spp", "4", "--resume", out("copy.exr"), "-o", out("moved.exr")}) == 0);
    // One byte of a material changed: detected.
    {
        std::string mtl = bytes(dir + "/CornellBox-Original.mtl");
        const size_t kd = mtl.find("Kd 0.");
        REQUIRE(kd != std::string::npos);
        mtl[kd + 5] = mtl[kd + 5] == '1' ? '2' : '1';
        std::ofstream(dir + "/CornellBox-Original.mtl", std::ios::binary) << mtl;
    }
    CHECK_THAT(error_of({"render", scene, "--spp", "4", "--resume", out("copy.exr"), "-o", out("changed.exr")}),
               Contains("scene_hash"));
    // The wrong resolution once rendered everything first and then failed.
    const auto t0 = std::chrono::steady_clock::now();
    CHECK_THAT(error_of({"render", moved, "--resolution", "12x12", "--spp", "100000", "--resume", out("copy.exr"), "-o",
                         out("res.exr")}),
               Contains("resolution") && Contains("24x24") && Contains("12x12"));
    CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 5.0);
    CHECK_FALSE(fs::exists(out("res.exr")));
}

TEST_CASE("safety: a failure after rendering keeps the new samples in the rescue file", "[cli][safety]") {
    REQUIRE(cli::run({"render", kSmall, "--spp", "2", "-o", out("base.exr")}) == 0);
    // A layer the new render does not make: merging the two fails after rendering.
    FrameBuffer fb = read_exr(out("base.exr"));
    fb.add("stray", 1);
    write_exr(out("stray.exr"), fb);
    std::remove(cli::rescue_path().c_str());
    const std::string msg = error_of({"render", kSmall, "--spp", "5", "--resume", out("stray.exr"), "-o", out("r.exr")});
    CHECK_THAT(msg, Contains("stray") && Contains(cli::rescue_path()));
    REQUIRE(fs::exists(cli::rescue_path()));
    const cli::StoredRender part = cli::read_stored_render(cli::rescue_path());
    CHECK(part.spp == 3);
    CHECK(part.first_sample == 2);
    fs::remove(cli::rescue_path());
}

TEST_CASE("safety: merge refuses other scenes and names the parameter that differs", "[cli][safety]") {
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "1", "-o", out("s1.exr")}) == 0);
    REQUIRE(cli::run({"render", kScenes + "emitter-wall/scene.json", "--resolution", "24x24", "--spp", "1", "--seed", "2",
                      "-o", out("wall24.exr")}) == 0);
    // Once only a warning.
    CHECK_THAT(error_of({"merge", out("s1.exr"), out("wall24.exr"), "-o", out("bad.exr")}), Contains("scene"));
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "3", "--set", "rr_depth=2", "-o", out("rr.exr")}) == 0);
    // Once both parameter lists, without the key.
    CHECK_THAT(error_of({"merge", out("s1.exr"), out("rr.exr"), "-o", out("bad.exr")}),
               Contains("'rr_depth'") && Contains("5") && Contains("2"));
    CHECK_FALSE(fs::exists(out("bad.exr")));
}

TEST_CASE("safety: a damaged spp layer or header is an error naming the file and what is wrong", "[cli][safety]") {
    REQUIRE(cli::run({"render", kSmall, "--spp", "2", "--seed", "1", "-o", out("p1.exr")}) == 0);
    REQUIRE(cli::run({"render", kSmall, "--spp", "2", "--seed", "2", "-o", out("p2.exr")}) == 0);
    const FrameBuffer good = read_exr(out("p2.exr"));
    for (const float bad : {0.f, -3.f, 7.f}) {
        FrameBuffer fb = good;
        fb.get("spp").at(3, 4) = bad;
        write_exr(out("spp-bad.exr"), fb);
        // Once merged with the wrong weights.
        CHECK_THAT(error_of({"merge", out("p1.exr"), out("spp-bad.exr"), "-o", out("m.exr")}),
                   Contains("spp-bad.exr") && Contains("(3, 4)"));
    }
    FrameBuffer no_spp = good;
    no_spp.remove("spp");
    write_exr(out("no-spp.exr"), no_spp);
    CHECK_THAT(error_of({"merge", out("p1.exr"), out("no-spp.exr"), "-o", out("m.exr")}), Contains("'spp' layer"));
    CHECK_FALSE(fs::exists(out("m.exr")));

    // Layers without the settings: once read as an image with no settings, rc 0.
    FrameBuffer bare = good;
    bare.metadata().clear();
    write_exr(out("bare.exr"), bare);
    CHECK_THAT(error_of({"info", out("bare.exr")}), Contains("bare.exr") && Contains("integrator") && Contains("seed"));
    // A header zeroed from the data window's value on (40 bytes): it once
    // read as a 1x1 image of zeros with no settings, rc 0.
    std::string raw = bytes(out("p2.exr"));
    const size_t dw = raw.find("dataWindow");
    REQUIRE(dw != std::string::npos);
    for (size_t i = dw + 18; i < dw + 58; ++i) raw[i] = '\0';
    std::ofstream(out("zeroed.exr"), std::ios::binary) << raw;
    CHECK_THAT(error_of({"info", out("zeroed.exr")}), Contains("zeroed.exr"));
    // An ordinary single-image EXR is not a render and reads as before.
    write_exr_image(out("plain.exr"), Image(2, 2, 3, 0.5f));
    CHECK(stdout_of([&] { cli::run({"info", out("plain.exr")}); }).find("2x2") != std::string::npos);
}

TEST_CASE("safety: resume finishes the stored target, --spp is a new total, the integrator comes from the file",
          "[cli][safety]") {
    REQUIRE(cli::run({"render", kSmall, "--integrator", "gpt", "--spp", "2", "--seed", "4", "-o", out("t2.exr")}) == 0);
    // What an interrupted render of 6 spp leaves: 2 spp of a target of 6.
    FrameBuffer fb = read_exr(out("t2.exr"));
    CHECK(fb.metadata().at("target_spp") == "2");
    fb.metadata()["target_spp"] = "6";
    fb.metadata()["interrupted"] = "true";
    write_exr(out("t2of6.exr"), fb);
    // No --spp, no --integrator (the scene's default is pt): continues the gpt render to 6 spp.
    REQUIRE(cli::run({"render", kSmall, "--resume", out("t2of6.exr"), "-o", out("t6.exr")}) == 0);
    const FrameBuffer six = read_exr(out("t6.exr"));
    CHECK(six.metadata().at("spp") == "6");
    CHECK(six.metadata().at("integrator") == "gpt");
    CHECK(six.metadata().at("interrupted") == "false");
    // Complete: nothing more to do, and nothing written.
    CHECK(cli::run({"render", kSmall, "--resume", out("t6.exr"), "-o", out("t6b.exr")}) == 0);
    CHECK_FALSE(fs::exists(out("t6b.exr")));
    // --spp is the new total, and may not go backwards.
    REQUIRE(cli::run({"render", kSmall, "--resume", out("t6.exr"), "--spp", "8", "-o", out("t8.exr")}) == 0);
    CHECK(read_exr(out("t8.exr")).metadata().at("spp") == "8");
    CHECK_THAT(error_of({"render", kSmall, "--resume", out("t8.exr"), "--spp", "4", "-o", out("t4.exr")}),
               Contains("--spp 4") && Contains("8"));
    // Equal to one render of 8 spp.
    REQUIRE(cli::run({"render", kSmall, "--integrator", "gpt", "--spp", "8", "--seed", "4", "-o", out("w8.exr")}) == 0);
    const FrameBuffer a = read_exr(out("t8.exr")), b = read_exr(out("w8.exr"));
    double worst = 0.0;
    for (size_t i = 0; i < a.get("primal").values().size(); ++i)
        worst = std::max(worst, double(std::abs(a.get("primal").values()[i] - b.get("primal").values()[i])));
    CHECK(worst < 1e-5);
}

TEST_CASE("safety: a merged file merges again, only true overlaps are refused", "[cli][safety]") {
    for (const char* seed : {"1", "2", "3"})
        REQUIRE(cli::run({"render", kSmall, "--spp", "2", "--seed", seed, "-o", out(std::string("q") + seed + ".exr")}) == 0);
    REQUIRE(cli::run({"merge", out("q1.exr"), out("q2.exr"), "-o", out("q12.exr")}) == 0);
    // Once refused: "merged from renders with different seeds".
    REQUIRE(cli::run({"merge", out("q12.exr"), out("q3.exr"), "-o", out("q123.exr")}) == 0);
    const cli::StoredRender all = cli::read_stored_render(out("q123.exr"));
    CHECK(all.spp == 6);
    CHECK(all.ranges.size() == 3);
    CHECK(all.fb.metadata().at("sample_ranges") == "1:0:2,2:0:2,3:0:2");
    CHECK_THAT(error_of({"merge", out("q12.exr"), out("q1.exr"), "-o", out("bad.exr")}), Contains("same samples"));
    // A continuation of one seed joins its range: one sequence again, which --resume can continue.
    REQUIRE(cli::run({"render", kSmall, "--spp", "5", "--resume", out("q1.exr"), "-o", out("q1more.exr")}) == 0);
    CHECK(read_exr(out("q1more.exr")).metadata().at("sample_ranges") == "1:0:5");
}

TEST_CASE("safety: --version, help and every command's --help exit 0 with usage", "[cli][safety]") {
    CHECK_THAT(stdout_of([] { CHECK(cli::run({"--version"}) == 0); }), Contains("gdr 0.1"));
    CHECK_THAT(stdout_of([] { CHECK(cli::run({"help"}) == 0); }), Contains("gdr render") && Contains("gdr merge"));
    for (const char* cmd : {"render", "merge", "info", "reconstruct", "compare", "check-shift", "list"}) {
        INFO(cmd);
        CHECK_THAT(stdout_of([&] { CHECK(cli::run({cmd, "--help"}) == 0); }), Contains(std::string("gdr ") + cmd));
        CHECK_THAT(stdout_of([&] { CHECK(cli::run({"help", cmd}) == 0); }), Contains(std::string("gdr ") + cmd));
    }
    CHECK_THAT(error_of({"help", "frobnicate"}), Contains("'frobnicate'"));
}

TEST_CASE("safety: resolution and field of view from the command line", "[cli][safety]") {
    // emitter-wall is 10x8: one side keeps the aspect ratio.
    const std::string wall = kScenes + "emitter-wall/scene.json";
    REQUIRE(cli::run({"render", wall, "--spp", "1", "--width", "20", "-o", out("w20.exr")}) == 0);
    const FrameBuffer w = read_exr(out("w20.exr"));
    CHECK((w.width() == 20 && w.height() == 16));
    REQUIRE(cli::run({"render", wall, "--spp", "1", "--resolution", "7x3", "-o", out("w7.exr")}) == 0);
    const FrameBuffer r = read_exr(out("w7.exr"));
    CHECK((r.width() == 7 && r.height() == 3));
    CHECK_THAT(error_of({"render", wall, "--resolution", "7by3", "-o", out("x.exr")}), Contains("--resolution"));
    CHECK_THAT(error_of({"render", wall, "--width", "1e9", "-o", out("x.exr")}), Contains("--width") && Contains("1e9"));
    // A narrower field of view sees less of the box: the image changes.
    REQUIRE(cli::run({"render", kSmall, "--spp", "4", "-o", out("fov45.exr")}) == 0);
    REQUIRE(cli::run({"render", kSmall, "--spp", "4", "--set", "fov=20", "-o", out("fov20.exr")}) == 0);
    CHECK(read_exr(out("fov45.exr")).get("color").values() != read_exr(out("fov20.exr")).get("color").values());
    CHECK_THAT(error_of({"render", kSmall, "--set", "fov=200", "-o", out("x.exr")}), Contains("fov") && Contains("200"));
}

TEST_CASE("safety: info aligns its columns and prints numbers as given, list shows every parameter", "[cli][safety]") {
    REQUIRE(cli::run({"render", kSmall, "--integrator", "gpt", "--spp", "1", "--set", "alpha=0.2", "-o", out("i.exr")}) == 0);
    const std::string text = stdout_of([&] { cli::run({"info", out("i.exr")}); });
    CHECK_THAT(text, Contains("alpha=0.2\n") && !Contains("0.20000000000000001") && Contains("threshold=0.001\n"));
    // Every layer line has its "mean" in the same column.
    size_t column = std::string::npos;
    bool aligned = true;
    for (size_t at = 0; at < text.size();) {
        const size_t end = text.find('\n', at);
        const std::string line = text.substr(at, end - at);
        if (line.find(" mean ") != std::string::npos) {
            if (column == std::string::npos) column = line.find(" mean ");
            aligned &= line.find(" mean ") == column;
        }
        at = end == std::string::npos ? text.size() : end + 1;
    }
    CHECK(column != std::string::npos);
    CHECK(aligned);
    CHECK_THAT(stdout_of([] { cli::run({"list"}); }), Contains("nee") && Contains("batch") && Contains("alpha=0.2"));
    // check-shift says how many of the paths it was given could be shifted.
    CHECK_THAT(stdout_of([] { cli::run({"check-shift", kSmall, "--paths", "50"}); }), Contains("of 50 sampled"));
}
