// gdr compare through gdr::cli::run on small hand-made EXRs: which layers it
// compares by default and on request, how it matches sizes and channel
// counts, and that it names the file, layer and pixel of what it refuses.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <cstdio>
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

std::string out(const std::string& name) {
    static const test::OutDir dir("compare");
    return dir(name);
}

// What cli::run(args) prints to stdout; `rc` gets its return value.
std::string stdout_of(const std::vector<std::string>& args, int* rc = nullptr) {
    int r = 0;
    const std::string text = test::stdout_of([&] { r = cli::run(args); });
    if (rc) *rc = r;
    return text;
}

// The message of the gdr::Error that compare throws, its report silenced ("" if none).
std::string error_of(const std::vector<std::string>& args) {
    try {
        stdout_of(args);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

// The number after "NAME:" at the start of a line of compare's report (NaN if absent).
double metric(const std::string& report, const std::string& name) {
    const std::string key = "\n" + name + ":";
    const size_t at = ("\n" + report).find(key);
    if (at == std::string::npos) return std::numeric_limits<double>::quiet_NaN();
    return std::stod(report.substr(at + key.size() - 1));
}

// A smooth RGB pattern in [0.1, 0.9].
Image pattern(int w, int h, int c = 3) {
    Image img(w, h, c);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int k = 0; k < c; ++k) img.at(x, y, k) = 0.5f + 0.4f * float(((x * 7 + y * 3 + k * 5) % 11) - 5) / 5.f;
    return img;
}

// `img` with every value shifted alternately up and down by 0.1: noise of MSE 0.01.
Image noisy(const Image& img) {
    Image n = img;
    for (size_t i = 0; i < n.values().size(); ++i) n.values()[i] += i % 2 ? 0.1f : -0.1f;
    return n;
}

std::string write_layers(const std::string& name, const std::vector<std::pair<std::string, Image>>& layers) {
    FrameBuffer fb(layers.front().second.width(), layers.front().second.height());
    for (const auto& [n, img] : layers) fb.set(n, img);
    write_exr(out(name), fb);
    return out(name);
}

}  // namespace

TEST_CASE("compare: a gradient-domain render is compared by its final image unless --layer says otherwise",
          "[compare][cli]") {
    const Image truth = pattern(8, 6);
    // Like a gpt render: noisy colour and primal beside an exact L1 reconstruction.
    const std::string gpt = write_layers("gpt.exr", {{"color", noisy(truth)}, {"primal", noisy(truth)},
                                                     {"reconstruction_l1", truth}});
    const std::string pt_ref = write_layers("pt-ref.exr", {{"color", truth}});

    const std::string rep = stdout_of({"compare", gpt, pt_ref});
    INFO(rep);
    // Which layer of which file comes first, before any number.
    CHECK(rep.rfind("image:         " + gpt + " layer 'reconstruction_l1'", 0) == 0);
    CHECK_THAT(rep, Contains("reference:     " + pt_ref + " layer 'color'"));
    CHECK(metric(rep, "MSE") == 0.0);

    const std::string col = stdout_of({"compare", gpt, pt_ref, "--layer", "color"});
    INFO(col);
    CHECK_THAT(col, Contains(gpt + " layer 'color' (--layer)") && Contains(pt_ref + " layer 'color' (--layer"));
    CHECK(metric(col, "MSE") == Approx(0.01).epsilon(1e-4));

    // The PT reference has no primal: it is held against its own final image.
    const std::string prim = stdout_of({"compare", gpt, pt_ref, "--layer", "primal"});
    INFO(prim);
    CHECK_THAT(prim, Contains(gpt + " layer 'primal'") &&
                         Contains(pt_ref + " layer 'color' (its final image; it has no layer 'primal')"));
    CHECK(metric(prim, "MSE") == Approx(0.01).epsilon(1e-4));

    // Two gpt renders: --layer applies to both; --ref-layer picks the reference's separately.
    const std::string both = stdout_of({"compare", gpt, gpt, "--layer", "primal"});
    CHECK_THAT(both, Contains("reference:     " + gpt + " layer 'primal'"));
    CHECK(metric(both, "MSE") == 0.0);
    const std::string mixed = stdout_of({"compare", gpt, gpt, "--layer", "primal", "--ref-layer", "reconstruction_l1"});
    CHECK_THAT(mixed, Contains(gpt + " layer 'reconstruction_l1' (--ref-layer)"));
    CHECK(metric(mixed, "MSE") == Approx(0.01).epsilon(1e-4));

    CHECK_THAT(error_of({"compare", gpt, pt_ref, "--layer", "dx"}),
               Contains("--layer") && Contains("gpt.exr") && Contains("'dx'") && Contains("reconstruction_l1"));
    CHECK_THAT(error_of({"compare", gpt, pt_ref, "--ref-layer", "primal"}),
               Contains("--ref-layer") && Contains("pt-ref.exr") && Contains("'primal'"));
}

