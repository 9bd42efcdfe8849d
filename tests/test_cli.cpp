// The gdr tool through gdr::cli::run: bad command lines are gdr::Errors that
// name what is wrong (and list the alternatives), good ones write EXRs that
// record their settings, and --resume continues a render exactly.
#include <catch2/catch.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <limits>
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

const fs::path& out_dir() {
    static const test::OutDir dir("cli");
    return dir.path;
}

std::string out(const std::string& name) { return (out_dir() / name).string(); }

using test::error_of;

}  // namespace

TEST_CASE("cli: an unknown integrator lists the available ones", "[cli][errors]") {
    const std::string msg = error_of({"render", kScenes + "bad/ok.json", "--integrator", "ptt", "-o", out("x.exr")});
    CHECK_THAT(msg, Contains("'ptt'") && Contains("available") && Contains("pt"));
}

TEST_CASE("cli: a misspelt --set parameter is named, not ignored", "[cli][errors]") {
    const std::string msg = error_of({"render", kScenes + "bad/ok.json", "--set", "mx_depth=3", "-o", out("x.exr")});
    CHECK_THAT(msg, Contains("'mx_depth'") && Contains("--set") && Contains("pt"));
    // ... and so is one in the scene file's render.params, with the file.
    const std::string msg2 = error_of({"render", kScenes + "bad/misspelt-param.json", "-o", out("x.exr")});
    CHECK_THAT(msg2, Contains("'mx_depth'") && Contains("misspelt-param.json"));
    // An ill-typed value names its key.
    const std::string msg3 = error_of({"render", kScenes + "bad/ok.json", "--set", "max_depth=deep", "-o", out("x.exr")});
    CHECK_THAT(msg3, Contains("max_depth"));
}

TEST_CASE("cli: missing and malformed scene files are errors naming the file", "[cli][errors]") {
    CHECK_THAT(error_of({"render", kScenes + "bad/nope.json", "-o", out("x.exr")}), Contains("nope.json"));
    CHECK_THAT(error_of({"render", kScenes + "bad/malformed.json", "-o", out("x.exr")}), Contains("malformed.json"));
    CHECK_THAT(error_of({"render", kScenes + "bad/missing-mtl-obj.json", "-o", out("x.exr")}), Contains("no-such-file.mtl"));
    CHECK_THAT(error_of({"render", kScenes + "bad/nan-vertex-obj.json", "-o", out("x.exr")}), Contains("nan-vertex.obj"));
    CHECK_THAT(error_of({"render", kScenes + "bad/empty-obj.json", "-o", out("x.exr")}), Contains("empty-obj.json"));
    CHECK_FALSE(fs::exists(out("x.exr")));
}

TEST_CASE("cli: bad command lines name the option", "[cli][errors]") {
    const std::string ok = kScenes + "bad/ok.json";
    CHECK_THAT(error_of({"render", ok}), Contains("-o"));
    CHECK_THAT(error_of({"render", ok, "--spp", "0", "-o", out("x.exr")}), Contains("--spp"));
    CHECK_THAT(error_of({"render", ok, "--spp", "ten", "-o", out("x.exr")}), Contains("--spp"));
    CHECK_THAT(error_of({"render", ok, "--spp", "4", "--time", "1", "-o", out("x.exr")}), Contains("--time"));
    CHECK_THAT(error_of({"render", ok, "--frobnicate", "-o", out("x.exr")}), Contains("--frobnicate"));
    CHECK_THAT(error_of({"render", ok, "--threads", "-2", "-o", out("x.exr")}), Contains("--threads"));
    CHECK_THAT(error_of({"render", ok, "-o"}), Contains("-o"));
    CHECK_THAT(error_of({"frobnicate"}), Contains("'frobnicate'") && Contains("usage"));
    CHECK_THAT(error_of({"list", "integrators"}), Contains("list") && Contains("'integrators'"));
    CHECK_THAT(error_of({"info", out("none.exr")}), Contains("none.exr"));
    CHECK_THAT(error_of({"render", ok, "--resume", out("none.exr"), "-o", out("x.exr")}), Contains("none.exr"));
}

