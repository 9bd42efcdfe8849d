// The gdr tool's plugin loading (gdr/cli/plugins.h): where the neural plugin
// is not there (GDR_PLUGIN_PATH points the search at a directory without it,
// so these run alike in builds with and without libtorch), and with the
// outside plugin of examples/plugin (a reconstructor and a shift with a
// parameter) chosen by name in render, reconstruct, merge, resume and
// check-shift. They run the real binary, whose plugin search happens once
// per process.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "cli_test_util.h"
#include "gdr/integrators/gpt.h"
#include "gdr/io/exr.h"
#include "tool_process.h"

#ifdef GDR_TOOL

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

const std::string kScene = GDR_SOURCE_DIR "/tests/scenes/cornell-small.json";

}  // namespace

TEST_CASE("without its plugin, the neural reconstructor's absence is named with how to build it", "[cli][plugins]") {
    const test::OutDir dir("plugins-absent");
    std::filesystem::create_directories(dir("empty"));
    const std::string empty = dir("empty");
    const std::string gpt = dir("gpt.exr");
    // The input, rendered in process (no plugin involved).
    REQUIRE(cli::run({"render", kScene, "--integrator", "gpt", "--spp", "2", "--set", "reconstruct=none", "-o", gpt}) == 0);

    const test::ToolRun rec =
        test::run_tool(GDR_TOOL, {"reconstruct", gpt, "--method", "neural", "-o", dir("neural.exr")}, dir("log1"),
                       empty.c_str());
    INFO(rec.output);
    CHECK(rec.status == 1);
    CHECK_THAT(rec.output, Contains("gdr reconstruct --method neural") && Contains("not built") &&
                               Contains("libtorch") && Contains("scripts/install-deps.sh") &&
                               Contains("libtorch-dev") && Contains("libgdr_neural_plugin.so") &&
                               Contains(empty) && Contains("GDR_PLUGIN_PATH"));
    CHECK_FALSE(std::filesystem::exists(dir("neural.exr")));

    // gdr render refuses before rendering, not after.
    const test::ToolRun ren = test::run_tool(
        GDR_TOOL, {"render", kScene, "--integrator", "gpt", "--spp", "2", "--set", "reconstruct=neural", "-o", dir("r.exr")},
        dir("log2"), empty.c_str());
    INFO(ren.output);
    CHECK(ren.status == 1);
    CHECK_THAT(ren.output, Contains("gdr render (reconstruct=neural)") && Contains("not built") &&
                               Contains("libtorch-dev"));
    CHECK_THAT(ren.output, !Contains("rendered"));
    CHECK_FALSE(std::filesystem::exists(dir("r.exr")));

    // Set but empty: no directory is searched, and the message says so.
    const test::ToolRun none =
        test::run_tool(GDR_TOOL, {"reconstruct", gpt, "--method", "neural", "-o", dir("n.exr")}, dir("log3"), "");
    CHECK(none.status == 1);
    CHECK_THAT(none.output, Contains("no directory was searched"));

    // Another unknown name is the registry's error, listing what there is.
    const test::ToolRun typo =
        test::run_tool(GDR_TOOL, {"reconstruct", gpt, "--method", "poisson-l3", "-o", dir("t.exr")}, dir("log4"),
                       empty.c_str());
    CHECK(typo.status == 1);
    CHECK_THAT(typo.output, Contains("unknown reconstructor 'poisson-l3'") && Contains("poisson-l1"));

    // gdr list says that neural is not built rather than leaving it out silently.
    const test::ToolRun list = test::run_tool(GDR_TOOL, {"list"}, dir("log5"), empty.c_str());
    CHECK(list.status == 0);
    CHECK_THAT(list.output, Contains("neural") && Contains("not built"));
}

TEST_CASE("a plugin file that is not a loadable library is named with the loader's reason", "[cli][plugins]") {
    const test::OutDir dir("plugins-broken");
    std::filesystem::create_directories(dir("plugins"));
    const std::string plugin = dir("plugins/libgdr_neural_plugin.so");
    std::ofstream(plugin) << "not a shared library";
    const std::string gpt = dir("gpt.exr");
    REQUIRE(cli::run({"render", kScene, "--integrator", "gpt", "--spp", "1", "--set", "reconstruct=none", "-o", gpt}) == 0);
    const test::ToolRun r = test::run_tool(GDR_TOOL, {"reconstruct", gpt, "--method", "neural", "-o", dir("n.exr")},
                                           dir("log"), dir("plugins").c_str());
    INFO(r.output);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("--method neural") && Contains(plugin) && Contains("could not be loaded"));
    CHECK_FALSE(std::filesystem::exists(dir("n.exr")));
}

