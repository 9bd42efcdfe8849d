// Variance-weighted, outlier-robust Poisson reconstruction (gdr/reconstruct/
// weighted.h): exactness on noiseless inputs, unbiasedness of the weighted
// L2 form, outlier rejection, the L1 form's energy on rendered scenes, the
// fallback to the primal, and the inverse-variance combination of gradient sets.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/reconstruct/weighted.h"
#include "block_stats.h"
#include "cli_test_util.h"
#include "public_scenes.h"

using namespace gdr;
using gdr::test::params;

namespace {

/// A smooth image with a sharp edge, values in about [0.1, 2] (radiance).
Image clean_image(int w, int h, int channels, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    float fx[4], fy[4], ph[4], step[4];
    for (int c = 0; c < 4; ++c) fx[c] = 0.3f * u(rng), fy[c] = 0.3f * u(rng), ph[c] = 6.f * u(rng), step[c] = u(rng);
    const float ex = 0.4f * w, ey = 0.3f * h;
    Image img(w, h, channels);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < channels; ++c)
                img.at(x, y, c) = 0.7f + 0.5f * std::sin(fx[c] * x + fy[c] * y + ph[c]) + (x > ex && y > ey ? step[c] : 0.f);
    return img;
}

/// Forward differences of img (last column of dx, last row of dy: 0).
void differences(const Image& img, Image& dx, Image& dy) {
    dx = Image(img.width(), img.height(), img.channels()), dy = dx;
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x)
            for (int c = 0; c < img.channels(); ++c) {
                if (x + 1 < img.width()) dx.at(x, y, c) = img.at(x + 1, y, c) - img.at(x, y, c);
                if (y + 1 < img.height()) dy.at(x, y, c) = img.at(x, y + 1, c) - img.at(x, y, c);
            }
}

/// The buffers of one frame with variance and spp layers, owning them.
struct WFrame {
    Image primal, dx, dy, vp, vx, vy, spp;
    GradientBuffers buffers() const {
        GradientBuffers b{&primal, &dx, &dy, nullptr};
        b.primal_variance = &vp, b.dx_variance = &vx, b.dy_variance = &vy, b.spp = &spp;
        return b;
    }
};

/// A noiseless frame of `img`: exact gradients and zero variances (the true ones), 16 spp.
WFrame noiseless(const Image& img) {
    WFrame f;
    f.primal = img;
    differences(img, f.dx, f.dy);
    f.vp = Image(img.width(), img.height(), img.channels());
    f.vx = f.vp, f.vy = f.vp;
    f.spp = Image(img.width(), img.height(), 1, 16.f);
    return f;
}

double max_relative_error(const Image& a, const Image& b) {
    double e = 0;
    for (size_t i = 0; i < a.values().size(); ++i)
        e = std::max(e, std::abs(double(a.values()[i]) - b.values()[i]) / std::max(1e-3, std::abs(double(b.values()[i]))));
    return e;
}

const std::vector<Params>& all_variants() {
    static const std::vector<Params> v = {
        params({}),
        params({{"norm", "l1"}}),
        params({{"norm", "l1"}, {"energy", "none"}}),
        params({{"outliers", "downweight"}}),
        params({{"outliers", "none"}, {"variance_radius", "0"}}),
        params({{"fallback", "tile"}, {"tile", "4"}}),
        params({{"energy", "mean"}}),
        params({{"energy", "lowpass"}, {"energy_radius", "3"}}),
        params({{"norm", "l1"}, {"fallback", "tile"}, {"outliers", "downweight"}, {"energy", "mean"}}),
        params({{"norm", "l2"}, {"energy", "none"}, {"variance_radius", "1"}}),
        params({{"energy_clip", "3"}, {"energy_radius", "2"}}),
        params({{"guard", "median"}, {"variance_radius", "1"}}),
    };
    return v;
}

}  // namespace

