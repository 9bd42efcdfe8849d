// Combined shifts (thesis section 4.3.6): gpt with shift=combined shifts each
// base path with two shifts and weighs their gradients by their variances
// and covariance. The combination must estimate the same gradients, and be
// no noisier than the better of the two.
#include <catch2/catch.hpp>

#include <algorithm>
#include <string>
#include <vector>

#include "block_stats.h"
#include "gdr/integrators/integrator.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

// Across-run variance of layer `layer`'s grey value, summed over the pixels.
double spread(const std::vector<FrameBuffer>& fbs, const std::string& layer) {
    const int w = fbs[0].width(), h = fbs[0].height();
    double total = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double m = 0.0, q = 0.0;
            for (const FrameBuffer& fb : fbs) m += test::grey(fb.get(layer), x, y);
            m /= double(fbs.size());
            for (const FrameBuffer& fb : fbs) {
                const double d = test::grey(fb.get(layer), x, y) - m;
                q += d * d;
            }
            total += q / double(fbs.size() - 1);
        }
    return total;
}

}  // namespace

TEST_CASE("combined shifts: unbiased gradients no noisier than the better shift", "[combined][statistical]") {
    // The glass-sphere box, where half-vector and replay-reconnect differ (at
    // the specular vertices); 96 runs of 8 spp at 24x24, blocks of 4x4.
    auto scene = test::small_box("Sphere", 24);
    const int runs = 96;
    std::vector<FrameBuffer> combined, plain;
    for (int r = 0; r < runs; ++r) {
        combined.push_back(test::render(*scene, "gpt", test::params({{"shift", "combined"}, {"reconstruct", "none"}}), 8,
                                        100 + r));
        plain.push_back(test::render(*scene, "gpt", test::params({{"reconstruct", "none"}}), 8, 900 + r));
    }
    for (const char* g : {"dx", "dy"}) {
        INFO(g);
        const test::BlockStats ref = test::grey_stats(plain, g, 4), got = test::grey_stats(combined, g, 4);
        const double z = test::max_z(got, ref);
        const double z_wrong = test::max_z(test::scaled(got, 1.5), ref);
        UNSCOPED_INFO(g << ": max z " << z << ", scaled by 1.5: " << z_wrong);
        CHECK(z < 4.5);
        CHECK(z_wrong > 6.0);
        // Each shift's own layer is the render that shift alone would give.
        for (const char* s : {"half-vector", "replay-reconnect"}) {
            const double zs = test::max_z(test::grey_stats(combined, std::string(g) + "_" + s, 4), ref);
            UNSCOPED_INFO(g << "_" << s << ": max z " << zs);
            CHECK(zs < 4.5);
        }
        const double v = spread(combined, g), v1 = spread(combined, std::string(g) + "_half-vector"),
                     v2 = spread(combined, std::string(g) + "_replay-reconnect");
        UNSCOPED_INFO(g << " across-run variance: combined " << v << ", half-vector " << v1 << ", replay-reconnect "
                        << v2);
        // Measured: dx 9.60 against 10.79 and 11.35, dy 14.02 against 14.38
        // and 14.86; weights that ignore the covariance gave 9.86 and 14.12.
        CHECK(v <= 1.02 * std::min(v1, v2));
    }
    // The plain half-vector render equals the combined render's first shift, bit for bit.
    const FrameBuffer a = test::render(*scene, "gpt", test::params({{"shift", "combined"}, {"reconstruct", "none"}}), 2, 7);
    const FrameBuffer b = test::render(*scene, "gpt", test::params({{"reconstruct", "none"}}), 2, 7);
    CHECK(a.get("dx_half-vector").values() == b.get("dx").values());
    CHECK(a.get("primal").values() == b.get("primal").values());
}

TEST_CASE("combined shifts: bad shift lists are named", "[combined]") {
    auto scene = test::small_box("Original", 4);
    CHECK_THROWS_WITH(test::render(*scene, "gpt", test::params({{"shift", "combined"}, {"shifts", "half-vector"}}), 1, 1),
                      Contains("two shifts"));
    CHECK_THROWS_WITH(
        test::render(*scene, "gpt", test::params({{"shift", "combined"}, {"shifts", "replay,replay"}}), 1, 1),
        Contains("two different"));
    CHECK_THROWS_WITH(
        test::render(*scene, "gpt", test::params({{"shift", "combined"}, {"shifts", "replay,nonesuch"}}), 1, 1),
        Contains("nonesuch"));
}