#ifdef GDR_EXAMPLE_PLUGIN_DIR

namespace {

// The largest absolute difference between two images of one shape (radiance).
double max_abs_diff(const Image& a, const Image& b) {
    REQUIRE(a.same_shape(b));
    double m = 0.0;
    for (size_t i = 0; i < a.values().size(); ++i) m = std::max(m, double(std::abs(a.values()[i] - b.values()[i])));
    return m;
}

double mean_of(const Image& a) {
    double s = 0.0;
    for (float v : a.values()) s += v;
    return s / double(a.values().size());
}

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

}  // namespace

TEST_CASE("an outside plugin's reconstructor is chosen by name in render, reconstruct, merge and resume",
          "[cli][plugins]") {
    const test::OutDir dir("plugins-reconstructor");
    const char* plugins = GDR_EXAMPLE_PLUGIN_DIR;
    // The example's Jacobi solve of the screened Poisson L2 energy, iterated
    // far enough (its slowest modes shrink by 4 / 4.04 an iteration at
    // alpha = 0.2: 3000 iterations leave e^-30 of the start), equals
    // poisson-l2's exact DCT solve up to float rounding: the largest
    // difference measured was 9.5e-7 against a tolerance of 1.3e-5. With
    // the sign of the left neighbour's dx in its right-hand side flipped
    // (a wrong divergence), it was 0.75, and this check and the merged
    // file's failed.
    const std::vector<std::string> render{"render", kScene, "--integrator", "gpt", "--spp", "4"};
    const std::vector<std::string> recon{"--set", "reconstruct=l2,jacobi-poisson", "--set",
                                         "reconstruct.jacobi-poisson.iterations=3000"};
    const std::string a = dir("a.exr"), b = dir("b.exr");
    test::ToolRun r = test::run_tool(GDR_TOOL, with(with(render, recon), {"--seed", "1", "-o", a}), dir("a.log"), plugins);
    INFO(r.output);
    REQUIRE(r.status == 0);
    const FrameBuffer fa = read_exr(a);
    REQUIRE(fa.has("reconstruction_l2"));
    REQUIRE(fa.has("reconstruction_jacobi-poisson"));
    CHECK_THAT(fa.metadata().at("integrator_params"),
               Contains("reconstruct=l2,jacobi-poisson") && Contains("reconstruct.jacobi-poisson.iterations=3000"));
    const Image& l2 = fa.get("reconstruction_l2");
    const double tol = 1e-4 * mean_of(l2);
    CHECK(max_abs_diff(fa.get("reconstruction_jacobi-poisson"), l2) <= tol);

    // gdr reconstruct --method with its parameters: the same solve from the
    // file's layers. Without iterations (the wrong variant: no solve, the
    // primal plus the direct light) it is far from poisson-l2, so the
    // tolerance above tells a solved image from an unsolved one.
    r = test::run_tool(GDR_TOOL, {"reconstruct", a, "--method", "jacobi-poisson", "--set", "iterations=3000", "-o",
                                  dir("rec.exr")},
                       dir("rec.log"), plugins);
    INFO(r.output);
    REQUIRE(r.status == 0);
    const FrameBuffer rec = read_exr(dir("rec.exr"));
    CHECK(rec.metadata().at("reconstruction") == "jacobi-poisson");
    CHECK_THAT(rec.metadata().at("reconstruction_params"), Contains("iterations=3000"));
    CHECK(max_abs_diff(rec.get("color"), fa.get("reconstruction_jacobi-poisson")) <= 1e-6 * mean_of(l2));
    r = test::run_tool(GDR_TOOL, {"reconstruct", a, "--method", "jacobi-poisson", "--set", "iterations=0", "-o",
                                  dir("rec0.exr")},
                       dir("rec0.log"), plugins);
    REQUIRE(r.status == 0);
    CHECK(max_abs_diff(read_exr(dir("rec0.exr")).get("color"), l2) > 100 * tol);

    // A second part merges: the plugin is loaded for it (no warning that the
    // reconstructor is unknown) and the merged file keeps both layers and the parameters.
    r = test::run_tool(GDR_TOOL, with(with(render, recon), {"--seed", "2", "-o", b}), dir("b.log"), plugins);
    REQUIRE(r.status == 0);
    r = test::run_tool(GDR_TOOL, {"merge", a, b, "-o", dir("m.exr")}, dir("m.log"), plugins);
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK_THAT(r.output, !Contains("warning"));
    const FrameBuffer fm = read_exr(dir("m.exr"));
    CHECK(fm.has("reconstruction_jacobi-poisson"));
    CHECK(fm.has("reconstruction_l2"));
    CHECK_THAT(fm.metadata().at("integrator_params"), Contains("reconstruct.jacobi-poisson.iterations=3000"));
    CHECK(max_abs_diff(fm.get("reconstruction_jacobi-poisson"), fm.get("reconstruction_l2")) <=
          1e-4 * mean_of(fm.get("reconstruction_l2")));

    // Resume: continued with the stored parameters; another value is refused, naming the key.
    r = test::run_tool(GDR_TOOL, {"render", kScene, "--resume", a, "--spp", "8", "-o", dir("r.exr")}, dir("r.log"),
                       plugins);
    INFO(r.output);
    REQUIRE(r.status == 0);
    const FrameBuffer fr = read_exr(dir("r.exr"));
    CHECK(fr.metadata().at("spp") == "8");
    CHECK(fr.has("reconstruction_jacobi-poisson"));
    CHECK_THAT(fr.metadata().at("integrator_params"), Contains("reconstruct.jacobi-poisson.iterations=3000"));
    r = test::run_tool(GDR_TOOL,
                       {"render", kScene, "--resume", a, "--spp", "8", "--set",
                        "reconstruct.jacobi-poisson.iterations=10", "-o", dir("r2.exr")},
                       dir("r2.log"), plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("'reconstruct.jacobi-poisson.iterations'") && Contains("3000"));
    CHECK_FALSE(std::filesystem::exists(dir("r2.exr")));

    // gdr submit checks the names and keys before writing its scripts, and
    // its render jobs pass them on.
    r = test::run_tool(GDR_TOOL,
                       with(with({"submit", kScene, "--parts", "2", "--spp", "4", "--integrator", "gpt"}, recon),
                            {"--dry-run", "-o", dir("s.exr")}),
                       dir("s.log"), plugins);
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK_THAT(r.output, Contains("reconstruct.jacobi-poisson.iterations=3000"));
    r = test::run_tool(GDR_TOOL,
                       {"submit", kScene, "--parts", "2", "--spp", "4", "--integrator", "gpt", "--set",
                        "reconstruct=jacobi-poison", "--dry-run", "-o", dir("s2.exr")},
                       dir("s2.log"), plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("gdr submit") && Contains("unknown reconstructor 'jacobi-poison'"));

    // Named errors, before rendering: an unknown name lists what is
    // registered, the plugin's names too; an unknown key is named in full.
    r = test::run_tool(GDR_TOOL, with(render, {"--set", "reconstruct=jacobi-poison", "-o", dir("e1.exr")}), dir("e1.log"),
                       plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown reconstructor 'jacobi-poison'") && Contains("jacobi-poisson") &&
                             Contains("poisson-l2"));
    r = test::run_tool(GDR_TOOL,
                       with(render, {"--set", "reconstruct=jacobi-poisson", "--set", "reconstruct.iteratons=5", "-o",
                                     dir("e2.exr")}),
                       dir("e2.log"), plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown parameter 'reconstruct.iteratons'") && Contains("'jacobi-poisson'"));
    CHECK_THAT(r.output, !Contains("rendered"));
    r = test::run_tool(GDR_TOOL, {"reconstruct", a, "--method", "jacobi-poisson", "--set", "iteratons=5", "-o",
                                  dir("e3.exr")},
                       dir("e3.log"), plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown parameter 'iteratons'") && Contains("'jacobi-poisson'"));
    for (const char* f : {"e1.exr", "e2.exr", "e3.exr"}) CHECK_FALSE(std::filesystem::exists(dir(f)));
}

TEST_CASE("an outside plugin's shift takes its parameter in a render and is refused a wrong one", "[cli][plugins]") {
    const test::OutDir dir("plugins-shift");
    const char* plugins = GDR_EXAMPLE_PLUGIN_DIR;
    const auto render = [&](const std::string& out, const std::vector<std::string>& sets) {
        std::vector<std::string> args{"render", kScene, "--integrator", "gpt", "--spp", "2", "--seed", "5",
                                      "--set", "reconstruct=none", "--set", "shift=late-reconnect"};
        for (const std::string& s : sets) args.push_back("--set"), args.push_back(s);
        args.push_back("-o"), args.push_back(dir(out));
        return test::run_tool(GDR_TOOL, args, dir(out + ".log"), plugins);
    };
    test::ToolRun r = render("one.exr", {"shift.replay_vertices=1"});
    INFO(r.output);
    REQUIRE(r.status == 0);
    r = render("three.exr", {"shift.replay_vertices=3"});
    REQUIRE(r.status == 0);
    const FrameBuffer one = read_exr(dir("one.exr")), three = read_exr(dir("three.exr"));
    CHECK_THAT(three.metadata().at("integrator_params"),
               Contains("shift=late-reconnect") && Contains("shift.replay_vertices=3"));
    // The parameter reaches the shift: the same samples shifted otherwise
    // give other gradients. With the shift made to ignore it (replay_vertices
    // always 1), the two dx layers were equal and this check failed.
    CHECK(max_abs_diff(one.get("dx"), three.get("dx")) > 0.0);

    // A resume with another value is refused, naming the key.
    r = test::run_tool(GDR_TOOL,
                       {"render", kScene, "--resume", dir("three.exr"), "--spp", "4", "--set",
                        "shift.replay_vertices=2", "-o", dir("r.exr")},
                       dir("r.log"), plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("'shift.replay_vertices'"));

    // The validator: the shift with its parameter is reversible and its Jacobians match.
    r = test::run_tool(GDR_TOOL,
                       {"check-shift", kScene, "--shift", "late-reconnect", "--set", "replay_vertices=2", "--paths",
                        "400"},
                       dir("check.log"), plugins);
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK_THAT(r.output, Contains("PASS"));

    // Named errors: an unknown shift lists the registered ones (the
    // plugin's too), an unknown key or a bad value is named in full.
    r = render("e1.exr", {"shift=late-reconect"});
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown shift mapping 'late-reconect'") && Contains("late-reconnect") &&
                             Contains("half-vector"));
    r = render("e2.exr", {"shift.replay_vertice=2"});
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown parameter 'shift.replay_vertice'") && Contains("'late-reconnect'"));
    r = render("e3.exr", {"shift.replay_vertices=0"});
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("'shift.replay_vertices'") && Contains("1..1024"));
    // A built-in shift takes no parameter.
    r = test::run_tool(GDR_TOOL, {"render", kScene, "--integrator", "gpt", "--spp", "1", "--set", "shift.radius=2", "-o",
                                  dir("e4.exr")},
                       dir("e4.log"), plugins);
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown parameter 'shift.radius'") && Contains("'half-vector'"));
    for (const char* f : {"e1.exr", "e2.exr", "e3.exr", "e4.exr"}) CHECK_FALSE(std::filesystem::exists(dir(f)));
}

