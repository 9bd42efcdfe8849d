// Adaptive sampling: per-pixel sample counts keep every pixel unbiased (for
// pt's own-pixel estimates and for G-PT, whose pixels also gather their
// neighbours' offsets), the density from a pilot puts samples where the
// gradients are noisy, and a render's counts are recorded and checked.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "block_stats.h"
#include "cli_test_util.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/integrators/adaptive.h"
#include "gdr/integrators/integrator.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

constexpr int kRes = 24, kBlock = 4;

// A density that changes from block to block of the z-tests (0.5 or 2.5, so
// that dividing by the pass count instead of the pixel's own count moves a
// block's mean by a factor of 0.5 or 2.5) and from pixel to pixel within a
// block (so that G-PT's neighbours differ in count inside blocks too).
Image test_density(int res) {
    Image d(res, res, 1);
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < res; ++x)
            d.at(x, y) = ((x / kBlock + y / kBlock) % 2 ? 2.5f : 0.5f) + 0.25f * float((x + y) % 2);
    return d;
}

FrameBuffer render_with(const Scene& scene, const std::string& integrator, long long spp, uint64_t seed,
                        const Image* density, const Params& p = Params("test")) {
    auto integ = integrator_registry().create(integrator, p);
    RenderSettings st;
    st.spp = spp;
    st.seed = seed;
    st.sample_density = density;
    FrameBuffer fb;
    integ->render(scene, st, fb);
    return fb;
}

// The deliberately wrong estimate: each pixel's sum over the pass count
// instead of its own count, i.e. the adaptive mean times count / passes.
FrameBuffer divided_by_passes(FrameBuffer fb, const std::string& layer, long long passes) {
    Image& im = fb.get(layer);
    const Image& n = fb.get("spp");
    for (int y = 0; y < im.height(); ++y)
        for (int x = 0; x < im.width(); ++x) im.set_rgb(x, y, im.rgb(x, y) * (n.at(x, y) / float(passes)));
    return fb;
}

}  // namespace

TEST_CASE("adaptive: a density of one everywhere renders the uniform image bit for bit", "[adaptive]") {
    auto scene = test::small_box("Original", 16);
    Image ones(16, 16, 1);
    std::fill(ones.values().begin(), ones.values().end(), 1.f);
    for (const char* integrator : {"pt", "gpt", "tgpt"}) {
        INFO(integrator);
        const FrameBuffer u = render_with(*scene, integrator, 3, 7, nullptr);
        const FrameBuffer a = render_with(*scene, integrator, 3, 7, &ones);
        for (const std::string& name : u.names()) {
            INFO(name);
            REQUIRE(a.has(name));
            CHECK(a.get(name).values() == u.get(name).values());
        }
        CHECK(a.get("sample_density").values() == ones.values());
    }
}

TEST_CASE("adaptive: each pixel takes its own count and records it", "[adaptive]") {
    auto scene = test::small_box("Original", kRes);
    const Image d = test_density(kRes);
    const FrameBuffer fb = render_with(*scene, "gpt", 5, 3, &d);
    const Image& spp = fb.get("spp");
    double total = 0.0;
    for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) {
            CHECK(spp.at(x, y) == float(sample_count(5, d.at(x, y))));
            total += spp.at(x, y);
        }
    CHECK(fb.metadata().at("spp") == "5");
    double mean_d = 0.0;
    for (float v : d.values()) mean_d += v;
    CHECK(total == Approx(5.0 * mean_d).epsilon(0.05));
    // Counts never decrease as passes are added, and every pixel has a sample.
    for (float v : {0.f, 0.01f, 0.3f, 1.f, 2.5f, 7.7f})
        for (long long j = 0; j < 40; ++j) {
            CHECK(sample_count(j + 1, v) >= sample_count(j, v));
            if (j > 0) CHECK(sample_count(j, v) >= 1);
        }
}