TEST_CASE("cli: out-of-range and non-finite option values are refused, not clamped or ignored", "[cli][errors]") {
    const std::string ok = kScenes + "bad/ok.json";
    const auto render_with = [&](const std::string& opt, const std::string& v) {
        return error_of({"render", ok, opt, v, "-o", out("x.exr")});
    };
    // A negative seed once meant "the scene's seed", silently.
    CHECK_THAT(render_with("--seed", "-1"), Contains("--seed") && Contains(">= 0"));
    // strtoll saturates; the clamped value would be another setting than asked for.
    CHECK_THAT(render_with("--seed", "99999999999999999999"), Contains("--seed") && Contains("out of range"));
    // NaN and 0 once fell through to an spp render, silently.
    CHECK_THAT(render_with("--time", "nan"), Contains("--time") && Contains("finite"));
    CHECK_THAT(render_with("--time", "inf"), Contains("--time") && Contains("finite"));
    CHECK_THAT(render_with("--time", "0"), Contains("--time") && Contains("positive"));
    CHECK_THAT(render_with("--exposure", "nan"), Contains("--exposure"));
    // Once truncated to an int.
    CHECK_THAT(render_with("--threads", "99999999999"), Contains("--threads") && Contains("between"));
    // The sampler numbers a pixel's samples in 32 bits.
    CHECK_THAT(render_with("--spp", "5000000000"), Contains("2^32"));
    CHECK_THAT(error_of({"check-shift", ok, "--seed", "-4"}), Contains("--seed"));
    CHECK_THAT(error_of({"check-shift", ok, "--paths", "0"}), Contains("--paths"));
    CHECK_THAT(error_of({"check-shift", ok, "--max-depth", "0"}), Contains("--max-depth"));
    CHECK_THAT(error_of({"check-shift", ok, "--threshold", "-1"}), Contains("--threshold"));
    CHECK_FALSE(fs::exists(out("x.exr")));
}

TEST_CASE("cli: zero-area triangles do not stop a render", "[cli]") {
    REQUIRE(cli::run({"render", kScenes + "bad/degenerate-obj.json", "--spp", "2", "-o", out("degenerate.exr")}) == 0);
    CHECK(read_exr(out("degenerate.exr")).has("color"));
}

TEST_CASE("cli: render writes every layer and the settings it was made with", "[cli]") {
    REQUIRE(cli::run({"render", kScenes + "emitter-wall/scene.json", "--spp", "3", "--seed", "5", "--set", "max_depth=4",
                      "--threads", "2", "-o", out("wall.exr")}) == 0);
    const FrameBuffer fb = read_exr(out("wall.exr"));
    for (const char* layer : {"color", "albedo", "normal", "depth", "variance", "spp"}) CHECK(fb.has(layer));
    CHECK(fb.get("color").rgb(3, 3).r == Approx(3.f));
    const auto& m = fb.metadata();
    CHECK(m.at("integrator") == "pt");
    CHECK(m.at("spp") == "3");
    CHECK(m.at("seed") == "5");
    CHECK_THAT(m.at("integrator_params"), Contains("max_depth=4"));
    CHECK_THAT(m.at("scene"), Contains("emitter-wall"));
    CHECK(fs::exists(out("wall.png")));
    CHECK(cli::run({"info", out("wall.exr")}) == 0);
    CHECK(cli::run({"list"}) == 0);
}

TEST_CASE("cli: --resume continues the sample sequence: 8 + 8 spp equals 16 spp", "[cli]") {
    const std::string scene = kScenes + "cornell-small.json";
    REQUIRE(cli::run({"render", scene, "--spp", "8", "--seed", "9", "-o", out("first.exr")}) == 0);
    // --spp with --resume is the new total.
    REQUIRE(cli::run({"render", scene, "--spp", "16", "--resume", out("first.exr"), "-o", out("resumed.exr")}) == 0);
    REQUIRE(cli::run({"render", scene, "--spp", "16", "--seed", "9", "-o", out("full.exr")}) == 0);
    const FrameBuffer a = read_exr(out("resumed.exr")), b = read_exr(out("full.exr"));
    CHECK(a.metadata().at("spp") == "16");
    const Image &ca = a.get("color"), &cb = b.get("color");
    const Image &va = a.get("variance"), &vb = b.get("variance");
    REQUIRE(ca.same_shape(cb));
    double worst = 0, worst_var = 0;
    for (size_t i = 0; i < ca.values().size(); ++i) {
        worst = std::max(worst, std::abs(double(ca.values()[i]) - cb.values()[i]) / (std::abs(double(cb.values()[i])) + 1e-6));
        worst_var = std::max(worst_var, std::abs(double(va.values()[i]) - vb.values()[i]) / (std::abs(double(vb.values()[i])) + 1e-6));
    }
    CHECK(worst < 1e-5);
    CHECK(worst_var < 1e-4);
    CHECK(a.get("spp").at(0, 0) == 16.f);
    // Resuming with another seed or integrator parameters would mix two estimates: refused.
    CHECK_THAT(error_of({"render", scene, "--spp", "16", "--seed", "3", "--resume", out("first.exr"), "-o", out("bad.exr")}),
               Contains("seed"));
    CHECK_THAT(error_of({"render", scene, "--spp", "16", "--set", "max_depth=3", "--resume", out("first.exr"), "-o",
                         out("bad.exr")}),
               Contains("parameter 'max_depth'"));
}

