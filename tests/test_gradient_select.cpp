// Colour-gradient selection (thesis section 4.3.2): pixels without gradient
// samples (RenderSettings::gradient_mask) keep every pixel unbiased, cost a
// path tracer's sample, reconstruct to their primal, and are chosen where
// the weighted reconstruction's variance per second loses to the primal's.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "block_stats.h"
#include "cli_test_util.h"
#include "gdr/integrators/adaptive.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/reconstruct/reconstructor.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

constexpr int kRes = 24, kBlock = 4;

// Gradients in a checkerboard of 4x4 blocks, so that every block of the
// z-tests has masked edges inside and on its border.
Image checker_mask(int res) {
    Image m(res, res, 1);
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < res; ++x) m.at(x, y) = (x / kBlock + y / kBlock) % 2 ? 1.f : 0.f;
    return m;
}

FrameBuffer render_masked(const Scene& scene, long long spp, uint64_t seed, const Image* mask,
                          const Image* density = nullptr, RenderStats* stats = nullptr,
                          const std::string& integrator = "gpt") {
    auto integ = integrator_registry().create(integrator, Params("test"));
    RenderSettings st;
    st.spp = spp;
    st.seed = seed;
    st.gradient_mask = mask;
    st.sample_density = density;
    FrameBuffer fb;
    const RenderStats rs = integ->render(scene, st, fb);
    if (stats) *stats = rs;
    return fb;
}

double worst_relative(const Image& a, const Image& b) {
    double worst = 0.0;
    for (size_t i = 0; i < a.values().size(); ++i)
        worst = std::max(worst, std::abs(double(a.values()[i]) - b.values()[i]) /
                                    std::max(1e-3, std::abs(double(b.values()[i]))));
    return worst;
}

}  // namespace

TEST_CASE("gradient selection: without gradients every reconstruction is the primal", "[select]") {
    auto scene = test::small_box("Original", 20);
    const Image none(20, 20, 1);
    RenderStats masked, pt;
    const FrameBuffer fb = render_masked(*scene, 4, 11, &none, nullptr, &masked);
    render_masked(*scene, 4, 11, nullptr, nullptr, &pt, "pt");
    REQUIRE(fb.has("gradient_mask"));
    CHECK(fb.get("gradient_mask").values() == none.values());
    // Primal-only samples trace no offset paths: about a path tracer's rays.
    const double ray_ratio = double(masked.rays) / double(pt.rays);
    UNSCOPED_INFO("rays of primal-only gpt over pt's: " << ray_ratio);
    CHECK(ray_ratio > 0.9);
    CHECK(ray_ratio < 1.1);
    // The masked edges hold the primal's differences, so every method gives the primal back.
    const Image& p = fb.get("primal");
    for (int y = 0; y + 1 < 20; ++y)
        for (int x = 0; x + 1 < 20; ++x)
            for (int c = 0; c < 3; ++c) {
                CHECK(fb.get("dx").at(x, y, c) == p.at(x + 1, y, c) - p.at(x, y, c));
                CHECK(fb.get("dy").at(x, y, c) == p.at(x, y + 1, c) - p.at(x, y, c));
            }
    for (const char* r : {"reconstruction_weighted", "reconstruction_l1", "reconstruction_l2"}) {
        INFO(r);
        Image expect = fb.get("color");
        // poisson-weighted is exact; the DCT and CG solves to float rounding,
        // which for a transform of the whole image is relative to its
        // largest values (about 1 here): a few 1e-7 absolute, so up to a few
        // 1e-4 relative at a pixel near the 1e-3 floor (measured 1.2e-4).
        CHECK(worst_relative(fb.get(r), expect) < 5e-4);
    }
}