TEST_CASE("adaptive: unequal per-pixel counts keep pt and gpt unbiased", "[adaptive][statistical]") {
    // 48 runs of 4 passes per method at 24x24, blocks of 4x4: the uniform
    // renders (8 spp) are the reference, with their own run-to-run errors.
    // Measured max z 1.5-2.5. Wrong variants: each pixel's sum over the pass
    // count gives z 120-147; G-PT's pair weights with a share a = n_p /
    // (n_p + n_q) read from the wrong neighbour (so the two pixels' weights no
    // longer sum to one) gave primal z 31.8, dx 6.5, dy 11.0.
    auto scene = test::small_box("Original", kRes);
    const Image d = test_density(kRes);
    const int runs = 48;
    for (const char* integrator : {"pt", "gpt", "tgpt"}) {
        INFO(integrator);
        const std::string layer = std::string(integrator) == "pt" ? "color" : "primal";
        std::vector<FrameBuffer> uniform, adaptive, wrong;
        for (int r = 0; r < runs; ++r) {
            uniform.push_back(render_with(*scene, integrator, 8, 1000 + r, nullptr));
            adaptive.push_back(render_with(*scene, integrator, 4, 5000 + r, &d));
            wrong.push_back(divided_by_passes(adaptive.back(), layer, 4));
        }
        const test::BlockStats ref = test::grey_stats(uniform, layer, kBlock);
        const double z = test::max_z(test::grey_stats(adaptive, layer, kBlock), ref);
        const double z_wrong = test::max_z(test::grey_stats(wrong, layer, kBlock), ref);
        UNSCOPED_INFO("max z " << z << ", dividing by the passes instead: " << z_wrong);
        CHECK(z < 4.5);
        CHECK(z_wrong > 8.0);
        if (layer == "primal") {
            // The gradients too: they combine the pixel's own and its neighbour's samples.
            for (const char* g : {"dx", "dy"}) {
                const double zg = test::max_z(test::grey_stats(adaptive, g, kBlock), test::grey_stats(uniform, g, kBlock));
                UNSCOPED_INFO(g << " max z " << zg);
                CHECK(zg < 4.5);
            }
        }
    }
}

TEST_CASE("adaptive: the variance layers over a pixel's count are its estimate's variance", "[adaptive][statistical]") {
    // G-PT's primal gathers neighbours' offsets, each a mean over the
    // neighbour's own count; primal_variance / spp must still predict the
    // spread of the primal across runs. Checked on the red channel (the
    // halves' terms are independent, so the ratio is 1 in expectation) of the
    // pixels on a block edge, whose neighbours across it have 3 to 5 times
    // fewer or more samples. Measured 0.97-1.02 with three seed sets; not
    // scaling the neighbours' variances by the count ratio gave 0.78 on the
    // low-density side.
    auto scene = test::small_box("Original", kRes);
    const Image d = test_density(kRes);
    const int runs = 60;
    std::vector<FrameBuffer> fbs;
    for (int r = 0; r < runs; ++r) fbs.push_back(render_with(*scene, "gpt", 4, 9000 + r, &d));
    double predicted[2] = {0, 0}, observed[2] = {0, 0};  // low-density side, high-density side
    for (int y = 1; y < kRes - 1; ++y)
        for (int x = 1; x < kRes - 1; ++x) {
            const bool edge = x % kBlock == 0 || x % kBlock == kBlock - 1 || y % kBlock == 0 || y % kBlock == kBlock - 1;
            if (!edge) continue;
            const int side = d.at(x, y) > 1.5f ? 1 : 0;
            double m = 0.0, q = 0.0, pv = 0.0;
            for (const FrameBuffer& fb : fbs) m += fb.get("primal").at(x, y, 0);
            m /= runs;
            for (const FrameBuffer& fb : fbs) {
                const double v = fb.get("primal").at(x, y, 0) - m;
                q += v * v;
                pv += fb.get("primal_variance").at(x, y, 0) / fb.get("spp").at(x, y);
            }
            observed[side] += q / (runs - 1);
            predicted[side] += pv / runs;
        }
    const double low = observed[0] / predicted[0], high = observed[1] / predicted[1];
    UNSCOPED_INFO("observed / predicted variance: low-density side " << low << ", high-density side " << high);
    CHECK(low == Approx(1.0).margin(0.12));
    CHECK(high == Approx(1.0).margin(0.12));
}