TEST_CASE("cli: --resume names a malformed metadata entry before rendering", "[cli][errors]") {
    const std::string scene = kScenes + "cornell-small.json";
    REQUIRE(cli::run({"render", scene, "--spp", "1", "-o", out("meta.exr")}) == 0);
    const FrameBuffer good = read_exr(out("meta.exr"));
    for (const char* key : {"seed", "spp", "first_sample", "render_seconds"}) {
        FrameBuffer bad = good;
        bad.metadata()[key] = "-2x";
        write_exr(out("meta-bad.exr"), bad);
        const std::string msg = error_of({"render", scene, "--spp", "1", "--resume", out("meta-bad.exr"), "-o", out("meta-out.exr")});
        CHECK_THAT(msg, Contains("meta-bad.exr") && Contains(key));
        CHECK_FALSE(fs::exists(out("meta-out.exr")));
    }
    FrameBuffer old = good;
    old.metadata().erase("first_sample");
    write_exr(out("meta-old.exr"), old);
    CHECK_THAT(error_of({"render", scene, "--spp", "1", "--resume", out("meta-old.exr"), "-o", out("meta-out.exr")}),
               Contains("first_sample"));
}

TEST_CASE("cli: an unwritable output is refused before rendering, and a failed write is rescued", "[cli][errors]") {
    const std::string ok = kScenes + "bad/ok.json";
    CHECK_THAT(error_of({"render", ok, "-o", out("no-such-dir/x.exr")}), Contains("no-such-dir"));
    CHECK_THAT(error_of({"render", ok, "-o", out_dir().string()}), Contains("directory"));
    // An EXR writer seeks back, so a pipe cannot take one: refused before rendering.
    REQUIRE(mkfifo(out("pipe.exr").c_str(), 0600) == 0);
    CHECK_THAT(error_of({"render", ok, "-o", out("pipe.exr")}), Contains("pipe"));
    // A write that fails after rendering (here: its directory is gone) leaves the image in a rescue file.
    REQUIRE(cli::run({"render", ok, "--spp", "2", "-o", out("rescued.exr")}) == 0);
    const FrameBuffer fb = read_exr(out("rescued.exr"));
    std::string msg;
    try {
        cli::write_exr_or_rescue(out("gone/x.exr"), fb);
    } catch (const RuntimeFailure& e) {
        msg = e.what();
    }
    REQUIRE_THAT(msg, Contains("gone/x.exr") && Contains("saved to"));
    const std::string rescue = msg.substr(msg.find("saved to ") + 9, msg.find(" instead") - msg.find("saved to ") - 9);
    const FrameBuffer back = read_exr(rescue);
    CHECK(back.metadata().at("spp") == "2");
    CHECK(back.get("color").values() == fb.get("color").values());
    fs::remove(rescue);
    // reconstruct and compare name the file that lacks a layer.
    CHECK_THAT(error_of({"reconstruct", out("rescued.exr"), "-o", out("r.exr")}), Contains("rescued.exr") && Contains("primal"));
    CHECK_THAT(error_of({"compare", out("rescued.exr"), out("rescued.exr"), "--layer", "dx"}),
               Contains("rescued.exr") && Contains("'dx'"));
}

TEST_CASE("cli: reconstruct names the file and the pixel of a NaN in a gradient", "[cli][errors]") {
    REQUIRE(cli::run({"render", kScenes + "cornell-small.json", "--integrator", "gpt", "--spp", "1", "--set",
                      "reconstruct=none", "-o", out("grad.exr")}) == 0);
    FrameBuffer fb = read_exr(out("grad.exr"));
    fb.get("dx").at(3, 2, 1) = std::numeric_limits<float>::quiet_NaN();
    write_exr(out("grad-nan.exr"), fb);
    const std::string msg = error_of({"reconstruct", out("grad-nan.exr"), "-o", out("rec.exr")});
    CHECK_THAT(msg, Contains("grad-nan.exr") && Contains("dx") && Contains("(3, 2)"));
    CHECK_FALSE(fs::exists(out("rec.exr")));
    CHECK(cli::run({"reconstruct", out("grad.exr"), "-o", out("rec.exr")}) == 0);
}

