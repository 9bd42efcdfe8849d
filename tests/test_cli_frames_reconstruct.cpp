// gdr reconstruct --frames: a frame sequence through the spatio-temporal solve, from the command line.
#include <catch2/catch.hpp>

#include <cmath>

#include "cli_test_util.h"
#include "gdr/io/exr.h"

using namespace gdr;
using namespace gdr::test;

namespace {

// Frame k of a brightening video with exact gradients and temporal differences (no motion).
FrameBuffer exact_frame(int k, int last, bool with_dt) {
    const int W = 9, H = 7;
    const auto value = [](int x, int y, int k) { return 0.2f + 0.05f * float(x) + 0.03f * float(y) + 0.1f * float(k); };
    FrameBuffer fb(W, H);
    Image p(W, H, 3), dx(W, H, 3), dy(W, H, 3), dt(W, H, 3);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < 3; ++c) {
                p.at(x, y, c) = value(x, y, k);
                if (x + 1 < W) dx.at(x, y, c) = value(x + 1, y, k) - value(x, y, k);
                if (y + 1 < H) dy.at(x, y, c) = value(x, y + 1, k) - value(x, y, k);
                dt.at(x, y, c) = k < last ? value(x, y, k + 1) - value(x, y, k) : 0.f;
            }
    fb.set("primal", std::move(p));
    fb.set("dx", std::move(dx));
    fb.set("dy", std::move(dy));
    if (with_dt) fb.set("dt", std::move(dt));
    return fb;
}

}  // namespace

TEST_CASE("cli: reconstruct --frames solves a sequence and names what is wrong", "[cli][temporal]") {
    OutDir dir("reconstruct-frames");
    const int last = 6;
    for (int k = 0; k <= last; ++k) write_exr(dir("in." + std::to_string(k) + ".exr"), exact_frame(k, last, true));
    REQUIRE(error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:6", "-o", dir("out.%04d.exr")}) == "");
    for (int k = 0; k <= last; ++k) {
        const FrameBuffer out = read_exr(dir("out.000" + std::to_string(k) + ".exr"));
        const FrameBuffer ref = exact_frame(k, last, true);
        double worst = 0;
        for (size_t i = 0; i < ref.get("primal").values().size(); ++i)
            worst = std::max(worst, double(std::abs(out.get("color").values()[i] - ref.get("primal").values()[i]) /
                                           ref.get("primal").values()[i]));
        INFO("frame " << k);
        CHECK(worst < 1e-5);  // exact inputs give back the frames
    }
    // An output never replaces an input; patterns are required; a missing layer names its file.
    CHECK(error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:6", "-o", dir("in.%d.exr")}) != "");
    CHECK(error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:6", "-o", dir("out.exr")}).find("pattern") !=
          std::string::npos);
    CHECK(error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:6", "--method", "poisson-l1", "-o",
                    dir("o2.%d.exr")})
              .find("temporal") != std::string::npos);
    write_exr(dir("in.3.exr"), exact_frame(3, last, false));
    const std::string e = error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:6", "-o", dir("o3.%d.exr")});
    CAPTURE(e);
    CHECK(e.find("in.3.exr") != std::string::npos);
    CHECK(e.find("dt") != std::string::npos);
    CHECK(error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:9", "-o", dir("o4.%d.exr")}).find("in.7.exr") !=
          std::string::npos);
}