TEST_CASE("gradient selection: masked pixels and their neighbours stay unbiased", "[select][statistical]") {
    // 48 runs per set at 24x24 in blocks of 4x4, against uniform gpt renders of
    // 8 spp with their own run-to-run errors. The mask is a checkerboard of
    // blocks and the primal-only pixels take 3 times the samples. Measured max
    // z: primal 2.4, dx 2.6, dy 2.5 (over the edges with gradients at both
    // ends). Power: the primal-only pixels' estimates 8% low give z 11.5.
    auto scene = test::small_box("Original", kRes);
    const Image mask = checker_mask(kRes);
    Image density(kRes, kRes, 1);
    for (size_t i = 0; i < density.values().size(); ++i) density.values()[i] = mask.values()[i] != 0.f ? 0.5f : 1.5f;
    const int runs = 48;
    std::vector<FrameBuffer> uniform, masked;
    for (int r = 0; r < runs; ++r) {
        uniform.push_back(render_masked(*scene, 8, 1000 + r, nullptr));
        masked.push_back(render_masked(*scene, 8, 7000 + r, &mask, &density));
    }
    const test::BlockStats ref = test::grey_stats(uniform, "primal", kBlock);
    const test::BlockStats got = test::grey_stats(masked, "primal", kBlock);
    const double z = test::max_z(got, ref);
    UNSCOPED_INFO("primal max z " << z);
    CHECK(z < 4.5);
    // Power: the blocks without gradients 8% low (a third of the share a
    // masked pair would lose if the base did not estimate its pixel alone there).
    test::BlockStats low = got;
    const int bw = kRes / kBlock;
    for (size_t b = 0; b < low.mean.size(); ++b)
        if (mask.at(int(b % bw) * kBlock, int(b / bw) * kBlock) == 0.f) low.mean[b] *= 0.92;
    const double z_low = test::max_z(low, ref);
    UNSCOPED_INFO("with the primal-only blocks 8% low: " << z_low);
    CHECK(z_low > 8.0);
    // Gradients where both ends take them: blocks of single edges inside gradient blocks.
    for (const char* g : {"dx", "dy"}) {
        const bool horizontal = std::string(g) == "dx";
        const auto stats = [&](const std::vector<FrameBuffer>& fbs) {
            return test::block_stats(runs, kRes, kRes, kBlock, [&](int r, auto&& add) {
                const Image& im = fbs[r].get(g);
                for (int y = 0; y + 1 < kRes; ++y)
                    for (int x = 0; x + 1 < kRes; ++x) {
                        const int qx = horizontal ? x + 1 : x, qy = horizontal ? y : y + 1;
                        if (mask.at(x, y) != 0.f && mask.at(qx, qy) != 0.f) add(x, y, test::grey(im, x, y));
                    }
            });
        };
        test::BlockStats a = stats(masked), u = stats(uniform);
        // Blocks without such edges hold 0 in both.
        const double zg = test::max_z(a, u);
        UNSCOPED_INFO(g << " max z " << zg);
        CHECK(zg < 4.5);
    }
}