TEST_CASE("cli: --resume of a gradient-domain render reconstructs the merged buffers", "[cli]") {
    const std::string scene = kScenes + "cornell-small.json";
    const std::vector<std::string> gpt = {"--integrator", "gpt", "--seed", "4"};
    const auto run = [&](std::vector<std::string> args) {
        args.insert(args.begin() + 2, gpt.begin(), gpt.end());
        return cli::run(args);
    };
    REQUIRE(run({"render", scene, "--spp", "2", "-o", out("g2.exr")}) == 0);
    REQUIRE(run({"render", scene, "--spp", "4", "--resume", out("g2.exr"), "-o", out("g2+2.exr")}) == 0);
    REQUIRE(run({"render", scene, "--spp", "4", "-o", out("g4.exr")}) == 0);
    const FrameBuffer merged = read_exr(out("g2+2.exr")), whole = read_exr(out("g4.exr")), half = read_exr(out("g2.exr"));
    CHECK(merged.metadata().at("interrupted") == "false");
    // The merged primal and gradients are the 4-spp render's up to rounding; so
    // must be the L1 reconstruction, which is not linear in them: averaging the
    // two halves' reconstructions would differ by far more.
    const auto rel_diff = [](const Image& a, const Image& b) {
        double num = 0, den = 0;
        for (size_t i = 0; i < a.values().size(); ++i)
            num += std::abs(double(a.values()[i]) - b.values()[i]), den += std::abs(double(b.values()[i]));
        return num / den;
    };
    for (const char* layer : {"primal", "dx", "dy", "reconstruction_l2"})
        CHECK(rel_diff(merged.get(layer), whole.get(layer)) < 1e-5);
    CHECK(rel_diff(merged.get("reconstruction_l1"), whole.get("reconstruction_l1")) < 1e-3);
    CHECK(rel_diff(half.get("reconstruction_l1"), whole.get("reconstruction_l1")) > 1e-2);
}

TEST_CASE("cli: merge pools independent renders and refuses to count samples twice", "[cli]") {
    const std::string scene = kScenes + "cornell-small.json";
    REQUIRE(cli::run({"render", scene, "--spp", "4", "--seed", "1", "-o", out("part1.exr")}) == 0);
    REQUIRE(cli::run({"render", scene, "--spp", "2", "--seed", "2", "-o", out("part2.exr")}) == 0);
    REQUIRE(cli::run({"merge", out("part1.exr"), out("part2.exr"), "-o", out("merged.exr")}) == 0);
    const FrameBuffer a = read_exr(out("part1.exr")), b = read_exr(out("part2.exr")), m = read_exr(out("merged.exr"));
    CHECK(m.metadata().at("spp") == "6");
    CHECK(m.metadata().at("seed") == cli::kMixedSeeds);
    CHECK(m.get("spp").at(0, 0) == 6.f);
    // The sample-weighted mean of the parts.
    const auto& ca = a.get("color").values();
    const auto& cb = b.get("color").values();
    const auto& cm = m.get("color").values();
    double worst = 0.0;
    for (size_t i = 0; i < cm.size(); ++i)
        worst = std::max(worst, std::abs(cm[i] - (4.0 * ca[i] + 2.0 * cb[i]) / 6.0) / (1e-6 + std::abs(double(cm[i]))));
    CHECK(worst < 1e-5);
    // The same samples twice, another integrator, and resuming a merge of several seeds are refused.
    CHECK_THAT(error_of({"merge", out("part1.exr"), out("part1.exr"), "-o", out("bad.exr")}), Contains("same samples"));
    REQUIRE(cli::run({"render", scene, "--spp", "1", "--seed", "3", "--set", "max_depth=2", "-o", out("other.exr")}) == 0);
    CHECK_THAT(error_of({"merge", out("part1.exr"), out("other.exr"), "-o", out("bad.exr")}),
               Contains("other.exr") && Contains("parameter 'max_depth'"));
    CHECK_THAT(error_of({"render", scene, "--spp", "1", "--resume", out("merged.exr"), "-o", out("bad.exr")}),
               Contains("different seeds"));
    CHECK_THAT(error_of({"merge", out("part1.exr"), "-o", out("bad.exr")}), Contains("two"));
    CHECK_FALSE(fs::exists(out("bad.exr")));
    // Renders of an integrator that another program registered still merge (its mean layers).
    for (const char* part : {"part1", "part2"}) {
        FrameBuffer fb = read_exr(out(std::string(part) + ".exr"));
        fb.metadata()["integrator"] = "registered-elsewhere";
        write_exr(out(std::string(part) + "-elsewhere.exr"), fb);
    }
    REQUIRE(cli::run({"merge", out("part1-elsewhere.exr"), out("part2-elsewhere.exr"), "-o", out("elsewhere.exr")}) == 0);
    CHECK(read_exr(out("elsewhere.exr")).get("color").values() == cm);
}

