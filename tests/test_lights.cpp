// Light sampling: Scene::sample_light against light_pdf_a by chi-square tests
// (which triangle and where on it; the solid-angle density seen from a point),
// the power-proportional selection, and the one-sidedness of emitters.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "chi2.h"
#include "gdr/core/sampler.h"
#include "gdr/scene/scene.h"

using namespace gdr;

namespace {

// Emitters of different size, radiance and orientation, none hiding another
// from the origin, plus a non-emitting triangle that must never be sampled:
//   quad A (2 triangles) at z = -2 facing the origin, Le 1;
//   triangle B at x = 2 facing the origin, Le (5, 1, 0.5);
//   small quad C at y = 3 seen from behind by the origin, Le 2;
//   grey triangle D at z = 5 (not an emitter).
std::unique_ptr<Scene> light_scene() {
    TriangleMesh m;
    auto tri = [&](Vec3 a, Vec3 b, Vec3 c, uint32_t mat) {
        m.positions.insert(m.positions.end(), {a, b, c});
        m.material_ids.push_back(mat);
    };
    tri(Vec3(-0.5f, -0.5f, -2), Vec3(0.5f, -0.5f, -2), Vec3(0.5f, 0.5f, -2), 0);
    tri(Vec3(-0.5f, -0.5f, -2), Vec3(0.5f, 0.5f, -2), Vec3(-0.5f, 0.5f, -2), 0);
    tri(Vec3(2, -1, -1), Vec3(2, 0.5f, -0.5f), Vec3(2, -0.5f, 1), 1);
    tri(Vec3(-0.2f, 3, -0.2f), Vec3(-0.2f, 3, 0.2f), Vec3(0.2f, 3, 0.2f), 2);
    tri(Vec3(-0.2f, 3, -0.2f), Vec3(0.2f, 3, 0.2f), Vec3(0.2f, 3, -0.2f), 2);
    tri(Vec3(-1, -1, 5), Vec3(0, 1, 5), Vec3(1, -1, 5), 3);
    auto grey = make_lambertian(make_constant_texture(Color(0.5f)));
    std::vector<Material> mats = {{"A", grey, Color(1.f)},
                                  {"B", grey, Color(5.f, 1.f, 0.5f)},
                                  {"C", grey, Color(2.f)},
                                  {"D", grey, Color(0.f)}};
    return std::make_unique<Scene>(std::move(m), std::move(mats), Camera(), "light test scene");
}

float area_of(const Scene& s, uint32_t t) {
    const Vec3* p = &s.mesh().positions[3 * t];
    return 0.5f * glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
}

// Barycentric coordinates (b1, b2) of a point in the plane of triangle t.
Vec2 barycentrics(const Scene& s, uint32_t t, const Vec3& x) {
    const Vec3* p = &s.mesh().positions[3 * t];
    const Vec3 e1 = p[1] - p[0], e2 = p[2] - p[0], d = x - p[0];
    const double a = glm::dot(e1, e1), b = glm::dot(e1, e2), c = glm::dot(e2, e2);
    const double r1 = glm::dot(d, e1), r2 = glm::dot(d, e2), det = a * c - b * b;
    return Vec2(float((c * r1 - b * r2) / det), float((a * r2 - b * r1) / det));
}

// Index in [0, n^2) of the congruent sub-triangle (of an n-fold subdivision)
// holding barycentrics (b1, b2): the cells all have the same area.
int subcell(Vec2 b, int n) {
    const float x = std::clamp(b.x, 0.f, 1.f) * n, y = std::clamp(b.y, 0.f, 1.f) * n;
    int i = std::min(int(x), n - 1), j = std::min(int(y), n - 1);
    if (i + j > n - 1) j = n - 1 - i;  // rounding at the hypotenuse
    const bool upper = (x - i) + (y - j) > 1.f && i + j < n - 1;
    // Lower cells (i + j <= n - 1) first, row by row, then the upper ones (i + j <= n - 2).
    if (!upper) return i * n - i * (i - 1) / 2 + j;
    return n * (n + 1) / 2 + i * (n - 1) - i * (i - 1) / 2 + j;
}

}  // namespace

TEST_CASE("lights: selection is proportional to power and light_pdf_a integrates to one", "[lights]") {
    const auto scene = light_scene();
    double total = 0, integral = 0;
    for (uint32_t t = 0; t < 6; ++t) total += luminance(scene->materials()[scene->mesh().material_ids[t]].emission) * area_of(*scene, t);
    for (uint32_t t = 0; t < 6; ++t) {
        const float le = luminance(scene->materials()[scene->mesh().material_ids[t]].emission);
        CHECK(scene->light_pdf_a(t) == Approx(le / total).epsilon(1e-5));
        integral += scene->light_pdf_a(t) * area_of(*scene, t);
    }
    CHECK(integral == Approx(1.0).epsilon(1e-5));
    CHECK(scene->light_pdf_a(5) == 0.f);   // not an emitter
    CHECK(scene->light_pdf_a(99) == 0.f);  // no such triangle
    CHECK(scene->stats().emitters == 5);
    CHECK(scene->has_lights());
}

