// Warps: chi-square of each direction warp against its pdf, round trips
// through the inverses, and uniformity of the triangle warp.
#include <catch2/catch.hpp>

#include "chi2.h"
#include "gdr/core/sampler.h"
#include "gdr/scene/warp.h"

using namespace gdr;
using gdr::test::spherical_chi2;

namespace {

/// Fixed-seed uniform pairs for round-trip tests, excluding the exact borders
/// where the inverse is not unique (phi = 0 vs 2 pi).
Vec2 pair_at(Sampler& s) {
    const Vec2 u = s.next2d();
    return glm::clamp(u, Vec2(1e-4f), Vec2(1.f - 1e-4f));
}

}  // namespace

TEST_CASE("warp: cosine hemisphere matches its pdf (chi-square)", "[warp][statistical]") {
    auto r = spherical_chi2([](Sampler& s) { return std::optional<Vec3>(warp::square_to_cosine_hemisphere(s.next2d())); },
                            [](const Vec3& w) { return warp::cosine_hemisphere_pdf(w); });
    INFO(r.message);
    CHECK(r.passed);
    CHECK(r.pdf_integral == Approx(1.0).epsilon(1e-3));
}

TEST_CASE("warp: uniform sphere and hemisphere match their pdfs (chi-square)", "[warp][statistical]") {
    auto r = spherical_chi2([](Sampler& s) { return std::optional<Vec3>(warp::square_to_uniform_sphere(s.next2d())); },
                            [](const Vec3&) { return warp::uniform_sphere_pdf(); });
    INFO(r.message);
    CHECK(r.passed);
    CHECK(r.pdf_integral == Approx(1.0).epsilon(1e-3));
    auto h = spherical_chi2(
        [](Sampler& s) { return std::optional<Vec3>(warp::square_to_uniform_hemisphere(s.next2d())); },
        [](const Vec3& w) { return warp::uniform_hemisphere_pdf(w); });
    INFO(h.message);
    CHECK(h.passed);
}

TEST_CASE("warp: uniform cone matches its pdf (chi-square)", "[warp][statistical]") {
    for (float cos_max : {0.95f, 0.5f, -0.3f}) {
        auto r = spherical_chi2(
            [&](Sampler& s) { return std::optional<Vec3>(warp::square_to_uniform_cone(s.next2d(), cos_max)); },
            [&](const Vec3& w) { return warp::uniform_cone_pdf(w, cos_max); });
        INFO("cos_max " << cos_max << ": " << r.message);
        CHECK(r.passed);
        CHECK(r.pdf_integral == Approx(1.0).epsilon(2e-3));
    }
}

TEST_CASE("warp: chi-square rejects a sampler that does not match its pdf", "[warp][statistical]") {
    // Uniform hemisphere samples claimed to be cosine-distributed: the helper must notice.
    gdr::test::SphericalChi2Options opt;
    opt.samples = 100000;
    auto r = spherical_chi2(
        [](Sampler& s) { return std::optional<Vec3>(warp::square_to_uniform_hemisphere(s.next2d())); },
        [](const Vec3& w) { return warp::cosine_hemisphere_pdf(w); }, opt);
    CHECK_FALSE(r.passed);
    // A subtle error: cosine sampling whose pdf is 3% too small near the pole.
    auto subtle = spherical_chi2(
        [](Sampler& s) { return std::optional<Vec3>(warp::square_to_cosine_hemisphere(s.next2d())); },
        [](const Vec3& w) { return warp::cosine_hemisphere_pdf(w) * (w.z > 0.9f ? 0.97f : 1.f); });
    CHECK_FALSE(subtle.passed);
    // Rejected samples that the pdf does not account for.
    auto lossy = spherical_chi2(
        [](Sampler& s) -> std::optional<Vec3> {
            const Vec2 u = s.next2d();
            if (u.x < 0.01f) return std::nullopt;
            return warp::square_to_uniform_sphere(u);
        },
        [](const Vec3&) { return warp::uniform_sphere_pdf(); }, opt);
    CHECK_FALSE(lossy.passed);
}