TEST_CASE("plugin files that are not gdr plugins are skipped, and named only where a name stays unknown",
          "[cli][plugins]") {
    const test::OutDir dir("plugins-skipped");
    std::filesystem::create_directories(dir("junk"));
    std::ofstream(dir("junk/libbroken.so")) << "not a shared library";
    // A real library without gdr's entry point.
    std::error_code ec;
    const char* libm = "/lib/x86_64-linux-gnu/libm.so.6";
    const bool have_libm = std::filesystem::exists(libm, ec);
    if (have_libm) std::filesystem::create_symlink(libm, dir("junk/libm.so"), ec);
    const std::string path = dir("junk") + ":" + GDR_EXAMPLE_PLUGIN_DIR;
    // Every name known: nothing is loaded, nothing said.
    test::ToolRun r = test::run_tool(GDR_TOOL,
                                     {"render", kScene, "--integrator", "gpt", "--spp", "1", "--set", "reconstruct=l2",
                                      "-o", dir("plain.exr")},
                                     dir("plain.log"), path.c_str());
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK_THAT(r.output, !Contains("libbroken.so"));
    // The plugin in the second directory is still found past the junk of the first.
    r = test::run_tool(GDR_TOOL,
                       {"render", kScene, "--integrator", "gpt", "--spp", "1", "--set", "shift=late-reconnect", "--set",
                        "reconstruct=jacobi-poisson", "-o", dir("found.exr")},
                       dir("found.log"), path.c_str());
    CHECK(r.status == 0);
    // Its preview shows the plugin's reconstruction (it showed "color" when
    // the preview knew only the built-in names).
    CHECK_THAT(r.output, Contains("found.png (reconstruction_jacobi-poisson)"));
    // A name no plugin registers: the skipped files are named, with why.
    r = test::run_tool(GDR_TOOL,
                       {"render", kScene, "--integrator", "gpt", "--spp", "1", "--set", "shift=nowhere", "-o",
                        dir("e.exr")},
                       dir("e.log"), path.c_str());
    CHECK(r.status == 1);
    CHECK_THAT(r.output, Contains("unknown shift mapping 'nowhere'") && Contains(dir("junk/libbroken.so")) &&
                             Contains("late-reconnect"));
    if (have_libm) CHECK_THAT(r.output, Contains(dir("junk/libm.so")) && Contains("not a gdr plugin"));
}