TEST_CASE("lights: sampled triangles and points match light_pdf_a (chi-square)", "[lights][statistical]") {
    // Cells: 16 congruent sub-triangles of every triangle of the scene; the
    // expected count of a cell is N * pdf_a * area / 16 (0 for the non-emitter).
    const auto scene = light_scene();
    const int n = 4, cells = n * n, tris = int(scene->mesh().size());
    const int64_t samples = 1000000;
    std::vector<double> observed(size_t(tris) * cells, 0.0), expected(observed.size(), 0.0);
    for (int t = 0; t < tris; ++t)
        for (int c = 0; c < cells; ++c)
            expected[size_t(t) * cells + c] = double(samples) * scene->light_pdf_a(uint32_t(t)) * area_of(*scene, uint32_t(t)) / cells;
    const Vec3 ref(0.f);
    int off_surface = 0;
    for (int64_t i = 0; i < samples; ++i) {
        Sampler s(SampleKey{11, 0, uint32_t(i >> 32), uint32_t(i)});
        const float u_sel = s.next1d();
        const Vec2 u = s.next2d();
        const LightSample ls = scene->sample_light(ref, u_sel, u);
        REQUIRE(ls.prim < uint32_t(tris));
        CHECK(ls.pdf_a == scene->light_pdf_a(ls.prim));
        const Vec2 b = barycentrics(*scene, ls.prim, ls.p);
        off_surface += b.x < -1e-5f || b.y < -1e-5f || b.x + b.y > 1.f + 1e-5f;
        observed[size_t(ls.prim) * cells + subcell(b, n)] += 1.0;
    }
    CHECK(off_surface == 0);
    const test::Chi2Result r = test::chi2_from_counts(observed, expected, test::suite_significance());
    INFO(r.message);
    CHECK(r.passed);
}

TEST_CASE("lights: the chi-square has power: a uniform-in-barycentrics warp is rejected", "[lights][statistical]") {
    // Sanity check of the test itself: b1 = u.x, b2 = u.y (1 - u.x) covers the
    // triangle but crowds the p1 corner (density 1 / (1 - b1)); it must fail.
    const auto scene = light_scene();
    const int n = 4, cells = n * n;
    const int64_t samples = 200000;
    std::vector<double> observed(cells, 0.0), expected(cells, double(samples) / cells);
    for (int64_t i = 0; i < samples; ++i) {
        Sampler s(SampleKey{12, 0, 0, uint32_t(i)});
        const Vec2 u = s.next2d();
        observed[subcell(Vec2(u.x, u.y * (1.f - u.x)), n)] += 1.0;
    }
    CHECK_FALSE(test::chi2_from_counts(observed, expected, test::suite_significance()).passed);
}

TEST_CASE("lights: directions towards sampled points match the solid-angle pdf (chi-square)", "[lights][statistical]") {
    // Seen from the origin, pdf_w(w) = pdf_a(y) |y - x|^2 / |cos theta_y| for the
    // emitter point y the direction reaches (no emitter hides another here).
    const auto scene = light_scene();
    const Vec3 ref(0.f);
    auto sample = [&](Sampler& s) -> std::optional<Vec3> {
        const float u_sel = s.next1d();
        const Vec2 u = s.next2d();
        const LightSample ls = scene->sample_light(ref, u_sel, u);
        return glm::normalize(ls.p - ref);
    };
    auto pdf = [&](const Vec3& w) -> double {
        SurfaceInteraction si;
        if (!scene->intersect(Ray{ref, w}, si)) return 0.0;
        const double cos_y = std::abs(glm::dot(si.ng, w));
        return cos_y > 0 ? double(scene->light_pdf_a(si.prim)) * double(si.t) * si.t / cos_y : 0.0;
    };
    test::SphericalChi2Options opt;
    opt.samples = 300000;
    const test::Chi2Result r = test::spherical_chi2(sample, pdf, opt);
    INFO(r.message);
    CHECK(r.passed);
    CHECK(r.pdf_integral == Approx(1.0).epsilon(2e-3));
}

TEST_CASE("lights: samples carry the front normal and radiance only towards the front", "[lights]") {
    const auto scene = light_scene();
    int front = 0, back = 0;
    for (uint32_t i = 0; i < 4096; ++i) {
        Sampler s(SampleKey{13, i, 0, 0});
        const float u_sel = s.next1d();
        const Vec2 u = s.next2d();
        const LightSample ls = scene->sample_light(Vec3(0.f), u_sel, u);
        const Vec3* p = &scene->mesh().positions[3 * ls.prim];
        const Vec3 n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
        REQUIRE(glm::dot(ls.n, n) == Approx(1.f));
        const Color le = scene->materials()[scene->mesh().material_ids[ls.prim]].emission;
        if (glm::dot(ls.n, -ls.p) > 0.f) {
            CHECK(ls.radiance == le);
            ++front;
        } else {
            CHECK(is_black(ls.radiance));  // quad C is seen from behind
            ++back;
        }
    }
    CHECK(front > 0);
    CHECK(back > 0);
}

TEST_CASE("lights: a scene without emitters samples nothing", "[lights]") {
    TriangleMesh m;
    m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    m.material_ids = {0};
    const Scene scene(std::move(m), {Material{"grey", make_lambertian(make_constant_texture(Color(0.5f))), Color(0.f)}},
                      Camera(), "dark");
    CHECK_FALSE(scene.has_lights());
    const LightSample ls = scene.sample_light(Vec3(0, 0, 1), 0.5f, Vec2(0.5f));
    CHECK(ls.pdf_a == 0.f);
    CHECK(is_black(ls.radiance));
    CHECK(scene.light_pdf_a(0) == 0.f);
}