TEST_CASE("cli: merging gradient-domain renders reconstructs the pooled buffers", "[cli]") {
    const std::string scene = kScenes + "cornell-small.json";
    for (const char* seed : {"1", "2"})
        REQUIRE(cli::run({"render", scene, "--integrator", "gpt", "--spp", "2", "--seed", seed, "-o",
                          out(std::string("gpart") + seed + ".exr")}) == 0);
    REQUIRE(cli::run({"merge", out("gpart1.exr"), out("gpart2.exr"), "-o", out("gmerged.exr")}) == 0);
    FrameBuffer m = read_exr(out("gmerged.exr"));
    const FrameBuffer p1 = read_exr(out("gpart1.exr")), p2 = read_exr(out("gpart2.exr"));
    const Image l1 = m.get("reconstruction_l1");
    // What reconstructing the merged primal and gradients gives.
    REQUIRE(cli::run({"reconstruct", out("gmerged.exr"), "--alpha", "0.2", "-o", out("grec.exr")}) == 0);
    const Image again = read_exr(out("grec.exr")).get("color");  // a copy: the FrameBuffer read is a temporary
    double num = 0, den = 0, avg_num = 0;
    for (size_t i = 0; i < l1.values().size(); ++i) {
        num += std::abs(double(l1.values()[i]) - again.values()[i]);
        den += std::abs(double(again.values()[i]));
        const double avg = 0.5 * (double(p1.get("reconstruction_l1").values()[i]) + p2.get("reconstruction_l1").values()[i]);
        avg_num += std::abs(avg - again.values()[i]);
    }
    CHECK(num / den < 1e-4);
    CHECK(avg_num / den > 1e-2);  // averaging the parts' reconstructions would be visibly off
}

TEST_CASE("cli: check-shift takes a Mitsuba scene's -D parameters and --lenient", "[cli][mitsuba]") {
    // A diffuse rectangle whose reflectance is the scene's $level, lit by an
    // emitter behind the camera, and a projector emitter, which gdr does not support.
    const std::string scene = out("check-shift.xml");
    std::ofstream(scene) << R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/></film></sensor>
  <shape type="rectangle"><bsdf type="diffuse"><rgb name="reflectance" value="$level"/></bsdf></shape>
  <shape type="rectangle"><boolean name="flip_normals" value="true"/>
    <transform name="to_world"><scale value="3"/><translate z="6"/></transform>
    <emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
  <emitter type="projector"/>
</scene>)";
    CHECK_THAT(error_of({"check-shift", scene, "--paths", "20"}), Contains("$level"));
    CHECK_THAT(error_of({"check-shift", scene, "--paths", "20", "-D", "level=0.5"}),
               Contains("projector") && Contains("--lenient"));
    CHECK_THAT(error_of({"check-shift", scene, "-D", "level"}), Contains("-D") && Contains("name=value"));
    CHECK_THAT(test::stdout_of([&] {
                   cli::run({"check-shift", scene, "--paths", "20", "-D", "level=0.5", "--lenient"});
               }),
               Contains("of 20 sampled") && Contains("PASS"));
    // An environment light is supported by pt and bdpt, not yet by the shifts: a clear error.
    const std::string env_scene = out("check-shift-env.xml");
    std::ofstream(env_scene) << R"(<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
  <shape type="rectangle"><transform name="to_world"><translate z="-3"/></transform></shape>
  <emitter type="constant"/>
</scene>)";
    CHECK_THAT(error_of({"check-shift", env_scene, "--paths", "20"}), Contains("environment"));
}