TEST_CASE("poisson-weighted returns a noiseless image exactly, with every option", "[reconstruct][weighted]") {
    for (auto [w, h] : {std::pair{1, 1}, {1, 7}, {9, 1}, {5, 4}, {23, 17}, {64, 48}}) {
        const Image img = clean_image(w, h, 3, uint32_t(w * 100 + h));
        // Zero variances (the true ones) and, the data being consistent, any
        // positive variances give the same image back.
        WFrame zero = noiseless(img), varied = noiseless(img);
        std::mt19937 rng(uint32_t(w + h));
        std::uniform_real_distribution<float> u(0.01f, 2.f);
        for (Image* v : {&varied.vp, &varied.vx, &varied.vy})
            for (float& x : v->values()) x = u(rng);
        for (const WFrame* f : {&zero, &varied})
            for (const Params& p : all_variants()) {
                INFO(w << "x" << h << " " << (f == &zero ? "zero" : "random") << " variances, " << p.to_text());
                const Image out = reconstruct("poisson-weighted", p, f->buffers());
                CHECK(max_relative_error(out, img) < 1e-5);
            }
    }
}

TEST_CASE("weighted L2 with the true variances is unbiased for skewed noise", "[reconstruct][weighted][stat]") {
    // Monte Carlo pixel estimates are skewed (rare bright samples). With the
    // true variances the weights do not depend on the data, the weighted L2
    // solution is linear in it, and so unbiased; over many seeds the mean
    // result must match the truth within its standard error.
    const int w = 12, h = 10, C = 3, seeds = 600;
    const Image truth = clean_image(w, h, C, 5);
    Image tdx, tdy;
    differences(truth, tdx, tdy);
    // Per-pixel noise levels varying over the image (per-sample variances at spp 4).
    WFrame f = noiseless(truth);
    f.spp = Image(w, h, 1, 4.f);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < C; ++c) {
                f.vp.at(x, y, c) = 0.4f * (1.f + float(x) / w);
                f.vx.at(x, y, c) = 0.02f * (1.f + 3.f * (y > h / 2));
                f.vy.at(x, y, c) = 0.03f;
            }
    // Zero-mean noise of variance v / spp: a centred exponential (skewness 2).
    auto noise = [](std::mt19937& rng, double var) {
        std::exponential_distribution<double> e(1.0);
        return float(std::sqrt(var) * (e(rng) - 1.0));
    };
    auto run = [&](const Params& p) {
        std::vector<double> sum(truth.values().size(), 0.0), sum2 = sum;
        for (int s = 0; s < seeds; ++s) {
            std::mt19937 rng(uint32_t(1000 + s));
            WFrame n = f;
            for (size_t i = 0; i < truth.values().size(); ++i) {
                n.primal.values()[i] = truth.values()[i] + noise(rng, f.vp.values()[i] / 4.0);
                n.dx.values()[i] = tdx.values()[i] + noise(rng, f.vx.values()[i] / 4.0);
                n.dy.values()[i] = tdy.values()[i] + noise(rng, f.vy.values()[i] / 4.0);
            }
            const Image out = reconstruct("poisson-weighted", p, n.buffers());
            for (size_t i = 0; i < sum.size(); ++i) {
                const double e = double(out.values()[i]) - truth.values()[i];
                sum[i] += e, sum2[i] += e * e;
            }
        }
        // The image-mean bias and the largest per-pixel z-score.
        double zmax = 0, mean_err = 0, mean_var = 0;
        for (size_t i = 0; i < sum.size(); ++i) {
            const double m = sum[i] / seeds, var = (sum2[i] / seeds - m * m) * seeds / (seeds - 1.0);
            zmax = std::max(zmax, std::abs(m) / std::sqrt(var / seeds));
            mean_err += m, mean_var += var;
        }
        const double n = double(sum.size());
        // Errors of neighbouring pixels are correlated, so the standard error
        // of the image mean is bounded by that of a single pixel's mean.
        const double z_mean = std::abs(mean_err / n) / std::sqrt(mean_var / n / seeds);
        return std::pair{zmax, z_mean};
    };
    // Without the outlier test: with it, a few tail samples are dropped, which is data-dependent.
    // The lowpass energy tie adds a linear function of the data, so it keeps the solution unbiased.
    for (const char* energy : {"none", "lowpass"}) {
        const auto [zmax, zmean] =
            run(params({{"norm", "l2"}, {"outliers", "none"}, {"tolerance", "1e-7"}, {"energy", energy}}));
        INFO("energy " << energy << ": largest per-pixel |z| " << zmax << ", image-mean |z| " << zmean);
        // 360 values: |z| > 4.5 has probability ~2e-3 under the null hypothesis.
        CHECK(zmax < 4.5);
        CHECK(zmean < 4.0);
    }
}