TEST_CASE("warp: inverses round-trip", "[warp]") {
    Sampler s(SampleKey{11, 0, 0, 0});
    for (int i = 0; i < 20000; ++i) {
        const Vec2 u = pair_at(s);
        const Vec2 d = warp::square_to_uniform_disk(u);
        REQUIRE(glm::length(d) <= 1.f + 1e-6f);
        const Vec2 ud = warp::uniform_disk_to_square(d);
        INFO("u = (" << u.x << ", " << u.y << ") -> (" << ud.x << ", " << ud.y << ")");
        REQUIRE(std::abs(ud.x - u.x) < 1e-4f);
        REQUIRE(std::abs(ud.y - u.y) < 1e-4f);

        const Vec3 wc = warp::square_to_cosine_hemisphere(u);
        REQUIRE(glm::length(wc) == Approx(1.f).margin(1e-5));
        const Vec2 uc = warp::cosine_hemisphere_to_square(wc);
        REQUIRE(std::abs(uc.x - u.x) < 1e-3f);
        REQUIRE(std::abs(uc.y - u.y) < 1e-3f);

        const Vec3 ws = warp::square_to_uniform_sphere(u);
        REQUIRE(glm::length(ws) == Approx(1.f).margin(1e-5));
        const Vec2 us = warp::uniform_sphere_to_square(ws);
        REQUIRE(std::abs(us.x - u.x) < 1e-4f);
        REQUIRE(std::abs(us.y - u.y) < 1e-4f);

        const float cos_max = 0.8f;
        const Vec3 wk = warp::square_to_uniform_cone(u, cos_max);
        REQUIRE(wk.z >= cos_max - 1e-6f);
        const Vec2 uk = warp::uniform_cone_to_square(wk, cos_max);
        REQUIRE(std::abs(uk.x - u.x) < 1e-3f);
        REQUIRE(std::abs(uk.y - u.y) < 1e-4f);

        const Vec2 b = warp::square_to_uniform_triangle(u);
        REQUIRE(b.x >= 0.f);
        REQUIRE(b.y >= 0.f);
        REQUIRE(b.x + b.y <= 1.f + 1e-6f);
        const Vec2 ut = warp::uniform_triangle_to_square(b);
        REQUIRE(std::abs(ut.x - u.x) < 1e-4f);
        REQUIRE(std::abs(ut.y - u.y) < 1e-3f);
    }
}

TEST_CASE("warp: the concentric disk map is continuous", "[warp]") {
    // Shift mappings rely on nearby numbers giving nearby directions.
    Sampler s(SampleKey{12, 0, 0, 0});
    for (int i = 0; i < 20000; ++i) {
        const Vec2 u = pair_at(s);
        const Vec2 du(1e-4f, -1e-4f);
        const float d = glm::length(warp::square_to_uniform_disk(u) - warp::square_to_uniform_disk(glm::clamp(u + du, Vec2(0.f), Vec2(1.f))));
        REQUIRE(d < 2e-3f);
    }
}

TEST_CASE("warp: triangle samples are uniform over the triangle (chi-square)", "[warp][statistical]") {
    // Split the triangle into 4^4 = 256 congruent sub-triangles (equal area)
    // and test equal counts. A point's sub-triangle follows from its position
    // in the grid of lines parallel to the sides: cell (i, j) with i + j < k is
    // an upright triangle if frac(b1 k) + frac(b2 k) < 1, else an inverted one.
    const int k = 16;  // 16^2 = 256 sub-triangles
    const int64_t n = 400000;
    std::vector<double> observed(size_t(k * k), 0.0);
    Sampler s(SampleKey{13, 0, 0, 0});
    for (int64_t i = 0; i < n; ++i) {
        const Vec2 b = warp::square_to_uniform_triangle(s.next2d());
        const float x = b.x * k, y = b.y * k;
        const int ix = std::min(k - 1, int(x)), iy = std::min(k - 1, int(y));
        const bool inverted = (x - ix) + (y - iy) >= 1.f;
        // Upright triangles: (ix, iy) with ix + iy <= k - 1; inverted ones: ix + iy <= k - 2.
        int idx;
        if (!inverted || ix + iy > k - 2) {
            idx = iy * k + std::min(ix, k - 1 - iy);
        } else {
            idx = k * k - 1 - (iy * k + ix);  // distinct slots counted from the end
        }
        observed[size_t(idx)] += 1.0;
    }
    // Upright cells occupy iy*k + ix with ix + iy <= k-1; inverted ones k*k-1-(iy*k+ix) with ix+iy <= k-2.
    // Those index sets are disjoint and together cover k(k+1)/2 + k(k-1)/2 = k^2 slots.
    std::vector<double> expected(observed.size(), double(n) / (k * k));
    auto r = gdr::test::chi2_from_counts(observed, expected, gdr::test::suite_significance());
    INFO(r.message);
    CHECK(r.passed);
    CHECK(warp::uniform_triangle_pdf(0.5f) == Approx(2.f));
}

TEST_CASE("warp: pdfs vanish outside their support", "[warp]") {
    CHECK(warp::cosine_hemisphere_pdf(Vec3(0, 0, -1)) == 0.f);
    CHECK(warp::uniform_hemisphere_pdf(Vec3(0, 0, -1)) == 0.f);
    CHECK(warp::uniform_cone_pdf(Vec3(1, 0, 0), 0.5f) == 0.f);
    CHECK(warp::uniform_cone_pdf(Vec3(0, 0, 1), 0.5f) == Approx(1.0 / kPi));
    CHECK(warp::cosine_hemisphere_pdf(Vec3(0, 0, 1)) == Approx(kInvPi));
}
