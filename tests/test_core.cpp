#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <set>
#include <string>
#include <utility>

#include "gdr/core/image.h"
#include "gdr/core/params.h"
#include "gdr/core/sampler.h"
#include "gdr/registry.h"

using namespace gdr;

TEST_CASE("sampler numbers are a pure function of their address", "[core]") {
    Sampler a(SampleKey{7, 3, 4, 5}), b(SampleKey{7, 3, 4, 5}), c(SampleKey{7, 4, 3, 5});
    for (int i = 0; i < 100; ++i) {
        const float x = a.next1d();
        REQUIRE(x == b.next1d());
        REQUIRE(x >= 0.f);
        REQUIRE(x < 1.f);
    }
    REQUIRE(a.at(17) == b.at(17));
    REQUIRE(a.at(0) != c.at(0));
}

TEST_CASE("sampler is uniform: chi-square over 64 bins", "[core][statistical]") {
    // 64 bins, 640k draws from many streams; the 1e-6 quantile of chi2(63) is about 143.
    std::vector<int> bins(64, 0);
    const int n = 640000;
    for (int i = 0; i < n / 64; ++i) {
        Sampler s(SampleKey{1, uint32_t(i % 97), uint32_t(i / 97), uint32_t(i)});
        for (int d = 0; d < 64; ++d) bins[int(s.next1d() * 64)]++;
    }
    double chi2 = 0;
    const double expect = n / 64.0;
    for (int b : bins) chi2 += sqr(b - expect) / expect;
    REQUIRE(chi2 < 143.0);
}

TEST_CASE("sampler pairs (2i, 2i+1) share a hash but are jointly uniform", "[core][statistical]") {
    // 2-D chi-square on a 16x16 grid over the two halves of one hash, and over
    // numbers of neighbouring pairs; the 1e-6 quantile of chi2(255) is about 372.
    for (uint32_t first : {0u, 1u}) {
        std::vector<int> bins(256, 0);
        const int n = 256 * 400;
        for (int i = 0; i < n / 8; ++i) {
            const Sampler s(SampleKey{3, uint32_t(i % 101), uint32_t(i / 101), uint32_t(i)});
            for (uint32_t d = first; d < first + 16; d += 2)
                bins[int(s.at(d) * 16) * 16 + int(s.at(d + 1) * 16)]++;
        }
        double chi2 = 0;
        const double expect = n / 256.0;
        for (int b : bins) chi2 += sqr(b - expect) / expect;
        INFO("pairs starting at dimension " << first);
        REQUIRE(chi2 < 372.0);
    }
}

TEST_CASE("params: typed reads, defaults, and unknown keys are errors", "[core]") {
    Params p("--set");
    p.set_from_text("spp=16");
    p.set_from_text("alpha=0.2");
    p.set_from_text("mode=fast");
    p.set_from_text("nee=false");
    REQUIRE(p.get_int("spp", 1) == 16);
    REQUIRE(p.get_real("alpha", 0) == Approx(0.2));
    REQUIRE(p.get_bool("nee", true) == false);
    REQUIRE(p.get_int("missing", 3) == 3);
    REQUIRE_THROWS_WITH(p.check_unused("x"), Catch::Contains("'mode'"));
    REQUIRE_THROWS_WITH(p.get_int("alpha", 0), Catch::Contains("'alpha'"));
    REQUIRE_THROWS_WITH(p.get_choice("mode", "a", {"a", "b"}), Catch::Contains("expected one of"));
}

TEST_CASE("registry: unknown names list the available ones", "[core]") {
    struct Thing {
        virtual ~Thing() = default;
    };
    Registry<Thing> r("thing");
    r.add("alpha", "first", [](const Params&) { return std::make_unique<Thing>(); });
    r.add("beta", "second", [](const Params& p) {
        p.get_int("size", 1);
        return std::make_unique<Thing>();
    });
    REQUIRE_THROWS_WITH(r.create("gamma", Params()), Catch::Contains("available: alpha, beta"));
    Params p;
    p.set("sise", 3LL);
    REQUIRE_THROWS_WITH(r.create("beta", p), Catch::Contains("'sise'"));
    REQUIRE(r.create("alpha", Params()) != nullptr);
}

TEST_CASE("require_finite names the pixel", "[core]") {
    Image img(4, 3, 3, 1.f);
    img.at(2, 1, 1) = std::numeric_limits<float>::quiet_NaN();
    REQUIRE_THROWS_WITH(require_finite(img, "layer dx"), Catch::Contains("pixel (2, 1)") && Catch::Contains("dx"));
}

TEST_CASE("params: a real is written as the shortest text that reads back as it", "[params]") {
    // The form stored in render headers and compared on resume: fixed
    // notation for decimal exponents -4 to 15, scientific otherwise.
    const std::pair<double, const char*> cases[] = {
        {0.2, "0.2"},         {1e-4, "0.0001"}, {1e-5, "1e-05"}, {1e15, "1000000000000000"}, {1e16, "1e+16"},
        {0.1 + 0.2, "0.30000000000000004"}, {-2.5, "-2.5"}, {3.0, "3"}, {5e-324, "5e-324"}, {1.5e300, "1.5e+300"},
        {123456.789, "123456.789"}, {-0.001, "-0.001"}};
    for (const auto& [v, text] : cases) CHECK(to_string(Params::Value(v)) == text);
    // Every text reads back as the same double.
    uint64_t state = 12345;
    for (int i = 0; i < 20000; ++i) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        const double v = std::ldexp(double(state >> 11) / double(1ull << 53), int(state % 200) - 100);
        const std::string t = to_string(Params::Value(v));
        REQUIRE(std::strtod(t.c_str(), nullptr) == v);
    }
}