TEST_CASE("poisson-weighted drops a planted outlier gradient and leaves a clean image untouched",
          "[reconstruct][weighted]") {
    const int w = 40, h = 30;
    const Image img = clean_image(w, h, 3, 11);
    // Small true variances: the clean data are consistent with them.
    WFrame f = noiseless(img);
    for (Image* v : {&f.vp, &f.vx, &f.vy})
        for (float& x : v->values()) x = 1e-4f;
    const VarianceProblem base = [&] {
        VarianceProblem p;
        auto view = [](const Image& i) { return ImageView{i.data(), i.width(), i.height(), i.channels()}; };
        p.primal = view(f.primal), p.dx = view(f.dx), p.dy = view(f.dy);
        p.primal_variance = view(f.vp), p.dx_variance = view(f.vx), p.dy_variance = view(f.vy);
        p.spp = f.spp.data();
        return p;
    }();
    WeightedOptions opt;
    opt.tolerance = 1e-7;
    Image clean_out(w, h, 3);
    const WeightedReport clean = poisson_variance_weighted(base, opt, clean_out.data());
    CHECK(clean.outlier_rows == 0);
    CHECK(max_relative_error(clean_out, img) < 1e-5);
    for (OutlierMode mode : {OutlierMode::drop, OutlierMode::downweight}) {
        for (auto [layer, px, py] : {std::tuple{0, 17, 12}, std::tuple{1, 3, 20}}) {
            WFrame bad = f;
            (layer == 0 ? bad.dx : bad.dy).at(px, py, 1) += 25.f;  // a firefly gradient, variance unchanged
            VarianceProblem p = base;
            p.dx.data = bad.dx.data(), p.dy.data = bad.dy.data();
            opt.outliers = mode;
            Image out(w, h, 3);
            const WeightedReport rep = poisson_variance_weighted(p, opt, out.data());
            INFO("mode " << int(mode) << " layer " << layer);
            CHECK(rep.outlier_rows == 1);
            // Dropped, it is gone; down-weighted to a 4-sigma pull, it moves nothing visible.
            CHECK(max_relative_error(out, clean_out) < (mode == OutlierMode::drop ? 1e-5 : 1e-3));
        }
    }
}