TEST_CASE("gradient selection: the variance model is the weighted L2 solve's", "[select][statistical]") {
    // White noise of per-sample variances vp (primal) and vg (gradients, true
    // image flat), 2 samples per pixel, reconstructed by poisson-weighted in
    // its L2 form without outlier test or energy tie: on a 64x64 image the
    // mean over pixels of the solution's variance is vp / 2 * F(vg / vp)
    // exactly (F averages over the DCT eigenvalues of this very grid).
    // 40 runs: measured within 2% for r = 0.05, 1 and 20; F(2r) differs from
    // F(r) by 75%, 50% and 8% there, so a model off by the factor of the two
    // gradient rows fails the 8% tolerance at r = 0.05 and 1.
    const int N = 64, runs = 40;
    std::mt19937 rng(5);
    for (double r : {0.05, 1.0, 20.0}) {
        INFO("r = " << r);
        const double vp = 0.01, vg = r * vp;
        double sum_var = 0.0;
        std::vector<double> mean(size_t(N) * N, 0.0), sq(size_t(N) * N, 0.0);
        for (int run = 0; run < runs; ++run) {
            std::normal_distribution<double> np(0.0, std::sqrt(vp / 2)), ng(0.0, std::sqrt(vg / 2));
            FrameBuffer fb(N, N);
            for (const char* l : {"primal", "dx", "dy", "primal_variance", "dx_variance", "dy_variance"}) fb.add(l, 3);
            fb.add("spp", 1);
            for (int y = 0; y < N; ++y)
                for (int x = 0; x < N; ++x) {
                    fb.get("spp").at(x, y) = 2.f;
                    for (int c = 0; c < 3; ++c) {
                        fb.get("primal").at(x, y, c) = float(0.5 + np(rng));
                        fb.get("dx").at(x, y, c) = float(ng(rng));
                        fb.get("dy").at(x, y, c) = float(ng(rng));
                        fb.get("primal_variance").at(x, y, c) = float(vp);
                        fb.get("dx_variance").at(x, y, c) = float(vg);
                        fb.get("dy_variance").at(x, y, c) = float(vg);
                    }
                }
            Params p("test");
            p.set_from_text("norm=l2");
            p.set_from_text("outliers=none");
            p.set_from_text("energy=none");
            p.set_from_text("tolerance=1e-7");
            p.set_from_text("cg_iterations=2000");
            const Image out = reconstruct("poisson-weighted", p, gradient_buffers(fb));
            for (int y = 0; y < N; ++y)
                for (int x = 0; x < N; ++x) {
                    const double v = out.at(x, y, 0);
                    mean[size_t(y) * N + x] += v, sq[size_t(y) * N + x] += v * v;
                }
        }
        for (size_t i = 0; i < mean.size(); ++i) {
            const double m = mean[i] / runs;
            sum_var += (sq[i] - runs * m * m) / (runs - 1);
        }
        const double measured = sum_var / double(mean.size()) / (vp / 2);
        UNSCOPED_INFO("measured " << measured << ", F(r) " << gls_variance_factor(r) << ", F(2r) "
                                  << gls_variance_factor(2 * r));
        CHECK(measured == Approx(gls_variance_factor(r)).epsilon(0.08));
    }
    CHECK(gls_variance_factor(0.0) == 0.0);
    CHECK(gls_variance_factor(1e9) == Approx(1.0).epsilon(1e-6));
    for (double r = 1e-4; r < 1e4; r *= 3) CHECK(gls_variance_factor(3 * r) > gls_variance_factor(r));
}

TEST_CASE("gradient selection: tiles keep gradients where they pay per second", "[select]") {
    // Synthetic pilots of 32x16: the left 16x16 tile has gradients 10 times
    // less noisy than its primal, the right one 10 times noisier; a gradient
    // sample costs 2.5 primal-only ones, whose variance equals the primal's.
    FrameBuffer g(32, 16), p(32, 16);
    for (const char* l : {"primal_variance", "dx_variance", "dy_variance"}) g.add(l, 3);
    p.add("primal_variance", 3);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 32; ++x)
            for (int c = 0; c < 3; ++c) {
                g.get("primal_variance").at(x, y, c) = 1.f;
                p.get("primal_variance").at(x, y, c) = 1.f;
                g.get("dx_variance").at(x, y, c) = g.get("dy_variance").at(x, y, c) = x < 16 ? 0.1f : 10.f;
            }
    const GradientSelection s = select_gradient_pixels(g, 2.5, p, 1.0);
    UNSCOPED_INFO("F(0.1) " << gls_variance_factor(0.1) << ", F(10) " << gls_variance_factor(10.0));
    CHECK(s.cost_ratio == Approx(2.5));
    CHECK(s.gradient_share == Approx(0.5));
    CHECK(s.mask.at(3, 3) == 1.f);
    CHECK(s.mask.at(20, 3) == 0.f);
    // Equal time per pixel, mean density 1: 1 / 1.75 and 2.5 / 1.75.
    CHECK(s.density.at(3, 3) == Approx(1.0 / 1.75));
    CHECK(s.density.at(20, 3) == Approx(2.5 / 1.75));
    // A gradient sample 100 times dearer: no tile pays, and the density is capped at max_density.
    const GradientSelection dear = select_gradient_pixels(g, 100.0, p, 1.0);
    CHECK(dear.gradient_share == 0.0);
    CHECK(dear.density.at(3, 3) == Approx(1.0));
    // Errors name what is wrong.
    FrameBuffer bad = p;
    CHECK_THROWS_WITH(select_gradient_pixels(bad, 1.0, p, 1.0), Contains("dx_variance"));
    CHECK_THROWS_WITH(select_gradient_pixels(g, 0.0, p, 1.0), Contains("seconds per pass"));
    CHECK_THROWS_WITH(select_gradient_pixels(g, 1.0, FrameBuffer(8, 8), 1.0), Contains("32x16 and 8x8"));
    GradientSelectOptions o;
    o.tile = 0;
    CHECK_THROWS_WITH(select_gradient_pixels(g, 1.0, p, 1.0, o), Contains("tile"));
}