TEST_CASE("adaptive: the density follows the gradient variance of the pilot", "[adaptive]") {
    SECTION("a synthetic pilot") {
        FrameBuffer pilot(20, 10);
        pilot.add("primal", 3);
        pilot.add("dx_variance", 3);
        pilot.add("dy_variance", 3);
        std::fill(pilot.get("primal").values().begin(), pilot.get("primal").values().end(), 0.5f);
        // Noisy gradients in the left half only.
        for (int y = 0; y < 10; ++y)
            for (int x = 0; x < 10; ++x)
                for (int c = 0; c < 3; ++c) pilot.get("dx_variance").at(x, y, c) = 4.f;
        AdaptiveOptions o;
        const Image d = adaptive_sample_density(pilot, o);
        double mean = 0.0;
        for (float v : d.values()) {
            mean += v;
            CHECK(v >= float(o.uniform) - 1e-6f);
            CHECK(v <= float(o.max_density) + 1e-5f);
        }
        CHECK(mean / double(d.values().size()) == Approx(1.0).epsilon(1e-4));
        CHECK(d.at(2, 5) > 1.5f);
        CHECK(d.at(17, 5) == Approx(o.uniform).margin(1e-6));
        // A noiseless pilot leaves sampling uniform.
        std::fill(pilot.get("dx_variance").values().begin(), pilot.get("dx_variance").values().end(), 0.f);
        const Image flat = adaptive_sample_density(pilot, o);
        for (float v : flat.values()) CHECK(v == 1.f);
        // The cap holds where one region would take everything.
        std::fill(pilot.get("dx_variance").values().begin(), pilot.get("dx_variance").values().end(), 0.f);
        for (int c = 0; c < 3; ++c) pilot.get("dx_variance").at(3, 3, c) = 1e6f;
        o.median_radius = 0;
        const Image capped = adaptive_sample_density(pilot, o);
        for (float v : capped.values()) CHECK(v <= float(o.max_density) + 1e-5f);
    }
    SECTION("a gpt pilot of the Cornell box") {
        auto scene = test::small_box("Original", 48);
        const FrameBuffer pilot = render_with(*scene, "gpt", 4, 1, nullptr);
        const Image d = adaptive_sample_density(pilot);
        // Pixels ranked by the raw relative gradient error: the noisiest
        // quarter takes more samples than the quietest quarter.
        std::vector<std::pair<float, float>> e;  // (error, density)
        for (int y = 0; y < 48; ++y)
            for (int x = 0; x < 48; ++x) {
                const float g = float(test::grey(pilot.get("dx_variance"), x, y) + test::grey(pilot.get("dy_variance"), x, y));
                const float l = float(test::grey(pilot.get("primal"), x, y));
                e.push_back({g / (l * l + 1e-3f), d.at(x, y)});
            }
        std::sort(e.begin(), e.end());
        const size_t q = e.size() / 4;
        double lo = 0.0, hi = 0.0;
        for (size_t i = 0; i < q; ++i) lo += e[i].second, hi += e[e.size() - 1 - i].second;
        UNSCOPED_INFO("mean density, quietest quarter " << lo / q << ", noisiest " << hi / q);
        CHECK(hi > 1.5 * lo);
    }
}