TEST_CASE("poisson-weighted with gradients disabled everywhere returns the primal", "[reconstruct][weighted]") {
    const int w = 31, h = 19;
    // A noisy primal with inconsistent gradients: only the fallback can return it.
    WFrame f = noiseless(clean_image(w, h, 3, 3));
    std::mt19937 rng(9);
    std::normal_distribution<float> n(0.f, 0.1f);
    for (float& v : f.primal.values()) v += n(rng);
    for (Image* g : {&f.dx, &f.dy})
        for (float& v : g->values()) v += n(rng);
    for (Image* v : {&f.vp, &f.vx, &f.vy})
        for (float& x : v->values()) x = 0.16f;
    SECTION("by a per-pixel mask") {
        auto view = [](const Image& i) { return ImageView{i.data(), i.width(), i.height(), i.channels()}; };
        VarianceProblem p;
        p.primal = view(f.primal), p.dx = view(f.dx), p.dy = view(f.dy);
        p.primal_variance = view(f.vp), p.dx_variance = view(f.vx), p.dy_variance = view(f.vy);
        p.spp = f.spp.data();
        const std::vector<unsigned char> off(size_t(w) * h, 0);
        p.gradient_enabled = off.data();
        for (WeightedNorm norm : {WeightedNorm::l2, WeightedNorm::l1}) {
            WeightedOptions o;
            o.norm = norm;
            o.energy = EnergyMode::lowpass;
            Image out(w, h, 3);
            const WeightedReport rep = poisson_variance_weighted(p, o, out.data());
            CHECK(rep.fallback_rows + rep.outlier_rows == (w - 1) * h + (h - 1) * w);
            CHECK(max_relative_error(out, f.primal) < 1e-6);
        }
    }
    SECTION("by the tile test, when every tile's gradients are noisier than the primal") {
        for (Image* v : {&f.vx, &f.vy})
            for (float& x : v->values()) x = 1.f;  // > 2 x 0.16
        for (const char* norm : {"l2", "l1"}) {
            const Image out = reconstruct("poisson-weighted", params({{"fallback", "tile"}, {"tile", "5"}, {"norm", norm}}),
                                          f.buffers());
            CHECK(max_relative_error(out, f.primal) < 1e-6);
        }
    }
}

TEST_CASE("poisson-weighted L1 keeps the image mean of rendered scenes at low spp", "[reconstruct][weighted][gpt]") {
    // The L1 form alone is biased low (a robust fit of skewed samples); its
    // low-frequency tie to the primal must keep the mean within 1%.
    std::vector<std::string> scenes = {GDR_SOURCE_DIR "/scenes/cornell-box/scene.json",
                                       GDR_SOURCE_DIR "/scenes/cornell-box/sphere.json"};
    if (!test::public_scene("bathroom-contemporary/bathroom.obj").empty())
        scenes.push_back(GDR_SOURCE_DIR "/scenes/bathroom/scene.json");
    else
        WARN(test::public_scene_missing("bathroom-contemporary", false));
    for (const std::string& path : scenes) {
        const SceneFile sf = load_scene_file(path);
        CameraDesc d = sf.scene->camera().desc();
        d.height = std::max(1, int(std::lround(64.0 * d.height / d.width))), d.width = 64;
        const Scene scene(sf.scene->mesh(), sf.scene->materials(), Camera(d), path);
        Params gp("test");
        gp.set("reconstruct", std::string("none"));
        const FrameBuffer fb = test::render(scene, "gpt", gp, 4, 77);
        const GradientBuffers gb = gradient_buffers(fb);
        const Image out = reconstruct("poisson-weighted", params({{"norm", "l1"}}), gb);
        for (int c = 0; c < 3; ++c) {
            double a = 0, b = 0;
            for (int y = 0; y < out.height(); ++y)
                for (int x = 0; x < out.width(); ++x) a += out.at(x, y, c), b += gb.primal->at(x, y, c) + gb.direct->at(x, y, c);
            INFO(path << " channel " << c << ": mean " << a << " primal + direct " << b);
            CHECK(std::abs(a / b - 1.0) < 0.01);
        }
    }
}