TEST_CASE("gradient selection: the measured criterion compares the renders' spreads", "[select]") {
    // Two gradient pilots whose reconstructions differ by 0.1 in the left
    // tile and by 1 in the right one, and two primal-only pilots differing by
    // 0.3 everywhere, at equal cost per pass and passes: the left tile keeps
    // its gradients (spread 0.1 < 0.3), the right one does not (1 > 0.3).
    // At 20 times the cost per pass, neither does (20 * 0.01 > 0.09).
    FrameBuffer g[2] = {FrameBuffer(32, 16), FrameBuffer(32, 16)}, p[2] = {FrameBuffer(32, 16), FrameBuffer(32, 16)};
    for (int i = 0; i < 2; ++i) {
        g[i].add("color", 3), g[i].add("reconstruction_weighted", 3), p[i].add("color", 3);
        for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 32; ++x)
                for (int c = 0; c < 3; ++c) {
                    const float sign = i ? 1.f : -1.f;
                    g[i].get("color").at(x, y, c) = 1.f;
                    g[i].get("reconstruction_weighted").at(x, y, c) = 1.f + sign * (x < 16 ? 0.05f : 0.5f);
                    p[i].get("color").at(x, y, c) = 1.f + sign * 0.15f;
                }
    }
    SelectionPilots pl;
    pl.gradient[0] = &g[0], pl.gradient[1] = &g[1], pl.primal[0] = &p[0], pl.primal[1] = &p[1];
    pl.gradient_passes = pl.primal_passes = 4;
    pl.gradient_seconds_per_pass = pl.primal_seconds_per_pass = 1.0;
    const GradientSelection s = select_gradient_pixels(pl);
    CHECK(s.mask.at(3, 3) == 1.f);
    CHECK(s.mask.at(20, 3) == 0.f);
    CHECK(s.gradient_share == Approx(0.5));
    pl.gradient_seconds_per_pass = 20.0;
    CHECK(select_gradient_pixels(pl).gradient_share == 0.0);
    pl.primal[1] = nullptr;
    CHECK_THROWS_WITH(select_gradient_pixels(pl), Contains("a pilot is missing"));
}

