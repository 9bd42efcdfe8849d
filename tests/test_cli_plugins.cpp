// The gdr tool's plugin loading (gdr/cli/plugins.h) where the plugin is not
// there: GDR_PLUGIN_PATH points the search at a directory without it, so
// these run alike in builds with and without libtorch. They run the real
// binary, whose plugin search happens once per process.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>

#include "cli_test_util.h"
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

#endif  // GDR_TOOL