TEST_CASE("inverse-variance combination of two gradient sets is unbiased and no noisier than the better set",
          "[reconstruct][weighted][stat]") {
    const int w = 64, h = 64, C = 3;
    const size_t len = size_t(w) * h * C;
    std::mt19937 rng(21);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    std::normal_distribution<double> n(0.0, 1.0);
    // Two sets estimating the same gradients g = 0.3, with per-value variances
    // between 0.01 and 1, either set the better one about half the time.
    std::vector<float> v1(len), v2(len), g1x(len), g2x(len), g1y(len), g2y(len);
    for (size_t i = 0; i < len; ++i) {
        v1[i] = 0.01f + u(rng), v2[i] = 0.01f + u(rng);
        g1x[i] = float(0.3 + std::sqrt(v1[i]) * n(rng)), g2x[i] = float(0.3 + std::sqrt(v2[i]) * n(rng));
        g1y[i] = float(-0.2 + std::sqrt(v1[i]) * n(rng)), g2y[i] = float(-0.2 + std::sqrt(v2[i]) * n(rng));
    }
    auto view = [&](const std::vector<float>& v) { return ImageView{v.data(), w, h, C}; };
    const std::vector<GradientSet> sets = {{view(g1x), view(g1y), view(v1), view(v1)},
                                           {view(g2x), view(g2y), view(v2), view(v2)}};
    std::vector<float> dx, dy, vx, vy;
    combine_gradient_sets(sets, dx, dy, vx, vy);
    double zsum = 0, zz = 0, sq = 0, sq_min = 0;
    for (size_t i = 0; i < len; ++i) {
        const double z = (dx[i] - 0.3) / std::sqrt(vx[i]);
        zsum += z, zz += z * z;
        sq += (dx[i] - 0.3) * (dx[i] - 0.3) + (dy[i] + 0.2) * (dy[i] + 0.2);
        sq_min += 2.0 * std::min(v1[i], v2[i]);
        CHECK(vx[i] <= std::min(v1[i], v2[i]) * (1 + 1e-6));
    }
    const double N = double(len);
    INFO("mean z " << zsum / N << ", var z " << zz / N << ", squared error " << sq << " vs the better set's variance " << sq_min);
    CHECK(std::abs(zsum / N) < 4.0 / std::sqrt(N));   // unbiased: z-test on the mean
    CHECK(std::abs(zz / N - 1.0) < 0.05);             // the stated variance is the actual one (N = 12288: sd 0.013)
    CHECK(sq < sq_min);                               // at most the smaller of the two sets' variances
}

TEST_CASE("poisson-weighted refuses missing or bad variance layers, naming them", "[reconstruct][weighted]") {
    WFrame f = noiseless(clean_image(6, 5, 3, 1));
    GradientBuffers b = f.buffers();
    b.dx_variance = nullptr, b.spp = nullptr;
    REQUIRE_THROWS_WITH(reconstruct("poisson-weighted", Params(), b),
                        Catch::Contains("dx_variance") && Catch::Contains("spp"));
    f.vy.at(4, 2, 1) = -1.f;
    REQUIRE_THROWS_WITH(reconstruct("poisson-weighted", Params(), f.buffers()),
                        Catch::Contains("dy_variance") && Catch::Contains("(4, 2)"));
    f.vy.at(4, 2, 1) = 0.f;
    f.spp.at(1, 3) = 0.f;
    REQUIRE_THROWS_WITH(reconstruct("poisson-weighted", Params(), f.buffers()),
                        Catch::Contains("spp") && Catch::Contains("(1, 3)"));
    REQUIRE_THROWS_AS(reconstruct("poisson-weighted", params({{"norm", "l3"}}), noiseless(clean_image(6, 5, 3, 1)).buffers()),
                      ParameterError);
}

TEST_CASE("gdr reconstruct runs poisson-weighted on the layers of a gpt render file", "[reconstruct][weighted][cli]") {
    const test::OutDir out("weighted-cli");
    REQUIRE(cli::run({"render", GDR_SOURCE_DIR "/tests/scenes/cornell-small.json", "--integrator", "gpt", "--spp", "4",
                      "--set", "reconstruct=none", "-o", out("g.exr")}) == 0);
    REQUIRE(cli::run({"reconstruct", out("g.exr"), "--method", "poisson-weighted", "--set", "norm=l2", "-o",
                      out("w.exr")}) == 0);
    // The same as the library call on the file's layers.
    const FrameBuffer fb = read_exr(out("g.exr"));
    Params p("test");
    p.set_from_text("norm=l2");
    const Image expect = reconstruct("poisson-weighted", p, gradient_buffers(fb));
    CHECK(read_exr(out("w.exr")).get("color").values() == expect.values());
    // Without the variance layers it is refused, naming them.
    FrameBuffer bare(fb.width(), fb.height());
    for (const char* layer : {"primal", "dx", "dy", "direct"}) bare.set(layer, fb.get(layer));
    write_exr(out("bare.exr"), bare);
    CHECK_THAT(test::error_of({"reconstruct", out("bare.exr"), "--method", "poisson-weighted", "-o", out("x.exr")}),
               Catch::Contains("bare.exr") && Catch::Contains("primal_variance"));
}