TEST_CASE("a plugin built for another gdr is skipped, naming both builds", "[cli][plugins]") {
    const test::OutDir dir("plugins-abi");
    const std::string plugin = GDR_WRONG_ABI_PLUGIN;
    const std::string path = std::filesystem::path(plugin).parent_path().string();
    const test::ToolRun r = test::run_tool(GDR_TOOL,
                                           {"render", kScene, "--integrator", "gpt", "--spp", "1", "--set",
                                            "shift=late-reconnect", "-o", dir("e.exr")},
                                           dir("e.log"), path.c_str());
    INFO(r.output);
    CHECK(r.status == 1);
    // Its shift is not registered: the file is named, with the two builds.
    CHECK_THAT(r.output, Contains("unknown shift mapping 'late-reconnect'") && Contains(plugin) &&
                             Contains("it was built for gdr 0.0, another compiler") && Contains("this gdr is"));
    CHECK_FALSE(std::filesystem::exists(dir("e.exr")));
}

TEST_CASE("reconstruct= takes registered names and their parameters, in the library too", "[cli][plugins]") {
    using Methods = std::vector<std::string>;
    CHECK(GradientReconstructions::methods_of("all", "t") == Methods{"poisson-weighted", "poisson-l1", "poisson-l2"});
    CHECK(GradientReconstructions::methods_of("l1+l2", "t") == Methods{"poisson-l1", "poisson-l2"});
    CHECK(GradientReconstructions::methods_of("none", "t").empty());
    CHECK(GradientReconstructions::methods_of("l2,mine", "t") == Methods{"poisson-l2", "mine"});
    CHECK_THROWS_AS(GradientReconstructions::methods_of("l2,", "t"), ParameterError);
    CHECK_THROWS_AS(GradientReconstructions::methods_of("l2,poisson-l2", "t"), ParameterError);
    CHECK(reconstruction_layer("poisson-l1") == "reconstruction_l1");
    CHECK(reconstruction_layer("mine") == "reconstruction_mine");

    const auto error_of = [](const std::vector<std::pair<std::string, std::string>>& kv) {
        Params p("test");
        for (const auto& [k, v] : kv) p.set_from_text(k + "=" + v);
        try {
            (void)integrator_registry().create("gpt", p);
        } catch (const ParameterError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    CHECK(error_of({{"reconstruct", "l1"}, {"reconstruct.iterations", "3"}}) == "");
    CHECK(error_of({{"reconstruct", "l1,l2"}, {"reconstruct.poisson-l1.iterations", "3"}}) == "");
    CHECK_THAT(error_of({{"reconstruct", "l1,l2"}, {"reconstruct.iterations", "3"}}),
               Contains("'reconstruct.iterations'") && Contains("reconstruct.<name>.iterations"));
    CHECK_THAT(error_of({{"reconstruct", "l2"}, {"reconstruct.iterations", "3"}}),
               Contains("unknown parameter 'reconstruct.iterations'") && Contains("'poisson-l2'"));
    CHECK_THAT(error_of({{"reconstruct", "none"}, {"reconstruct.alpha", "1"}}), Contains("'reconstruct.alpha'"));
    CHECK_THAT(error_of({{"reconstruct", "bogus"}}), Contains("unknown reconstructor 'bogus'") && Contains("poisson-l1"));
    CHECK_THAT(error_of({{"reconstruct", "neural"}, {"neural_weights", "x.pt"}}), Contains("reconstruct.weights"));
    CHECK_THAT(error_of({{"shift", "combined"}, {"shift.x", "1"}}), Contains("shift.<name>.x"));
}

#endif  // GDR_EXAMPLE_PLUGIN_DIR

#endif  // GDR_TOOL