TEST_CASE("adaptive: render_adaptive spends a pilot share and keeps the budget", "[adaptive]") {
    auto scene = test::small_box("Original", 24);
    auto integ = integrator_registry().create("gpt", Params("test"));
    RenderSettings st;
    st.spp = 16;
    st.seed = 4;
    FrameBuffer fb;
    AdaptiveRender ad;
    ad.pilot = 0.25;
    const RenderStats rs = render_adaptive(*integ, *scene, st, fb, ad);
    CHECK(fb.metadata().at("adaptive_pilot_spp") == "4");
    CHECK(fb.metadata().at("spp") == "12");
    CHECK(fb.has("sample_density"));
    double total = 0.0;
    for (float v : fb.get("spp").values()) {
        total += v;
        CHECK(v >= 1.f);
    }
    // About 12 samples a pixel in the second render, 16 with the pilot's.
    CHECK(total / (24.0 * 24.0) == Approx(12.0).epsilon(0.1));
    CHECK(double(rs.samples) / (24.0 * 24.0) == Approx(16.0).epsilon(0.1));
    CHECK(pilot_seed(4) != 4);

    // A time budget: the pilot takes at least 4 passes and about its share
    // of the time, and the render the rest.
    RenderSettings timed;
    timed.time_budget = 0.6;
    timed.seed = 5;
    FrameBuffer tb;
    const RenderStats ts = render_adaptive(*integ, *scene, timed, tb, ad);
    const long long pilot_passes = std::stoll(tb.metadata().at("adaptive_pilot_spp"));
    const double pilot_s = std::stod(tb.metadata().at("adaptive_pilot_seconds"));
    UNSCOPED_INFO("pilot " << pilot_passes << " passes in " << pilot_s << " s, render " << ts.spp << " passes, "
                           << ts.seconds << " s in all");
    CHECK(pilot_passes >= 4);
    CHECK(pilot_s < 0.5 * timed.time_budget);
    CHECK(ts.spp > pilot_passes);
    CHECK(ts.seconds < timed.time_budget + 0.3);
    // Keeping the pilot: each pixel holds the pilot's 4 samples and its own.
    AdaptiveRender keep = ad;
    keep.keep_pilot = true;
    FrameBuffer kb;
    render_adaptive(*integ, *scene, st, kb, keep);
    CHECK(kb.metadata().at("sample_density") == "mixed");
    CHECK(kb.metadata().at("adaptive_pilot_kept") == "true");
    CHECK(kb.has("reconstruction_l1"));
    CHECK(kb.get("spp").values()[37] == fb.get("spp").values()[37] + 4.f);
    ad.pilot = 0.0;
    CHECK_THROWS_WITH(render_adaptive(*integ, *scene, st, fb, ad), Contains("pilot's share"));
}

TEST_CASE("adaptive: bad densities and integrators that cannot adapt are named", "[adaptive]") {
    auto scene = test::small_box("Original", 8);
    Image d(8, 8, 1);
    std::fill(d.values().begin(), d.values().end(), 1.f);
    d.at(3, 5) = std::nanf("");
    CHECK_THROWS_WITH(render_with(*scene, "pt", 2, 1, &d), Contains("pixel (3, 5)"));
    d.at(3, 5) = 1000.f;
    CHECK_THROWS_WITH(render_with(*scene, "pt", 2, 1, &d), Contains("not between 0 and"));
    Image small(4, 8, 1);
    CHECK_THROWS_WITH(render_with(*scene, "pt", 2, 1, &small), Contains("4x8"));
    d.at(3, 5) = 1.f;
    CHECK_THROWS_WITH(render_with(*scene, "bdpt", 2, 1, &d), Contains("samples uniformly only"));
    FrameBuffer pilot(8, 8);
    pilot.add("primal", 3);
    AdaptiveOptions g;
    g.source = AdaptiveOptions::Source::Gradients;
    CHECK_THROWS_WITH(adaptive_sample_density(pilot, g), Contains("'dx_variance'"));
    CHECK_THROWS_WITH(adaptive_sample_density(pilot), Contains("'primal_variance'"));
}

