#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>

#include "gdr/metrics.h"

using namespace gdr;

namespace {

/// A smooth test pattern in [0.1, 0.9] so SSIM has structure to compare.
Image pattern(int w, int h, int c) {
    Image img(w, h, c);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int k = 0; k < c; ++k)
                img.at(x, y, k) = 0.5f + 0.4f * std::sin(0.3f * float(x) + 0.2f * float(y) + float(k));
    return img;
}

}  // namespace

TEST_CASE("metrics: MSE and MAE of hand-computed images", "[metrics]") {
    Image x(2, 1, 1), r(2, 1, 1);
    x.at(0, 0) = 1.f, x.at(1, 0) = 3.f;
    r.at(0, 0) = 0.f, r.at(1, 0) = 1.f;
    REQUIRE(mse(x, r) == Approx(2.5));  // (1 + 4) / 2
    REQUIRE(mae(x, r) == Approx(1.5));  // (1 + 2) / 2
    REQUIRE(mse(r, r) == 0.0);
    REQUIRE(mae(r, r) == 0.0);

    // Averaged over channels as well as pixels.
    Image a(1, 1, 3), b(1, 1, 3);
    a.set_rgb(0, 0, Color(1.f, 2.f, 3.f));
    REQUIRE(mse(a, b) == Approx(14.0 / 3.0));
    REQUIRE(mae(a, b) == Approx(2.0));
}

TEST_CASE("metrics: relMSE conventions in closed form", "[metrics]") {
    // x = s r  =>  per channel (s-1)^2 r^2 / (r^2 + eps).
    Image r(3, 2, 3, 1.f);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x) r.set_rgb(x, y, Color(1.f, 2.f, 3.f));
    Image x2 = r;
    for (float& v : x2.values()) v *= 2.f;
    const double expect = (1.0 / 1.01 + 4.0 / 4.01 + 9.0 / 9.01) / 3.0;
    REQUIRE(relmse(x2, r) == Approx(expect).epsilon(1e-6));
    REQUIRE(relmse(x2, r, RelMseOptions::thesis()) == Approx(expect).epsilon(1e-6));

    // Grey denominator: mean of r's channels is 2, so (r_c)^2 / (4 + 0.001).
    const double grey = (1.0 + 4.0 + 9.0) / 3.0 / 4.001;
    REQUIRE(relmse(x2, r, RelMseOptions::neural()) == Approx(grey).epsilon(1e-6));
    REQUIRE(relmse(x2, r, RelMseOptions{0.001f, true}) == Approx(grey).epsilon(1e-6));

    // Black reference: eps alone sets the scale.
    Image z(1, 1, 1), e(1, 1, 1, 0.1f);
    REQUIRE(relmse(e, z) == Approx(1.0).epsilon(1e-5));  // 0.01 / 0.01
    REQUIRE(relmse(z, z) == 0.0);
    REQUIRE_THROWS_AS(relmse(e, z, RelMseOptions{0.f, false}), ParameterError);
}

TEST_CASE("metrics: SSIM is 1 for identical images, closed form for constants, falls with noise", "[metrics]") {
    const Image ref = pattern(40, 30, 3);
    REQUIRE(ssim(ref, ref) == Approx(1.0).margin(1e-9));
    REQUIRE(ssim(ref, ref, SsimOptions{true}) == Approx(1.0).margin(1e-9));

    // Constant a vs constant b: no variance, so SSIM = (2ab + C1) / (a^2 + b^2 + C1).
    const double a = 0.2, b = 0.6, C1 = 1e-4;
    const Image ia(5, 4, 1, float(a)), ib(5, 4, 1, float(b));
    REQUIRE(ssim(ia, ib) == Approx((2 * a * b + C1) / (a * a + b * b + C1)).epsilon(1e-5));
    // HDR values are clamped to [0,1] first: 3 and 1 look identical.
    REQUIRE(ssim(Image(4, 4, 3, 3.f), Image(4, 4, 3, 1.f)) == Approx(1.0).margin(1e-9));

    std::mt19937 rng(7);
    std::normal_distribution<float> n01;
    double prev = 1.0;
    for (float sigma : {0.02f, 0.05f, 0.1f, 0.2f}) {
        Image noisy = ref;
        for (float& v : noisy.values()) v += sigma * n01(rng);
        const double s = ssim(noisy, ref);
        INFO("sigma " << sigma << " ssim " << s);
        REQUIRE(s < prev);
        REQUIRE(s > 0.0);
        REQUIRE(ssim(ref, noisy) == Approx(s).epsilon(1e-9));  // symmetric
        prev = s;
    }
    REQUIRE(prev < 0.8);
}

