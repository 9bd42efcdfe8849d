// Environment lights: the envmap's importance sampling against its pdf
// (chi-square), the lat-long convention (Mitsuba's), the scene's light
// selection with an environment, white furnaces for pt and bdpt, pt against
// bdpt and its strategies on an environment-lit box (block z-tests), the
// scene file's and the Mitsuba importer's environments, and gpt's refusal.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <map>

#include <glm/gtc/matrix_transform.hpp>

#include "block_stats.h"
#include "joined_densities.h"
#include "chi2.h"
#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/path/connection.h"
#include "gdr/path/dims.h"
#include "gdr/path/environment.h"
#include "gdr/scene/environment.h"
#include "gdr/scene/texture.h"

using namespace gdr;
using namespace gdr::test;

namespace {

// A small, strongly non-uniform map: a smooth gradient, a bright patch and a
// black texel (which must never be sampled).
Image test_map(int w = 12, int h = 8) {
    Image m(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float g = 0.2f + float(x) / w + 0.5f * float(y) / h;
            m.set_rgb(x, y, Color(g, 0.5f * g, 0.1f + g * g));
        }
    m.set_rgb(w / 4, h / 2, Color(30.f, 20.f, 10.f));
    // A black 3 x 3 block around texel (w - 2, 2): the interpolated radiance
    // is zero over that texel's whole cell (and on parts of its neighbours').
    for (int y = 1; y <= 3; ++y)
        for (int x = w - 3; x < w; ++x) m.set_rgb(x, y, Color(0.f));
    return m;
}

// Equal within float rounding of the direction-to-texel mapping (relative 1e-4).
bool near_color(const Color& a, const Color& b) {
    for (int c = 0; c < 3; ++c)
        if (!(std::abs(a[c] - b[c]) <= 1e-4f * std::max(1.f, std::abs(b[c])))) return false;
    return true;
}

// A rotation of `deg` degrees about `axis` as a 3x3 matrix.
glm::mat3 rotation(float deg, const Vec3& axis) { return glm::mat3(glm::rotate(Mat4(1.f), glm::radians(deg), glm::normalize(axis))); }

// A convex, flat-shaded polyhedron close to the unit sphere (an icosahedron
// subdivided `levels` times, vertices pushed onto the sphere), outward
// winding, material 0.
TriangleMesh icosphere(int levels, float radius, const Vec3& centre) {
    const float t = (1.f + std::sqrt(5.f)) / 2.f;
    std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                           {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<std::array<Vec3, 3>> f;
    const int idx[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                            {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                            {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (const auto& i : idx) f.push_back({glm::normalize(v[i[0]]), glm::normalize(v[i[1]]), glm::normalize(v[i[2]])});
    for (int l = 0; l < levels; ++l) {
        std::vector<std::array<Vec3, 3>> g;
        for (const auto& tri : f) {
            const Vec3 a = glm::normalize(tri[0] + tri[1]), b = glm::normalize(tri[1] + tri[2]),
                       c = glm::normalize(tri[2] + tri[0]);
            g.push_back({tri[0], a, c}), g.push_back({tri[1], b, a}), g.push_back({tri[2], c, b}), g.push_back({a, b, c});
        }
        f = std::move(g);
    }
    TriangleMesh m;
    for (auto tri : f) {
        if (glm::dot(glm::cross(tri[1] - tri[0], tri[2] - tri[0]), tri[0]) < 0.f) std::swap(tri[1], tri[2]);
        for (const Vec3& p : tri) m.positions.push_back(centre + radius * p);
        m.material_ids.push_back(0);
    }
    return m;
}

// The white furnace: a grey diffuse convex object of albedo `albedo` under a
// constant environment of radiance `l`, seen whole by a res x res camera.
std::unique_ptr<Scene> furnace(float albedo, float l, int res) {
    std::vector<Material> mats(1);
    mats[0].name = "grey";
    mats[0].bsdf = make_lambertian(make_constant_texture(Color(albedo)));
    CameraDesc cd;
    cd.position = {0.f, 0.f, 4.f};
    cd.target = {0.f, 0.f, 0.f};
    cd.fov_deg = 40.f;
    cd.width = cd.height = res;
    auto s = std::make_unique<Scene>(icosphere(3, 1.f, Vec3(0.f)), std::move(mats), Camera(cd), "furnace");
    s->set_environment(Environment::constant(Color(l)));
    return s;
}

// The box with its ceiling light, open towards the camera, also lit by the
// test map (times `scale`) rotated so that its bright patch shines into the opening.
std::unique_ptr<Scene> env_box(int res, float scale = 0.5f) {
    auto s = small_box("Original", res);
    s->set_environment(Environment::from_map(test_map(), rotation(-60.f, Vec3(0.f, 1.f, 0.f)), scale, "test map"));
    return s;
}

// Pixels of the furnace entirely covered by the object (its silhouette is
// convex: the pixel's four corners suffice) and entirely clear of it (more
// than two pixels' angle outside the circumscribed sphere's silhouette).
void furnace_pixels(const Scene& s, std::vector<std::pair<int, int>>& inside, std::vector<std::pair<int, int>>& outside) {
    const Camera& cam = s.camera();
    const float alpha = std::asin(1.f / 4.f), px = glm::radians(40.f) / float(cam.height());
    for (int y = 0; y < cam.height(); ++y)
        for (int x = 0; x < cam.width(); ++x) {
            bool all = true;
            for (int c = 0; c < 4; ++c) {
                SurfaceInteraction si;
                all = all && s.intersect(cam.generate_ray(Vec2(float(x + (c & 1)), float(y + (c >> 1)))), si);
            }
            const Ray r = cam.generate_ray(Vec2(x + 0.5f, y + 0.5f));
            const float angle = std::acos(std::clamp(glm::dot(r.d, glm::normalize(-r.o)), -1.f, 1.f));
            if (all) inside.emplace_back(x, y);
            else if (angle > alpha + 2.f * px) outside.emplace_back(x, y);
        }
}

// Mean and standard error of the grey values of `img` at `pixels` (each an
// independent estimate of the same value).
std::pair<double, double> mean_se(const Image& img, const std::vector<std::pair<int, int>>& pixels) {
    double s = 0.0, s2 = 0.0;
    for (const auto& [x, y] : pixels) {
        const double v = grey(img, x, y);
        s += v, s2 += v * v;
    }
    const double n = double(pixels.size()), m = s / n;
    return {m, std::sqrt(std::max(0.0, s2 / n - m * m) / (n - 1.0))};
}

}  // namespace

TEST_CASE("environment: envmap direction sampling matches its pdf (chi-square), with a rotation", "[environment][statistical]") {
    // The pdf is piecewise constant over texels whose edges the rotation
    // lays obliquely across any grid, where chi2.h's adaptive quadrature
    // cannot converge. So the cells are a uniform 20 x 40 grid of world
    // (cos theta, phi), their probabilities the pdf integrated by the
    // midpoint rule on 80 x 80 points per cell: a texel edge through a
    // cell then misplaces at most 1/80 of its share, a bias of about 1% of
    // a cell's 1250 expected samples against a noise of 3%.
    const auto env = Environment::from_map(test_map(), rotation(37.f, Vec3(1.f, 2.f, 0.5f)), 2.f, "test map");
    const int nc = 20, np = 40, sub = 80;
    const int64_t samples = 1000000;
    std::vector<double> observed(nc * np, 0.0), expected(nc * np, 0.0);
    const double two_pi = 2.0 * M_PI;
    for (int64_t i = 0; i < samples; ++i) {
        Sampler sm(SampleKey{17, 0u, uint32_t(i >> 32), uint32_t(i)});
        const EnvironmentSample es = env->sample(sm.next2d());
        REQUIRE(es.pdf_w > 0.f);
        double phi = std::atan2(double(es.wi.y), double(es.wi.x));
        if (phi < 0.0) phi += two_pi;
        const int ic = std::clamp(int((double(es.wi.z) + 1.0) / 2.0 * nc), 0, nc - 1);
        const int ip = std::clamp(int(phi / two_pi * np), 0, np - 1);
        observed[ic * np + ip] += 1.0;
    }
    double integral = 0.0;
    const double dc = 2.0 / (nc * sub), dp = two_pi / (np * sub);
    for (int ic = 0; ic < nc; ++ic)
        for (int ip = 0; ip < np; ++ip) {
            double prob = 0.0;
            for (int a = 0; a < sub; ++a)
                for (int b = 0; b < sub; ++b) {
                    const double c = -1.0 + (ic * sub + a + 0.5) * dc, phi = (ip * sub + b + 0.5) * dp;
                    prob += double(env->pdf(direction_from(c, phi))) * dc * dp;
                }
            expected[ic * np + ip] = prob * double(samples);
            integral += prob;
        }
    CHECK(integral == Approx(1.0).epsilon(2e-3));
    const Chi2Result r = chi2_from_counts(observed, expected, suite_significance());
    INFO(r.message);
    CHECK(r.passed);
}

TEST_CASE("environment: its own sampling estimates the map's integral as uniform sampling does", "[environment][statistical]") {
    // E[L / pdf] over sample() equals the integral of eval() over the
    // sphere only if pdf > 0 wherever L > 0 and sample() follows pdf();
    // the reference is 4 pi E[L] over uniform directions (stratified). A
    // sparse map (three lit texels on black) makes that coverage matter:
    // the interpolated radiance spreads into the black neighbours' cells,
    // and weights of each texel alone (the wrong variant) gave 5.56 against
    // the reference's 9.81.
    Image sparse(12, 8, 3, 0.f);
    sparse.set_rgb(2, 3, Color(30.f, 20.f, 10.f));
    sparse.set_rgb(11, 0, Color(1.f, 2.f, 3.f));  // next to the wrap in u and the pole
    sparse.set_rgb(6, 6, Color(5.f));
    const auto env = Environment::from_map(sparse, rotation(37.f, Vec3(1.f, 2.f, 0.5f)), 2.f, "sparse map");
    const int n = 400000;
    double s = 0, s2 = 0, u_sum = 0;
    for (int i = 0; i < n; ++i) {
        Sampler sm(SampleKey{23, 0u, 0u, uint32_t(i)});
        const EnvironmentSample es = env->sample(sm.next2d());
        REQUIRE(es.pdf_w > 0.f);
        const double v = luminance(es.radiance) / es.pdf_w;
        s += v, s2 += v * v;
    }
    const int strata = 1000;  // 1000 x 1000 midpoints in (cos theta, phi): a near-exact reference
    for (int a = 0; a < strata; ++a)
        for (int b = 0; b < strata; ++b) {
            const double c = -1.0 + 2.0 * (a + 0.5) / strata, phi = 2.0 * M_PI * (b + 0.5) / strata;
            u_sum += luminance(env->eval(direction_from(c, phi)));
        }
    const double mean = s / n, se = std::sqrt((s2 / n - mean * mean) / (n - 1));
    const double reference = 4.0 * M_PI * u_sum / (double(strata) * strata);
    CAPTURE(mean, se, reference);
    CHECK(std::abs(mean - reference) < 4.0 * se);
    CHECK(se < 0.005 * reference);  // power: a 2% error is seen
}

TEST_CASE("environment: a sample's pdf and radiance are pdf() and eval() of its direction", "[environment]") {
    const auto env = Environment::from_map(test_map(), rotation(-75.f, Vec3(0.3f, 1.f, -0.2f)), 3.f, "test map");
    const Image map = test_map();
    for (uint32_t i = 0; i < 20000; ++i) {
        Sampler s(SampleKey{7, i, 0, 0});
        const EnvironmentSample es = env->sample(s.next2d());
        REQUIRE(es.pdf_w > 0.f);
        REQUIRE(glm::length(es.wi) == Approx(1.f).epsilon(1e-5));
        CHECK(env->pdf(es.wi) == Approx(es.pdf_w).epsilon(1e-3));
        CHECK(env->eval(es.wi) == es.radiance);
        // The cell of texel (10, 2), black throughout, is never drawn.
        const Vec2 uv = env->direction_to_uv(es.wi);
        CHECK(!(int(uv.x * 12.f) == 10 && int(uv.y * 8.f) == 2));
    }
    // That cell: no radiance and no density anywhere in it.
    for (const Vec2 uv : {Vec2(10.5f / 12.f, 2.5f / 8.f), Vec2(10.05f / 12.f, 2.05f / 8.f), Vec2(10.95f / 12.f, 2.95f / 8.f)}) {
        const Vec3 black = env->uv_to_direction(uv);
        CHECK(is_black(env->eval(black)));
        CHECK(env->pdf(black) == 0.f);
    }
    // The luminance integral: per cell, the luminance of the bilinear
    // interpolant's mean over it (3/4 of the texel, 1/8 of each neighbour per
    // axis; u wraps, v clamps) times the cell's solid angle.
    const double k[3] = {0.125, 0.75, 0.125};
    double integral = 0.0;
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 12; ++x) {
            double mean = 0.0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    mean += k[dx + 1] * k[dy + 1] * luminance(map.rgb((x + dx + 12) % 12, std::clamp(y + dy, 0, 7)));
            integral += 3.0 * mean * (2.0 * M_PI / 12.0) * (std::cos(M_PI * y / 8.0) - std::cos(M_PI * (y + 1) / 8.0));
        }
    CHECK(env->luminance_integral() == Approx(integral).epsilon(1e-6));
    // A constant environment: uniform density, radiance everywhere.
    const auto c = Environment::constant(Color(0.5f, 1.f, 2.f));
    CHECK(c->pdf(Vec3(0.f, 0.f, 1.f)) == Approx(1.0 / (4.0 * M_PI)));
    CHECK(c->eval(glm::normalize(Vec3(1.f, -2.f, 3.f))) == Color(0.5f, 1.f, 2.f));
    CHECK(c->luminance_integral() == Approx(4.0 * M_PI * luminance(Color(0.5f, 1.f, 2.f))));
}

TEST_CASE("environment: the lat-long mapping is Mitsuba's (+y up, u = 0 towards -z, u = 1/4 towards +x)", "[environment]") {
    // One bright texel per test, the rest dim: eval() must find it in the
    // direction Mitsuba's envmap maps it to, d = (sin t sin p, cos t, -sin t cos p)
    // for phi = 2 pi u, theta = pi v, then to_world.
    const int w = 16, h = 8;
    struct Case {
        int x, y;
        Vec3 local;  // direction of the texel's centre in the emitter's frame
    };
    const float st = std::sin(float(M_PI) * 4.5f / 8.f), ct = std::cos(float(M_PI) * 4.5f / 8.f);
    // Texel centres: u = (x + 0.5) / 16, v = (y + 0.5) / 8. At the poles u is
    // undefined, so there the whole row is bright (x = -1).
    const std::vector<Case> cases = {
        {3, 4, Vec3(st * std::sin(2.f * float(M_PI) * 3.5f / 16.f), ct, -st * std::cos(2.f * float(M_PI) * 3.5f / 16.f))},
        {13, 2, Vec3(std::sin(float(M_PI) * 2.5f / 8.f) * std::sin(2.f * float(M_PI) * 13.5f / 16.f), std::cos(float(M_PI) * 2.5f / 8.f),
                     -std::sin(float(M_PI) * 2.5f / 8.f) * std::cos(2.f * float(M_PI) * 13.5f / 16.f))},
        {-1, 0, Vec3(0.f, 1.f, 0.f)},   // the top row looks up
        {-1, 7, Vec3(0.f, -1.f, 0.f)},  // the bottom row down
    };
    for (const glm::mat3 rot : {glm::mat3(1.f), rotation(90.f, Vec3(0.f, 1.f, 0.f)), rotation(30.f, Vec3(1.f, 0.f, 0.f))})
        for (const Case& c : cases) {
            Image m(w, h, 3, 0.1f);
            for (int x = 0; x < w; ++x)
                if (x == c.x || c.x < 0) m.set_rgb(x, c.y, Color(100.f));
            const auto env = Environment::from_map(m, rot, 1.f, "one texel");
            const Vec3 world = rot * glm::normalize(c.local);
            CHECK(env->eval(world).r == Approx(100.f).epsilon(1e-4));
            // Without to_world the texel is elsewhere: where the rotation
            // moves it by more than a texel's diagonal (32 degrees), the
            // unrotated direction misses it.
            INFO("texel " << c.x << ", " << c.y << " world " << world.x << " " << world.y << " " << world.z);
            if (glm::dot(world, glm::normalize(c.local)) < std::cos(glm::radians(35.f)))
                CHECK(env->eval(glm::normalize(c.local)).r < 50.f);
        }
    // Bilinear between texel centres, identity frame, on a ramp (r = column
    // + 1, g = row + 1): a centre gives its texel, a point a quarter of the
    // way to the next centre 1/4 of the difference.
    Image m(w, h, 3, 0.f);
    for (int x = 0; x < w; ++x)
        for (int y = 0; y < h; ++y) m.set_rgb(x, y, Color(float(x + 1), float(y + 1), 1.f));
    const auto env = Environment::from_map(m, glm::mat3(1.f), 1.f, "ramp");
    const auto at = [&](float u, float v) { return env->eval(env->uv_to_direction(Vec2(u, v))); };
    CHECK(at(4.5f / 16, 4.5f / 8).r == Approx(5.f).epsilon(1e-4));
    CHECK(at(4.5f / 16, 4.5f / 8).g == Approx(5.f).epsilon(1e-4));
    CHECK(at(4.75f / 16, 4.5f / 8).r == Approx(5.25f).epsilon(1e-4));
    CHECK(at(4.5f / 16, 5.f / 8).g == Approx(5.5f).epsilon(1e-4));
    // Exact axes: +x is u = 1/4, v = 1/2, the corner of texels 3-4 x 3-4;
    // +z is u = 1/2 (columns 7-8), -x u = 3/4 (11-12); -z is u = 0, halfway
    // between the last column and the first (u wraps).
    CHECK(env->eval(Vec3(1.f, 0.f, 0.f)).r == Approx(4.5f).epsilon(1e-4));
    CHECK(env->eval(Vec3(1.f, 0.f, 0.f)).g == Approx(4.5f).epsilon(1e-4));
    CHECK(env->eval(Vec3(0.f, 0.f, 1.f)).r == Approx(8.5f).epsilon(1e-4));
    CHECK(env->eval(Vec3(-1.f, 0.f, 0.f)).r == Approx(12.5f).epsilon(1e-4));
    CHECK(env->eval(Vec3(0.f, 0.f, -1.f)).r == Approx(8.5f).epsilon(1e-4));
    CHECK(env->eval(glm::normalize(Vec3(0.01f, 0.f, -1.f))).r < 8.5f);  // just past u = 0: nearer column 0 (r = 1)
    // Towards the poles v is clamped: beyond the first and last rows' centres, their values.
    CHECK(env->eval(glm::normalize(Vec3(1.f, 10.f, 0.f))).g == Approx(1.f).epsilon(1e-4));
    CHECK(env->eval(glm::normalize(Vec3(1.f, -10.f, 0.f))).g == Approx(8.f).epsilon(1e-4));
    const Vec2 uv = env->direction_to_uv(Vec3(1.f, 0.f, 0.f));
    CHECK(uv.x == Approx(0.25f));
    CHECK(uv.y == Approx(0.5f));
    // A to_world that is not a rotation is refused.
    CHECK_THROWS_WITH(Environment::from_map(m, glm::mat3(2.f), 1.f, "ramp"), Catch::Contains("ramp") && Catch::Contains("rotation"));
    Image bad(2, 2, 3, 1.f);
    bad.set_rgb(1, 0, Color(std::nanf(""), 0.f, 0.f));
    CHECK_THROWS_WITH(Environment::from_map(bad, glm::mat3(1.f), 1.f, "bad.exr"), Catch::Contains("bad.exr") && Catch::Contains("(1, 0)"));
    CHECK_THROWS_WITH(Environment::from_map(Image(2, 2, 3, 0.f), glm::mat3(1.f), 1.f, "black.exr"), Catch::Contains("black"));
}

TEST_CASE("environment: the scene selects it by power, and its light samples are infinite", "[environment]") {
    auto scene = env_box(16);
    const float tri_pdf_before = small_box("Original", 16)->light_pdf_a(0) + 0.f;
    uint32_t emitter = 0;
    for (uint32_t t = 0; t < scene->mesh().size(); ++t)
        if (scene->light_pdf_a(t) > 0.f) emitter = t;
    const float p_env = scene->environment_selection();
    REQUIRE(p_env > 0.f);
    REQUIRE(p_env < 1.f);
    // The triangles share what the environment leaves.
    const auto plain = small_box("Original", 16);
    CHECK(scene->light_pdf_a(emitter) == Approx((1.f - p_env) * plain->light_pdf_a(emitter)).epsilon(1e-5));
    (void)tri_pdf_before;
    // Expected selection share: r^2 times the luminance integral against L A.
    double tri_power = 0.0;
    for (uint32_t t = 0; t < scene->mesh().size(); ++t) {
        const Color le = scene->materials()[scene->mesh().material_ids[t]].emission;
        const Vec3* p = &scene->mesh().positions[3 * t];
        tri_power += luminance(le) * 0.5 * glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    }
    const double r = scene->bounding_radius();
    const double env_power = r * r * scene->environment()->luminance_integral();
    CHECK(p_env == Approx(env_power / (env_power + tri_power)).epsilon(1e-5));
    int infinite = 0;
    const Vec3 ref(0.f, 1.f, 0.f);
    for (uint32_t i = 0; i < 4000; ++i) {
        Sampler s(SampleKey{3, i, 0, 0});
        const float u_sel = s.next1d();
        const LightSample ls = scene->sample_light(ref, u_sel, s.next2d());
        CHECK(ls.infinite == scene->picks_environment(u_sel));
        if (!ls.infinite) continue;
        ++infinite;
        CHECK(ls.pdf_a == 0.f);  // code unaware of environments drops the sample
        CHECK(ls.pdf_w == Approx(scene->environment_pdf(-ls.n)).epsilon(1e-4));
        CHECK(ls.radiance == scene->environment()->eval(-ls.n));
        // The far point is outside the bounding sphere, along the direction.
        CHECK(glm::length(ls.p - scene->bounds_center()) > scene->bounding_radius());
        CHECK(glm::dot(glm::normalize(ls.p - ref), -ls.n) == Approx(1.f).epsilon(1e-5));
    }
    CHECK(double(infinite) / 4000.0 == Approx(p_env).margin(0.03));
    // No environment: no change to the light selection.
    CHECK(plain->environment() == nullptr);
    CHECK(plain->environment_selection() == 0.f);
    CHECK(plain->environment_pdf(Vec3(0.f, 0.f, 1.f)) == 0.f);
    // An environment alone is a light.
    CHECK(furnace(0.5f, 1.f, 8)->has_lights());
    CHECK(furnace(0.5f, 1.f, 8)->environment_selection() == 1.f);
}

TEST_CASE("environment: white furnace for pt, bdpt and gpt", "[environment][statistical]") {
    // Albedo 0.6 under radiance 1.5: the object is 0.9 everywhere, the
    // background 1.5 exactly (a camera ray that escapes has weight 1).
    // The object's pixels are independent unbiased estimates of 0.9 whose
    // spread gives the standard error: |z| < 4 and within 1%.
    const float a = 0.6f, l = 1.5f;
    const auto scene = furnace(a, l, 32);
    std::vector<std::pair<int, int>> inside, outside;
    furnace_pixels(*scene, inside, outside);
    REQUIRE(inside.size() > 150);
    REQUIRE(outside.size() > 150);
    for (const char* integ : {"pt", "bdpt", "gpt"}) {
        INFO(integ);
        const FrameBuffer fb = render(*scene, integ, Params(), 64, 11);
        const Image& c = fb.get("color");
        for (const auto& [x, y] : outside) {
            INFO("background pixel " << x << ", " << y);
            CHECK(grey(c, x, y) == Approx(l).epsilon(1e-5));
        }
        const auto [m, se] = mean_se(c, inside);
        CAPTURE(m, se);
        CHECK(std::abs(m - a * l) < 4.0 * se);
        CHECK(m == Approx(a * l).epsilon(0.01));
        CHECK(se < 0.002);  // power: a 1% error is many standard errors
    }
    // Each of bdpt's families alone, unweighted: light tracing from the
    // environment (strategy light) and the paths of one bounce by each
    // strategy, against their exact values: the object's one-bounce
    // radiance is a L (every reflected ray escapes).
    for (const char* st : {"light", "0,3", "1,2", "2,1"}) {
        INFO("strategy " << st);
        const bool one_bounce = std::string(st) != "light";
        const FrameBuffer fb = render(*scene, "bdpt", params({{"strategy", st}, {"max_depth", one_bounce ? "2" : "-1"}}), 64, 12);
        const auto [m, se] = mean_se(fb.get("color"), inside);
        CAPTURE(m, se);
        // (0, 3) has no variance here: a cosine-sampled bounce that always escapes.
        CHECK(std::abs(m - a * l) <= std::max(4.0 * se, 1e-5));
        CHECK(m == Approx(a * l).epsilon(0.02));
    }
}

TEST_CASE("environment: light subpaths leave the bounding disk with the densities they record", "[environment][bdpt][statistical]") {
    // A light subpath from the environment picks a direction, then a point
    // on the disk across the bounding sphere; its first hit x has the disk's
    // density times |cos| at x. So over many subpaths the mean of
    // 1{hit} |cos| / pdf_fwd(x) is the area the object projects along the
    // sampled directions (1 / pdf_fwd alone has infinite variance at the
    // silhouette). Under a constant environment the directions are uniform,
    // and a convex body's mean projected area is a quarter of its surface
    // (Cauchy's surface area formula). The throughput a subpath starts with
    // is Le / (p_dir p_disk).
    auto scene = furnace(0.5f, 1.f, 8);
    scene->set_environment(Environment::constant(Color(0.7f, 1.f, 1.3f)));
    double area = 0.0;
    const TriangleMesh& m = scene->mesh();
    for (size_t t = 0; t < m.size(); ++t) {
        const Vec3* p = &m.positions[3 * t];
        area += 0.5 * glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    }
    const int n = 400000;
    double s = 0.0, s2 = 0.0;
    int hits = 0;
    Subpath light;
    for (int i = 0; i < n; ++i) {
        const Sampler sampler(SampleKey{9, uint32_t(i), 0, 0});
        trace_light_subpath(*scene, sampler, {1, 5}, light);
        REQUIRE(light.size() >= 1);
        REQUIRE(light.v[0].infinite);
        REQUIRE(light.v[0].pdf_fwd == Approx(scene->environment_pdf(-light.v[0].si.ng)).epsilon(2e-3));
        if (light.size() < 2) continue;
        const Vertex& x = light.v[1];
        const double cos_x = std::abs(glm::dot(x.si.ng, light.v[0].si.ng));
        CHECK(x.pdf_fwd == Approx(environment_disk_pdf(*scene) * cos_x).epsilon(1e-4));
        const double le = luminance(light.v[0].le);
        CHECK(luminance(x.beta) * light.v[0].pdf_fwd * environment_disk_pdf(*scene) == Approx(le).epsilon(1e-3));
        const double v = cos_x / x.pdf_fwd;
        s += v, s2 += v * v;
        ++hits;
    }
    const double mean = s / n, se = std::sqrt((s2 / n - mean * mean) / (n - 1));
    CAPTURE(mean, se, area, hits);
    CHECK(std::abs(mean - area / 4.0) < 4.0 * se);
    CHECK(se < 0.0025 * area);  // power: a 4% error is seen
}

TEST_CASE("environment: bdpt equals pt on an environment-lit box, weighted and by strategy", "[environment][bdpt][statistical]") {
    // The box's ceiling light and the rotated test map through its open
    // front: paths mix both lights and the walls occlude most of the map.
    // 24 x 24 pixels in 6 x 6 blocks, 16 runs: |z| < 4.5 over the tests.
    // Sample counts are set so that every part also rejects its image scaled
    // by 0.95 (the bilinearly interpolated map is sampled by cell, so its
    // light samples vary more than the nearest-texel lookup's did).
    const int res = 24, block = 6, runs = 16;
    const auto scene = env_box(res);
    const BlockStats pt = grey_stats(render_runs(*scene, "pt", Params(), 64, runs, 100), "color", block);
    const BlockStats b = grey_stats(render_runs(*scene, "bdpt", Params(), 16, runs, 200), "color", block);
    double z = max_z(b, pt), z_dark = max_z(scaled(b, 0.95), pt);
    CAPTURE(z, z_dark);
    CHECK(z < 4.5);
    CHECK(z_dark > 4.5);
    // With a dimmer map the two lights are selected about equally often, so
    // that the selection probability in the environment vertex's origin
    // density weighs in the MIS weights (0.88 above, 0.48 here); more
    // samples, so that weights off by that factor are seen (z 5.4 without it).
    {
        const auto dim = env_box(res, 0.06f);
        CAPTURE(scene->environment_selection(), dim->environment_selection());
        CHECK(dim->environment_selection() < 0.6f);
        const BlockStats pt_dim = grey_stats(render_runs(*dim, "pt", Params(), 384, runs, 700), "color", block);
        const BlockStats b_dim = grey_stats(render_runs(*dim, "bdpt", Params(), 96, runs, 800), "color", block);
        z = max_z(b_dim, pt_dim), z_dark = max_z(scaled(b_dim, 0.95), pt_dim);
        CAPTURE(z, z_dark);
        CHECK(z < 4.5);
        CHECK(z_dark > 4.5);
    }
    // pt without the environment is rejected: the environment's light is seen.
    const auto plain = small_box("Original", res);
    CHECK(max_z(grey_stats(render_runs(*plain, "pt", Params(), 64, runs, 100), "color", block), pt) > 4.5);
    // Light tracing alone (t = 1 from both lights, s = 0 for what the camera sees directly).
    const BlockStats lt = grey_stats(render_runs(*scene, "bdpt", params({{"strategy", "light"}}), 32, runs, 300), "color", block);
    z = max_z(lt, pt), z_dark = max_z(scaled(lt, 0.95), pt);
    CAPTURE(z, z_dark);
    CHECK(z < 4.5);
    CHECK(z_dark > 4.5);
    // Each strategy of the paths of exactly two segments alone: the
    // reference is pt(max_depth 2) minus pt(max_depth 1) with the same seeds.
    std::vector<FrameBuffer> two = render_runs(*scene, "pt", params({{"max_depth", "2"}}), 128, runs, 400);
    const std::vector<FrameBuffer> one = render_runs(*scene, "pt", params({{"max_depth", "1"}}), 128, runs, 400);
    for (int r = 0; r < runs; ++r) {
        Image& c = two[r].get("color");
        for (size_t i = 0; i < c.values().size(); ++i) c.values()[i] -= one[r].get("color").values()[i];
    }
    const BlockStats ref2 = grey_stats(two, "color", block);
    for (const char* st : {"0,3", "1,2", "2,1"}) {
        INFO("strategy " << st);
        const long long spp = std::string(st) == "0,3" ? 256 : 40;
        const BlockStats s = grey_stats(render_runs(*scene, "bdpt", params({{"strategy", st}}), spp, runs, 500), "color", block);
        z = max_z(s, ref2), z_dark = max_z(scaled(s, 0.95), ref2);
        CAPTURE(z, z_dark);
        CHECK(z < 4.5);
        CHECK(z_dark > 4.5);
    }
}

TEST_CASE("environment: the densities of joined environment paths are the full path's, and their weights sum to one", "[environment][bdpt][mis]") {
    // As the same test of test_bdpt.cpp (tests/joined_densities.h), for the
    // paths that reach the environment: camera walks that escape (s = 0) and
    // light subpaths that start on it (s >= 2). The environment vertex's
    // solid-angle densities and its first hit's disk density must be
    // recorded as pdf_area() recomputes them.
    test::DensityTally tally;
    int from_env = 0, to_env = 0;
    const auto scene = env_box(16);
    Subpath camera, light;
    for (uint32_t i = 0; i < 3000; ++i) {
        const Sampler sampler(SampleKey{5, i % 16, (i / 16) % 16, i});
        const Vec2 film = Vec2(float(i % 16), float((i / 16) % 16)) + sampler.at2(dims::kFilm);
        trace_camera_subpath(*scene, film, sampler, {8, 5}, camera);
        trace_light_subpath(*scene, sampler, {7, 5}, light);
        for (int t = 1; t <= camera.size(); ++t)
            for (int s = 0; s <= light.size(); ++s) {
                if (s == 1 || s + t < 3 || s + t > 9 || (s == 0 && t == 1)) continue;
                const bool env = s == 0 ? camera.v[t - 1].infinite : light.v[0].infinite;
                if (!env) continue;
                INFO("sample " << i);
                if (test::check_joined_densities(*scene, light, camera, {s, t}, sampler, tally, true))
                    (s == 0 ? to_env : from_env)++;
            }
    }
    CAPTURE(tally.checked, from_env, to_env, tally.compared, tally.loose, tally.worst);
    CHECK(tally.loose < tally.compared / 20);
    CHECK(tally.worst < 0.1);
    CHECK(from_env > 100);
    CHECK(to_env > 100);
}

TEST_CASE("environment: scene files and Mitsuba XML give constant and envmap environments", "[environment][mitsuba]") {
    OutDir dir("environment");
    // A map with one bright texel centred on u = 1/4, v = 1/2 (direction +x in its frame).
    Image m(6, 3, 3, 0.25f);
    m.set_rgb(1, 1, Color(8.f, 4.f, 2.f));
    write_exr_image(dir("sky.exr"), m);
    {
        std::ofstream(dir("tri.obj")) << "v -1 0 -1\nv 1 0 -1\nv 0 1 -1\nf 1 2 3\n";
    }
    const std::string cam = R"("camera": {"position": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40, "width": 8, "height": 8},
                               "meshes": ["tri.obj"])";
    const auto json_scene = [&](const std::string& env) {
        std::ofstream(dir("scene.json")) << "{" << cam << ", \"environment\": " << env << "}";
        return dir("scene.json");
    };
    {
        const SceneFile sf = load_scene_file(json_scene(R"({"type": "constant", "radiance": [1, 2, 3], "scale": 0.5})"));
        REQUIRE(sf.scene->environment());
        CHECK(sf.scene->environment()->is_constant());
        CHECK(sf.scene->environment()->eval(Vec3(0.f, 0.f, 1.f)) == Color(0.5f, 1.f, 1.5f));
    }
    {
        // Rotated 90 degrees about +y: the map's +x is the world's -z.
        const SceneFile sf = load_scene_file(
            json_scene(R"({"type": "envmap", "file": "sky.exr", "scale": 2, "transform": {"rotate": [0, 1, 0, 90]}})"));
        REQUIRE(sf.scene->environment());
        CHECK(near_color(sf.scene->environment()->eval(Vec3(0.f, 0.f, -1.f)), Color(16.f, 8.f, 4.f)));
        CHECK(near_color(sf.scene->environment()->eval(Vec3(1.f, 0.f, 0.f)), Color(0.5f)));
        CHECK(std::find(sf.inputs.begin(), sf.inputs.end(), dir("sky.exr")) != sf.inputs.end());
    }
    CHECK_THROWS_WITH(load_scene_file(json_scene(R"({"type": "sunsky"})")), Catch::Contains("environment.type"));
    CHECK_THROWS_WITH(load_scene_file(json_scene(R"({"type": "constant"})")), Catch::Contains("environment.radiance"));
    CHECK_THROWS_WITH(load_scene_file(json_scene(R"({"type": "envmap", "file": "none.exr"})")), Catch::Contains("none.exr"));
    CHECK_THROWS_WITH(load_scene_file(json_scene(R"({"type": "constant", "radiance": 1, "file": "sky.exr"})")),
                      Catch::Contains("'file'"));

    // Mitsuba: constant (radiance, scale) and envmap (filename, to_world, scale).
    const std::string sensor = R"(<sensor type="perspective"><float name="fov" value="40"/>
      <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
      <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
      <shape type="rectangle"/>)";
    const auto xml = [&](const std::string& body, const std::string& version = "3.0.0") {
        std::ofstream(dir("scene.xml")) << "<scene version=\"" << version << "\">" << sensor << body << "</scene>\n";
        return dir("scene.xml");
    };
    {
        const SceneFile sf = load_scene_file(xml(R"(<emitter type="constant"><rgb name="radiance" value="0.3, 0.3, 0.3"/><float name="scale" value="2"/></emitter>)"));
        REQUIRE(sf.scene->environment());
        CHECK(sf.scene->environment()->eval(Vec3(0.f, 1.f, 0.f)) == Color(0.6f));
        CHECK(sf.scene->has_lights());
    }
    {
        // The living room's to_world (a quarter turn about y), in 0.6 spelling, and a gamma that is ignored.
        const SceneFile sf = load_scene_file(xml(R"(<emitter type="envmap" id="sky">
            <transform name="toWorld"><matrix value="-4.37114e-008 0 1 0 0 1 0 0 -1 0 -4.37114e-008 0 0 0 0 1"/></transform>
            <string name="filename" value="sky.exr"/><float name="scale" value="3"/><float name="gamma" value="2.2"/></emitter>)",
                                                 "0.6.0"));
        REQUIRE(sf.scene->environment());
        // Local +x maps to world (m00, m10, m20) = (0, 0, -1).
        CHECK(near_color(sf.scene->environment()->eval(Vec3(0.f, 0.f, -1.f)), Color(24.f, 12.f, 6.f)));
        bool warned = false;
        for (const std::string& w : sf.warnings) warned = warned || w.find("gamma 2.2 is ignored") != std::string::npos;
        CHECK(warned);
    }
    const auto error = [&](const std::string& body) {
        try {
            load_scene_file(xml(body));
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    CHECK_THAT(error(R"(<emitter type="envmap" id="e"><string name="filename" value="gone.exr"/></emitter>)"),
               Catch::Contains("<emitter type=\"envmap\" id=\"e\">") && Catch::Contains("gone.exr"));
    CHECK_THAT(error(R"(<emitter type="envmap" id="e"><string name="filename" value="sky.exr"/>
                        <transform name="to_world"><scale value="2"/></transform></emitter>)"),
               Catch::Contains("id=\"e\"") && Catch::Contains("rotation"));
    CHECK_THAT(error(R"(<emitter type="constant"/><emitter type="constant"/>)"), Catch::Contains("one environment"));
    CHECK_THAT(error(R"(<emitter type="constant"/><emitter type="sunsky" id="sun"/>)"),
               Catch::Contains("<emitter type=\"sunsky\" id=\"sun\">") && Catch::Contains("one environment"));
    CHECK_THAT(error(R"(<emitter type="constant"><float name="sheen" value="1"/></emitter>)"), Catch::Contains("sheen"));
}

TEST_CASE("environment: gpt is unbiased on an environment-lit box, for every shift", "[environment][gpt][statistical]") {
    // Base and offset paths that leave the box through its open front end on
    // the environment, and light samples towards it are shared by direction.
    // E[dx], E[dy] against the differences of pt's image and the primal
    // against pt's: block z-tests as in the gpt tests, 24 x 24 pixels in 6 x 6
    // blocks over 16 runs a side (|z| < 5 for the gradients' 25 tests per
    // shift and layer, 4.5 for the primal's 16).
    const int res = 24, block = 6, runs = 16;
    const auto scene = env_box(res);
    const std::vector<FrameBuffer> pt = render_runs(*scene, "pt", Params(), 128, runs, 1000);
    for (const char* shift : {"half-vector", "reconnection", "replay", "replay-reconnect"}) {
        INFO("shift " << shift);
        const std::vector<FrameBuffer> g =
            render_runs(*scene, "gpt", params({{"shift", shift}, {"reconstruct", "none"}}), 48, runs, 1);
        check_unbiased_gradients(gradient_z(pt, g, block));
    }
}