TEST_CASE("adaptive: gdr render --adaptive, --resume and merge keep each pixel's counts", "[adaptive][cli]") {
    test::OutDir dir("adaptive-cli");
    const std::string scene = std::string(GDR_SOURCE_DIR) + "/scenes/cornell-box/scene.json";
    const auto render = [&](std::vector<std::string> extra) {
        std::vector<std::string> args{"render", scene, "--integrator", "pt", "--width", "24", "--threads", "2"};
        args.insert(args.end(), extra.begin(), extra.end());
        test::stdout_of([&] { cli::run(args); });
    };
    // 8 spp: a pilot of 2 and 6 passes at the pilot's density.
    render({"--spp", "8", "--adaptive", "0.25", "--seed", "3", "-o", dir("a.exr")});
    const FrameBuffer a = read_exr(dir("a.exr"));
    REQUIRE(a.has("sample_density"));
    CHECK(a.metadata().at("spp") == "6");
    CHECK(a.metadata().at("target_spp") == "6");
    CHECK(a.metadata().at("adaptive_pilot_spp") == "2");
    const Image& d = a.get("sample_density");
    for (int y = 0; y < a.height(); ++y)
        for (int x = 0; x < a.width(); ++x) CHECK(a.get("spp").at(x, y) == float(sample_count(6, d.at(x, y))));

    // Resuming keeps the density and continues each pixel's sample numbers:
    // the result is the render of 10 passes at that density in one go.
    render({"--resume", dir("a.exr"), "--spp", "10", "-o", dir("b.exr")});
    const FrameBuffer b = read_exr(dir("b.exr"));
    CHECK(b.get("sample_density").values() == d.values());
    auto scene_file = load_scene_file(scene, {});
    set_resolution(scene_file, 24, 0);
    RenderSettings st;
    st.spp = 10;
    st.seed = 3;
    st.sample_density = &d;
    FrameBuffer whole;
    integrator_registry().create("pt", Params("test"))->render(*scene_file.scene, st, whole);
    CHECK(b.get("spp").values() == whole.get("spp").values());
    double worst = 0.0;
    for (size_t i = 0; i < whole.get("color").values().size(); ++i)
        worst = std::max(worst, std::abs(double(b.get("color").values()[i]) - whole.get("color").values()[i]) /
                                    std::max(1e-3, std::abs(double(whole.get("color").values()[i]))));
    CHECK(worst < 1e-5);

    // A part with another seed has another density: merged pixel by pixel,
    // marked as mixed, accepted again by merge and refused by --resume.
    render({"--spp", "8", "--adaptive", "0.25", "--seed", "4", "-o", dir("c.exr")});
    test::stdout_of([&] { cli::run({"merge", dir("a.exr"), dir("c.exr"), "-o", dir("m.exr")}); });
    const FrameBuffer m = read_exr(dir("m.exr")), c = read_exr(dir("c.exr"));
    CHECK(m.metadata().at("sample_density") == "mixed");
    CHECK_FALSE(m.has("sample_density"));
    for (int y = 0; y < m.height(); y += 5)
        for (int x = 0; x < m.width(); x += 5) {
            const float na = a.get("spp").at(x, y), nc = c.get("spp").at(x, y);
            CHECK(m.get("spp").at(x, y) == na + nc);
            CHECK(m.get("color").at(x, y, 1) ==
                  Approx((a.get("color").at(x, y, 1) * na + c.get("color").at(x, y, 1) * nc) / (na + nc)).epsilon(1e-5));
        }
    render({"--spp", "4", "--seed", "5", "-o", dir("u.exr")});  // uniform: density 1
    test::stdout_of([&] { cli::run({"merge", dir("m.exr"), dir("u.exr"), "-o", dir("m2.exr")}); });
    CHECK(read_exr(dir("m2.exr")).get("spp").at(3, 3) == m.get("spp").at(3, 3) + 4.f);
    CHECK_THAT(test::error_of({"render", scene, "--resume", dir("m.exr"), "--spp", "30", "-o", dir("r.exr")}),
               Contains("different seeds") || Contains("different sample densities"));
    CHECK_THAT(test::error_of({"render", scene, "--resume", dir("a.exr"), "--adaptive", "0.2", "-o", dir("r.exr")}),
               Contains("takes no --adaptive"));
    CHECK_THAT(test::error_of({"render", scene, "--first-sample", "8", "--adaptive", "0.2", "-o", dir("r.exr")}),
               Contains("different seeds instead"));
    CHECK_THAT(test::error_of({"render", scene, "--adaptive", "0.7", "-o", dir("r.exr")}), Contains("at most 0.5"));
}