TEST_CASE("metrics: shape mismatch and NaN are reported", "[metrics]") {
    const Image a(4, 4, 3), b(4, 4, 1), c(5, 4, 3);
    REQUIRE_THROWS_AS(mse(a, b), ParameterError);
    REQUIRE_THROWS_AS(relmse(a, c), ParameterError);
    REQUIRE_THROWS_AS(ssim(a, c), ParameterError);
    REQUIRE_THROWS_AS(mae(Image(), Image()), ParameterError);

    Image nan = a;
    nan.at(2, 1, 0) = std::numeric_limits<float>::quiet_NaN();
    REQUIRE_THROWS_AS(mse(nan, a), InputError);
    REQUIRE_THROWS_WITH(relmse(a, nan), Catch::Contains("(2, 1)") && Catch::Contains("reference"));
    REQUIRE_THROWS_WITH(ssim(nan, a), Catch::Contains("(2, 1)"));
    REQUIRE_THROWS_AS(compare_report(nan, a), InputError);
}

TEST_CASE("metrics: compare report lists every metric with its convention", "[metrics]") {
    const Image ref = pattern(16, 16, 3);
    Image img = ref;
    for (float& v : img.values()) v *= 1.1f;
    const std::string rep = compare_report(img, ref);
    for (const char* s : {"MSE", "relMSE", "0.01", "0.001", "MAE", "SSIM", "11x11", "clamped", "16x16"})
        REQUIRE_THAT(rep, Catch::Contains(s));
    REQUIRE(rep.back() == '\n');
    REQUIRE_THROWS_AS(compare_report(img, Image(16, 16, 1)), ParameterError);
}

TEST_CASE("metrics: box downsampling keeps the mean, is exact on constants, refuses other factors", "[metrics]") {
    const Image img = pattern(12, 9, 3);
    const Image half = box_downsample(img, 3);
    REQUIRE(half.width() == 4);
    REQUIRE(half.height() == 3);
    REQUIRE(half.channels() == 3);
    // Each output pixel is its block's mean, so the image mean is kept.
    for (int k = 0; k < 3; ++k) {
        double a = 0, b = 0;
        for (int y = 0; y < 9; ++y)
            for (int x = 0; x < 12; ++x) a += img.at(x, y, k);
        for (int y = 0; y < 3; ++y)
            for (int x = 0; x < 4; ++x) b += half.at(x, y, k);
        REQUIRE(b / 12.0 == Approx(a / 108.0).epsilon(1e-6));
    }
    double block = 0;
    for (int y = 3; y < 6; ++y)
        for (int x = 6; x < 9; ++x) block += img.at(x, y, 1);
    REQUIRE(half.at(2, 1, 1) == Approx(block / 9.0).epsilon(1e-6));

    const Image flat(6, 4, 1, 0.37f);
    const Image down = box_downsample(flat, 2);
    for (float v : down.values()) REQUIRE(v == 0.37f);
    REQUIRE(box_downsample(flat, 1).values() == flat.values());

    REQUIRE_THROWS_WITH(box_downsample(flat, 3), Catch::Contains("6x4") && Catch::Contains("3"));
    REQUIRE_THROWS_AS(box_downsample(flat, 4), ParameterError);
    REQUIRE_THROWS_AS(box_downsample(flat, 0), ParameterError);
    REQUIRE_THROWS_AS(box_downsample(Image(), 2), ParameterError);
}

TEST_CASE("metrics: compare report gives per-channel means and their ratio", "[metrics]") {
    Image img(2, 2, 3), ref(2, 2, 3);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x) img.set_rgb(x, y, Color(0.3f, 0.2f, 0.1f)), ref.set_rgb(x, y, Color(0.1f, 0.2f, 0.f));
    const std::string rep = compare_report(img, ref);
    INFO(rep);
    REQUIRE_THAT(rep, Catch::Contains("mean R:        0.3 (reference 0.1; ratio 3)"));
    REQUIRE_THAT(rep, Catch::Contains("mean G:        0.2 (reference 0.2; ratio 1)"));
    REQUIRE_THAT(rep, Catch::Contains("mean B:        0.1 (reference 0; ratio n/a"));
    REQUIRE_THAT(compare_report(Image(1, 1, 1, 2.f), Image(1, 1, 1, 4.f)), Catch::Contains("mean Y:") && Catch::Contains("ratio 0.5"));
}