TEST_CASE("gradient selection: render_adaptive, masks refused, merged and resumed", "[select][cli]") {
    auto scene = test::small_box("Glossy", 24);
    auto gpt = integrator_registry().create("gpt", Params("test"));
    RenderSettings st;
    st.spp = 8;
    st.seed = 2;
    AdaptiveRender ad;
    ad.pilot = 0.25;
    ad.mode = AdaptiveRender::Mode::SelectGradients;
    FrameBuffer fb;
    render_adaptive(*gpt, *scene, st, fb, ad);
    REQUIRE(fb.has("gradient_mask"));
    REQUIRE(fb.has("sample_density"));
    CHECK(fb.metadata().count("gradient_share") == 1);
    // Timed on 24x24 pilots: set-up costs weigh as much as samples there, so only its presence is checked.
    CHECK(std::stod(fb.metadata().at("gradient_cost_ratio")) > 0.0);
    CHECK(fb.metadata().at("spp") == "6");
    // The measured criterion: two pilots of each kind.
    ad.select.criterion = GradientSelectOptions::Criterion::Measured;
    FrameBuffer measured;
    render_adaptive(*gpt, *scene, st, measured, ad);
    CHECK(measured.has("gradient_mask"));
    CHECK(measured.metadata().at("adaptive_pilot_spp") == "2");  // two gradient pilots of 1 pass
    ad.select.criterion = GradientSelectOptions::Criterion::Model;
    auto pt = integrator_registry().create("pt", Params("test"));
    CHECK_THROWS_WITH(render_adaptive(*pt, *scene, st, fb, ad), Contains("does not take one"));
    // Keeping the gradient pilot: merged per pixel, its edges refilled where the render has no gradients.
    ad.keep_pilot = true;
    render_adaptive(*gpt, *scene, st, fb, ad);
    CHECK(fb.metadata().at("sample_density") == "mixed");
    const Image& mask = fb.get("gradient_mask");
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x + 1 < 24; ++x)
            if (mask.at(x, y) == 0.f || mask.at(x + 1, y) == 0.f)
                CHECK(fb.get("dx").at(x, y, 1) == fb.get("primal").at(x + 1, y, 1) - fb.get("primal").at(x, y, 1));
    auto tgpt = integrator_registry().create("tgpt", Params("test"));
    const Image none(24, 24, 1);
    st.gradient_mask = &none;
    CHECK_THROWS_WITH(tgpt->render(*scene, st, fb), Contains("does not take one"));
    Image half = none;
    half.at(3, 3) = 0.5f;
    st.gradient_mask = &half;
    CHECK_THROWS_WITH(gpt->render(*scene, st, fb), Contains("pixel (3, 3) holds 0.5"));
    // Renders of different masks do not merge.
    st.gradient_mask = &none;
    FrameBuffer a, b;
    gpt->render(*scene, st, a);
    st.gradient_mask = nullptr;
    st.seed = 3;
    gpt->render(*scene, st, b);
    CHECK_THROWS_WITH(merge_renders(a, b), Contains("gradient_mask"));

    // The tool: --select-gradients, and --resume keeps mask and density.
    test::OutDir dir("select-cli");
    const std::string file = std::string(GDR_SOURCE_DIR) + "/scenes/cornell-box/scene.json";
    const auto run = [&](std::vector<std::string> extra) {
        std::vector<std::string> args{"render", file, "--integrator", "gpt", "--width", "24", "--threads", "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        test::stdout_of([&] { cli::run(args); });
    };
    run({"--spp", "8", "--select-gradients", "0.25", "--seed", "3", "-o", dir("s.exr")});
    const FrameBuffer s = read_exr(dir("s.exr"));
    REQUIRE(s.has("gradient_mask"));
    run({"--resume", dir("s.exr"), "--spp", "10", "-o", dir("r.exr")});
    const FrameBuffer r = read_exr(dir("r.exr"));
    CHECK(r.get("gradient_mask").values() == s.get("gradient_mask").values());
    CHECK(r.get("sample_density").values() == s.get("sample_density").values());
    CHECK(r.metadata().at("spp") == "10");
    CHECK_THAT(test::error_of({"render", file, "--adaptive", "0.2", "--select-gradients", "0.2", "-o", dir("x.exr")}),
               Contains("give one of them"));
    CHECK_THAT(test::error_of({"render", file, "--resume", dir("s.exr"), "--select-gradients", "0.2", "-o",
                               dir("x.exr")}),
               Contains("takes no --select-gradients"));
}