TEST_CASE("compare: per-channel means and their ratio, n/a for a black reference channel", "[compare][cli]") {
    const std::string a = write_layers("means-a.exr", {{"color", Image(4, 4, 3, 0.5f)}});
    Image r(4, 4, 3);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) r.set_rgb(x, y, Color(0.25f, 0.5f, 0.f));
    const std::string b = write_layers("means-b.exr", {{"color", r}});
    const std::string rep = stdout_of({"compare", a, b});
    INFO(rep);
    CHECK_THAT(rep, Contains("mean R:") && Contains("ratio 2)") && Contains("ratio 1)"));
    CHECK_THAT(rep, Contains("mean B:") && Contains("n/a"));
}

TEST_CASE("compare: sizes that differ by one integer factor are box-downsampled, others refused naming both",
          "[compare][cli]") {
    const Image small = pattern(8, 6);
    // Each 2x2 block of the large reference averages to the small image's pixel.
    Image large(16, 12, 3);
    for (int y = 0; y < 12; ++y)
        for (int x = 0; x < 16; ++x)
            for (int k = 0; k < 3; ++k)
                large.at(x, y, k) = small.at(x / 2, y / 2, k) + ((x + y) % 2 ? 0.05f : -0.05f);
    const std::string img = write_layers("small.exr", {{"color", small}});
    const std::string ref = write_layers("large.exr", {{"color", large}});

    const std::string rep = stdout_of({"compare", img, ref});
    INFO(rep);
    CHECK_THAT(rep, Contains("downsampled the reference from 16x12 to 8x6") && Contains("automatically"));
    CHECK(metric(rep, "MSE") == Approx(0.0).margin(1e-12));
    const std::string expl = stdout_of({"compare", ref, img, "--downsample", "2"});
    CHECK_THAT(expl, Contains("downsampled the image from 16x12 to 8x6") && Contains("--downsample"));
    CHECK(metric(expl, "MSE") == Approx(0.0).margin(1e-12));

    const std::string wrong_k = error_of({"compare", img, ref, "--downsample", "3"});
    CHECK_THAT(wrong_k, Contains("--downsample 3") && Contains("8x6") && Contains("16x12"));
    CHECK_THAT(error_of({"compare", img, img, "--downsample", "2"}), Contains("--downsample 2") && Contains("8x6"));

    // 3x horizontally but 2x vertically: no one factor.
    const std::string wide = write_layers("wide.exr", {{"color", pattern(24, 12)}});
    const std::string msg = error_of({"compare", wide, img});
    CHECK_THAT(msg, Contains("24x12") && Contains("8x6") && Contains("wide.exr") && Contains("small.exr"));
    const std::string tall = write_layers("tall.exr", {{"color", pattern(4, 12)}});
    CHECK_THAT(error_of({"compare", tall, img}), Contains("4x12") && Contains("8x6"));
}

TEST_CASE("compare: grey is broadcast against RGB, other channel mismatches refused", "[compare][cli]") {
    const std::string grey = write_layers("grey.exr", {{"color", Image(4, 4, 1, 0.5f)}});
    const std::string rgb = write_layers("rgb.exr", {{"color", Image(4, 4, 3, 0.5f)}});
    const std::string rep = stdout_of({"compare", grey, rgb});
    CHECK_THAT(rep, Contains("broadcast the image's grey channel to RGB"));
    CHECK(metric(rep, "MSE") == 0.0);
    const std::string two = write_layers("two.exr", {{"uv", Image(4, 4, 2)}});
    CHECK_THAT(error_of({"compare", two, rgb}), Contains("two.exr") && Contains("'uv'") && Contains("2 channels"));
}

TEST_CASE("compare: a NaN is refused naming the file, layer and pixel", "[compare][cli][errors]") {
    Image bad = pattern(8, 6);
    bad.at(5, 3, 1) = std::numeric_limits<float>::quiet_NaN();
    const std::string ref = write_layers("finite.exr", {{"color", pattern(8, 6)}});
    const std::string nan = write_layers("nan.exr", {{"color", pattern(8, 6)}, {"reconstruction_l1", bad}});
    const std::string msg = error_of({"compare", nan, ref});
    CHECK_THAT(msg, Contains("nan.exr") && Contains("reconstruction_l1") && Contains("(5, 3)"));
    CHECK_THAT(error_of({"compare", ref, nan, "--ref-layer", "reconstruction_l1"}),
               Contains("reference") && Contains("nan.exr") && Contains("(5, 3)"));
}

TEST_CASE("compare: --help prints compare's usage and succeeds", "[compare][cli]") {
    for (const char* h : {"--help", "-h"}) {
        int rc = -1;
        const std::string text = stdout_of({"compare", h}, &rc);
        CHECK(rc == 0);
        CHECK_THAT(text, Contains("gdr compare") && Contains("--layer") && Contains("--ref-layer") &&
                             Contains("--downsample"));
    }
    CHECK_THAT(error_of({"compare", "a.exr", "b.exr", "--frobnicate"}), Contains("'--frobnicate'"));
}