TEST_CASE("poisson-weighted is never worse than poisson-l1 when huge gradients of ordinary variance are injected",
          "[reconstruct][weighted]") {
    // A smooth frame with noise of known variance (16 spp), into which a few
    // gradients of 1e10 ... 1e30 are injected with their variance left as it
    // was: such a row is far outside what its neighbours and the primal
    // allow. Before the weighted solve started from a start point and rows
    // cleaned of such gradients, the planted rows drove the image mean to
    // -0.19 ... -3.7e19 (the start point, poisson-l2 of all gradients, had
    // them; the relative CG tolerance then stopped the solve far from the
    // solution, and float could not even represent it near 1e10), while
    // poisson-l1 stayed within the noise.
    const int w = 48, h = 36, C = 3;
    const Image truth = clean_image(w, h, C, 5);
    std::mt19937 rng(39);
    std::normal_distribution<float> gauss(0.f, 1.f);
    const float sp = 0.05f, sg = 0.03f, spp = 16.f;  // standard deviations of the means
    WFrame f = noiseless(truth);
    for (float& v : f.primal.values()) v += sp * gauss(rng);
    for (Image* g : {&f.dx, &f.dy})
        for (float& v : g->values()) v += sg * gauss(rng);
    for (float& v : f.vp.values()) v = sp * sp * spp;  // per-sample variances
    for (Image* v : {&f.vx, &f.vy})
        for (float& x : v->values()) x = sg * sg * spp;
    f.spp = Image(w, h, 1, spp);
    // One sample at one pixel: its rows have no variance estimate and are not z-tested.
    f.spp.at(30, 8) = 1.f;
    f.dx.at(30, 8, 0) += 1e12f;
    f.dx.at(10, 10, 1) += 1e10f;
    f.dy.at(25, 20, 0) -= 1e20f;
    f.dx.at(40, 30, 2) += 1e30f;
    f.dy.at(5, 33, 1) += 3e15f;

    const auto mean_abs_error = [&](const Image& x) {
        double e = 0;
        for (size_t i = 0; i < x.values().size(); ++i) e += std::abs(double(x.values()[i]) - truth.values()[i]);
        return e / double(x.values().size());
    };
    const auto mean = [](const Image& x) {
        double s = 0;
        for (float v : x.values()) s += v;
        return s / double(x.values().size());
    };
    GradientBuffers l1_in{&f.primal, &f.dx, &f.dy, nullptr};
    const double e_l1 = mean_abs_error(reconstruct("poisson-l1", Params(), l1_in));
    INFO("poisson-l1 mean abs error " << e_l1);
    CHECK(e_l1 < 0.05);
    double worst = 0;
    for (size_t v = 0; v < all_variants().size(); ++v) {
        const Image x = reconstruct("poisson-weighted", all_variants()[v], f.buffers());
        const double e = mean_abs_error(x);
        worst = std::max(worst, e / e_l1);
        INFO("poisson-weighted variant " << v << " of all_variants(): mean abs error " << e << ", mean " << mean(x) << " (truth "
                                 << mean(truth) << ")");
        // L1's error with a margin of 10% for the weighted variants' own bias.
        CHECK(e <= 1.1 * e_l1);
        CHECK(std::abs(mean(x) - mean(truth)) < 0.01);
    }
    WARN("injected huge gradients: poisson-l1 mean abs error " << e_l1 << ", poisson-weighted at most " << worst
                                                               << " times it over " << all_variants().size() << " variants");
}
