// The path tracer against known answers: emitters seen directly, the white
// furnace, a floor lit by a parallel square light (form factor), NEE+MIS vs
// BSDF sampling on the Cornell box; against another renderer (Blender
// Cycles, on two Cornell boxes); and the render loop's guarantees:
// bit-identical images for any thread count, exact resume, NaN accounting.
//
// Statistical checks are z-tests with the per-pixel sample variance the
// renderer reports; thresholds are Bonferroni-corrected for the number of
// tests in a case so a correct renderer fails with probability < 1e-3, and
// each case shows the test has power (a wrong answer is rejected).
#include <catch2/catch.hpp>

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <mutex>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/path/dims.h"
#include "gdr/integrators/pt.h"
#include "gdr/integrators/tiled.h"
#include "gdr/io/scene_file.h"
#include "block_stats.h"
#include "cycles_compare.h"

using namespace gdr;
using gdr::test::z_threshold;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {

const std::string kScenes = GDR_SOURCE_DIR "/tests/scenes/";

FrameBuffer render(const Scene& scene, long long spp, uint64_t seed, const std::string& params = "", int threads = 0,
                   long long first_sample = 0, RenderStats* stats = nullptr) {
    Params p("test");
    if (!params.empty()) {
        size_t a = 0;
        while (a < params.size()) {
            const size_t b = params.find(',', a);
            p.set_from_text(params.substr(a, b == std::string::npos ? std::string::npos : b - a));
            a = b == std::string::npos ? params.size() : b + 1;
        }
    }
    auto pt = integrator_registry().create("pt", p);
    RenderSettings st;
    st.spp = spp;
    st.seed = seed;
    st.threads = threads;
    st.first_sample = first_sample;
    FrameBuffer fb;
    const RenderStats rs = pt->render(scene, st, fb, {});
    if (stats) *stats = rs;
    return fb;
}

// Mean of one channel over a pixel rectangle and the variance of that mean,
// from the per-pixel means and per-sample variances of a render.
struct Estimate {
    double mean = 0, var = 0;
};
Estimate region(const FrameBuffer& fb, int ch, int x0, int y0, int x1, int y1) {
    const Image &c = fb.get("color"), &v = fb.get("variance");
    const double spp = fb.get("spp").at(0, 0);
    Estimate e;
    const double n = double(x1 - x0) * (y1 - y0);
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) e.mean += c.at(x, y, ch) / n, e.var += v.at(x, y, ch) / spp / (n * n);
    return e;
}

// z of a render's region against a known value (an exactly known value has
// zero variance; a floor on the standard error keeps z finite).
double z_known(const Estimate& e, double expected) {
    return (e.mean - expected) / std::sqrt(std::max(e.var, 1e-14 * (1.0 + expected * expected)));
}
double z_two(const Estimate& a, const Estimate& b) {
    return (a.mean - b.mean) / std::sqrt(std::max(a.var + b.var, 1e-14));
}

// Largest |z| over every pixel and channel of a render against expected(x, y, ch).
double max_pixel_z(const FrameBuffer& fb, const std::function<double(int, int, int)>& expected) {
    double worst = 0;
    for (int y = 0; y < fb.height(); ++y)
        for (int x = 0; x < fb.width(); ++x)
            for (int ch = 0; ch < 3; ++ch) worst = std::max(worst, std::abs(z_known(region(fb, ch, x, y, x + 1, y + 1), expected(x, y, ch))));
    return worst;
}

// Radiance leaving a Lambertian floor point under a parallel rectangle:
// albedo * Le * F, with F the differential-area-to-rectangle form factor.
// The corner formula (the rectangle [0,a]x[0,b] at height h over the point)
// is odd in a and in b, so any rectangle follows by inclusion-exclusion.
double form_factor_corner(double a, double b, double h) {
    const double A = a / h, B = b / h, sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
    return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * M_PI);
}
double form_factor(double px, double pz, double x0, double x1, double z0, double z1, double h) {
    return form_factor_corner(x1 - px, z1 - pz, h) - form_factor_corner(x0 - px, z1 - pz, h) -
           form_factor_corner(x1 - px, z0 - pz, h) + form_factor_corner(x0 - px, z0 - pz, h);
}

}  // namespace

TEST_CASE("pt: an emitter seen directly gives exactly its radiance, from the front only", "[pt][analytic]") {
    const SceneFile front = load_scene_file(kScenes + "emitter-wall/scene.json");
    const SceneFile back = load_scene_file(kScenes + "emitter-wall/back.json");
    for (const char* params : {"", "nee=false"}) {
        const FrameBuffer f = render(*front.scene, 8, 1, params), b = render(*back.scene, 8, 1, params);
        for (int y = 0; y < f.height(); ++y)
            for (int x = 0; x < f.width(); ++x) {
                INFO(params << " pixel " << x << ", " << y);
                REQUIRE(f.get("color").rgb(x, y) == Color(3.f, 2.f, 0.5f));
                REQUIRE(f.get("variance").rgb(x, y) == Color(0.f));
                REQUIRE(b.get("color").rgb(x, y) == Color(0.f));
            }
        CHECK(f.get("depth").at(5, 4) == Approx(2.f).epsilon(0.01));
        CHECK(f.get("normal").rgb(5, 4).z == Approx(1.f));
    }
}

TEST_CASE("pt: white furnace, L = Le / (1 - albedo), and Le (1 - a^k) / (1 - a) at max_depth k", "[pt][analytic][statistical]") {
    // A closed Lambertian cube emitting Le = 1 from every inward face.
    const SceneFile grey = load_scene_file(kScenes + "furnace/scene.json");
    const SceneFile rgb = load_scene_file(kScenes + "furnace/coloured.json");
    struct Case {
        const Scene* scene;
        Color albedo;
        int max_depth;
        const char* params;
    };
    const Color a_grey(0.5f), a_rgb(0.2f, 0.5f, 0.8f);
    const std::vector<Case> cases = {
        {grey.scene.get(), a_grey, -1, ""},          {grey.scene.get(), a_grey, -1, "nee=false"},
        {rgb.scene.get(), a_rgb, -1, ""},            {rgb.scene.get(), a_rgb, -1, "nee=false"},
        {grey.scene.get(), a_grey, 1, "max_depth=1"}, {grey.scene.get(), a_grey, 2, "max_depth=2"},
        {rgb.scene.get(), a_rgb, 3, "max_depth=3"},  {rgb.scene.get(), a_rgb, 3, "max_depth=3,nee=false"},
        {rgb.scene.get(), a_rgb, 6, "max_depth=6,rr_depth=2"}};
    // Per case and channel: the whole image, and its four quadrants (a bias at
    // the cube's edges or corners would show there). Single pixels are not
    // tested: Russian roulette makes a pixel's 128 samples so skewed (a few
    // survivors carry the tail) that its variance estimate is unreliable.
    const double zt = z_threshold(int(cases.size()) * 3 * 5);
    for (const Case& c : cases) {
        const FrameBuffer fb = render(*c.scene, 128, 17, c.params);
        INFO("albedo " << c.albedo.r << "," << c.albedo.g << "," << c.albedo.b << " " << c.params);
        const int w = fb.width(), h = fb.height();
        for (int ch = 0; ch < 3; ++ch) {
            const double a = c.albedo[ch];
            const double expected = c.max_depth < 0 ? 1.0 / (1.0 - a) : (1.0 - std::pow(a, c.max_depth)) / (1.0 - a);
            const Estimate e = region(fb, ch, 0, 0, w, h);
            INFO("channel " << ch << ": " << e.mean << " +- " << std::sqrt(e.var) << " vs " << expected);
            CHECK(std::abs(z_known(e, expected)) < zt);
            // Power: an answer 5% off is rejected.
            CHECK(std::abs(z_known(e, 1.05 * expected)) > zt);
            for (int q = 0; q < 4; ++q) {
                const int x0 = (q % 2) * w / 2, y0 = (q / 2) * h / 2;
                CHECK(std::abs(z_known(region(fb, ch, x0, y0, x0 + w / 2, y0 + h / 2), expected)) < zt);
            }
        }
    }
}

TEST_CASE("pt: a floor under a parallel square light matches the form factor", "[pt][analytic][statistical]") {
    // Floor y = 0 (albedo 0.6), emitter [-0.25, 0.25]^2 at height 1 (Le 10) facing down.
    const double rho = 0.6, le = 10.0, h = 1.0, s = 0.25;
    // The closed form against brute-force quadrature of cos cos / (pi r^2) at one point.
    {
        const double px = 0.3, pz = -0.1;
        double f = 0;
        const int n = 400;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                const double x = -s + (i + 0.5) * 2 * s / n - px, z = -s + (j + 0.5) * 2 * s / n - pz;
                const double r2 = x * x + z * z + h * h;
                f += h * h / (M_PI * r2 * r2) * (2 * s / n) * (2 * s / n);
            }
        CHECK(form_factor(px, pz, -s, s, -s, s, h) == Approx(f).epsilon(1e-5));
    }
    const SceneFile sf = load_scene_file(kScenes + "parallel-light/scene.json");
    const Camera& cam = sf.scene->camera();
    // Expected pixel value: the pixel-footprint average of rho Le F (64 film points per pixel).
    std::vector<double> expected(size_t(cam.width()) * cam.height(), 0.0);
    for (int y = 0; y < cam.height(); ++y)
        for (int x = 0; x < cam.width(); ++x) {
            double sum = 0;
            for (int i = 0; i < 8; ++i)
                for (int j = 0; j < 8; ++j) {
                    const Ray r = cam.generate_ray(Vec2(x + (i + 0.5f) / 8, y + (j + 0.5f) / 8));
                    REQUIRE(r.d.y < 0.f);
                    const double t = -double(r.o.y) / r.d.y;
                    sum += rho * le * form_factor(r.o.x + t * r.d.x, r.o.z + t * r.d.z, -s, s, -s, s, h) / 64;
                }
            expected[size_t(y) * cam.width() + x] = sum;
        }
    auto exp_at = [&](int x, int y, int) { return expected[size_t(y) * cam.width() + x]; };
    const int pixels = cam.width() * cam.height();
    for (const auto& [params, spp] : {std::pair<const char*, int>{"", 64}, {"nee=false", 2048}}) {
        const FrameBuffer fb = render(*sf.scene, spp, 23, params);
        INFO(params);
        double mean_expected = 0;
        for (double v : expected) mean_expected += v / pixels;
        const Estimate e = region(fb, 1, 0, 0, cam.width(), cam.height());
        INFO("image mean " << e.mean << " +- " << std::sqrt(e.var) << " vs " << mean_expected);
        CHECK(std::abs(z_known(e, mean_expected)) < z_threshold(4));
        CHECK(std::abs(z_known(e, 1.05 * mean_expected)) > z_threshold(4));  // power: 5% off is rejected
        CHECK(max_pixel_z(fb, exp_at) < z_threshold(2 * pixels * 3));
    }
}

TEST_CASE("pt: NEE + MIS and BSDF sampling agree on the Cornell box", "[pt][statistical]") {
    // 24 x 24 pixels in 6 x 6 blocks: 16 blocks x 3 channels per comparison.
    // BSDF sampling finds the small light rarely; with too few samples its
    // block means are skewed low and their variance estimates too small, so
    // it gets 16x the samples (checked: worst |z| 1.8-3.4 over 12 seed pairs).
    const SceneFile sf = load_scene_file(kScenes + "cornell-small.json");
    const int res = 24, block = 6, n_blocks = (res / block) * (res / block);
    const double zt = z_threshold(2 * n_blocks * 3);
    auto max_block_z = [&](const FrameBuffer& a, const FrameBuffer& b) {
        double worst = 0;
        for (int by = 0; by < res; by += block)
            for (int bx = 0; bx < res; bx += block)
                for (int ch = 0; ch < 3; ++ch)
                    worst = std::max(worst, std::abs(z_two(region(a, ch, bx, by, bx + block, by + block),
                                                           region(b, ch, bx, by, bx + block, by + block))));
        return worst;
    };
    const FrameBuffer nee = render(*sf.scene, 64, 1), bsdf = render(*sf.scene, 1024, 2, "nee=false");
    CHECK(max_block_z(nee, bsdf) < zt);
    // Path-length limits must cut both estimators at the same place.
    const FrameBuffer nee3 = render(*sf.scene, 64, 3, "max_depth=3"), bsdf3 = render(*sf.scene, 1024, 4, "max_depth=3,nee=false");
    CHECK(max_block_z(nee3, bsdf3) < zt);
    // Power: dropping the indirect light (max_depth 2) is detected.
    CHECK(max_block_z(nee3, render(*sf.scene, 64, 5, "max_depth=2")) > zt);
}

TEST_CASE("pt: Cornell boxes agree with Blender Cycles (an independent production renderer)", "[pt][statistical][reference]") {
    // Cycles' block means of each scene (cycles_compare.h) against gdr's,
    // with variances from its per-pixel sample variances. Every block and
    // channel is tested at a family-wise level of 1e-3, and so is the whole
    // image's mean.
    // What it resolves: about 0.15% in the whole image's mean of the McGuire
    // box. Finer differences exist there: with 8 x 128 spp from each renderer
    // the means differed by 0.03% (z 3.5), and blocks along the ceiling's
    // edges by up to 0.25% (z up to 5.6), which this test does not see.
    // There gdr is the brighter; its NEE and BSDF-only estimators agree with
    // each other, and a 10x smaller ray offset does not move it.
    struct Case {
        const char* scene;      // under the source tree
        const char* reference;  // under tests/data
        long long spp;
    };
    const Case c = GENERATE(Case{"scenes/cornell-box/scene.json", "cycles-cornell-box.json", 32},
                            Case{"tests/scenes/cornell-cc0-256.json", "cycles-cornell-cc0-256.json", 128});
    INFO(c.scene);
    const test::CyclesReference ref(c.reference);
    const SceneFile sf = load_scene_file(std::string(GDR_SOURCE_DIR "/") + c.scene);
    REQUIRE(sf.scene->camera().width() == ref.width);
    REQUIRE(sf.scene->camera().height() == ref.height);
    const int n_blocks = ref.blocks;
    const auto compare = [&](const FrameBuffer& fb, double gain) { return test::compare_with_cycles(fb, ref, gain); };
    const FrameBuffer fb = render(*sf.scene, c.spp, 7);
    const test::CyclesWorst as_rendered = compare(fb, 1.0);
    CAPTURE(as_rendered.block, as_rendered.image);
    CHECK(as_rendered.block < z_threshold(n_blocks * 3));
    CHECK(as_rendered.image < z_threshold(3));
    // Power. The whole-image test rejects an image 0.5% too bright or too
    // dark (on the McGuire box, z about 12), and paths cut after 8 bounces,
    // which lose 0.6% of its light (z about 15).
    CHECK(compare(fb, 1.005).image > z_threshold(3));
    CHECK(compare(fb, 0.995).image > z_threshold(3));
    CHECK(compare(render(*sf.scene, c.spp, 7, "max_depth=8"), 1.0).image > z_threshold(3));
}

TEST_CASE("pt: images are bit-identical for 1, 2 and all threads", "[pt][determinism]") {
    const SceneFile sf = load_scene_file(kScenes + "cornell-small.json");
    const FrameBuffer a = render(*sf.scene, 8, 7, "", 1), b = render(*sf.scene, 8, 7, "", 2), c = render(*sf.scene, 8, 7, "", 0);
    REQUIRE(a.names() == b.names());
    for (const auto& name : a.names()) {
        INFO(name);
        const auto &va = a.get(name).values(), &vb = b.get(name).values(), &vc = c.get(name).values();
        REQUIRE(va.size() == vb.size());
        CHECK(std::memcmp(va.data(), vb.data(), va.size() * sizeof(float)) == 0);
        CHECK(std::memcmp(va.data(), vc.data(), va.size() * sizeof(float)) == 0);
    }
    // A different seed gives a different image.
    const FrameBuffer d = render(*sf.scene, 8, 8, "", 2);
    CHECK(std::memcmp(a.get("color").data(), d.get("color").data(), a.get("color").values().size() * sizeof(float)) != 0);
}

TEST_CASE("tiled integrators: kept accumulation buffers leave no trace in the next render", "[pt][tiled][determinism]") {
    // One integrator renders a big image, a small one, and the big one again
    // (reusing, shrinking and regrowing its buffers); each must equal a fresh
    // integrator's render bit for bit.
    const SceneFile big = load_scene_file(kScenes + "cornell-small.json");
    SceneFile small = load_scene_file(kScenes + "cornell-small.json");
    CameraDesc cd = small.scene->camera().desc();
    cd.width = 8, cd.height = 6;
    TriangleMesh mesh = small.scene->mesh();
    std::vector<Material> mats = small.scene->materials();
    const Scene tiny(std::move(mesh), std::move(mats), Camera(cd), "tiny");
    auto kept = integrator_registry().create("pt", Params("test"));
    RenderSettings st;
    st.spp = 3;
    st.seed = 5;
    for (const Scene* scene : std::initializer_list<const Scene*>{big.scene.get(), &tiny, big.scene.get()}) {
        FrameBuffer a, b;
        kept->render(*scene, st, a, {});
        integrator_registry().create("pt", Params("test"))->render(*scene, st, b, {});
        REQUIRE(a.names() == b.names());
        for (const auto& name : a.names()) {
            INFO(name << " at " << scene->camera().width() << "x" << scene->camera().height());
            const auto &va = a.get(name).values(), &vb = b.get(name).values();
            REQUIRE(va.size() == vb.size());
            CHECK(std::memcmp(va.data(), vb.data(), va.size() * sizeof(float)) == 0);
        }
    }
    auto* tiled = dynamic_cast<TiledIntegrator*>(kept.get());
    REQUIRE(tiled != nullptr);
    CHECK(tiled->release_buffers() > 0);
    CHECK(tiled->release_buffers() == 0);
}

TEST_CASE("pt: 8 spp resumed by 8 more equals one 16 spp render", "[pt][determinism]") {
    const SceneFile sf = load_scene_file(kScenes + "cornell-small.json");
    FrameBuffer first = render(*sf.scene, 8, 9);
    const FrameBuffer second = render(*sf.scene, 8, 9, "", 0, 8), full = render(*sf.scene, 16, 9);
    CHECK(second.metadata().at("first_sample") == "8");
    merge_renders(first, second);
    CHECK(first.metadata().at("spp") == "16");
    for (const auto& name : full.names()) {
        INFO(name);
        const auto &m = first.get(name).values(), &f = full.get(name).values();
        const double tol = name == "variance" ? 1e-4 : 1e-5;
        double worst = 0;
        for (size_t i = 0; i < f.size(); ++i) worst = std::max(worst, std::abs(double(m[i]) - f[i]) / (std::abs(double(f[i])) + 1e-6));
        CHECK(worst < tol);
    }
    // Starting again at sample 0 instead would repeat the first 8 samples: detected.
    FrameBuffer again = render(*sf.scene, 8, 9);
    merge_renders(again, render(*sf.scene, 8, 9));
    double diff = 0;
    for (size_t i = 0; i < full.get("color").values().size(); ++i)
        diff = std::max(diff, double(std::abs(again.get("color").values()[i] - full.get("color").values()[i])));
    CHECK(diff > 1e-3);
    // A malformed or zero sample count is named, not a bare "stoll" or a division by zero.
    for (const char* bad : {"many", "0", ""}) {
        FrameBuffer broken = render(*sf.scene, 1, 9);
        broken.metadata()["spp"] = bad;
        FrameBuffer into = render(*sf.scene, 1, 10);
        CHECK_THROWS_WITH(merge_renders(into, broken), Contains("second") && Contains("spp"));
    }
}

namespace {
// The test integrators below compute one sample of one pixel at a time:
// render() hands them one job at a time (batch_size() is 1).
class OneSampleIntegrator : public TiledIntegrator {
protected:
    virtual void sample(const Scene& scene, int x, int y, Sampler& sampler, float* out, uint64_t& rays) const = 0;
    void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        for (int i = 0; i < n; ++i) sample(scene, jobs[i].x, jobs[i].y, jobs[i].sampler, out + size_t(i) * stride, rays);
    }
};

// Writes NaN at pixel (1, 2), the pixel's x elsewhere: the render loop must
// drop and report the NaNs and keep the rest.
class NanAt12 final : public OneSampleIntegrator {
public:
    std::string describe() const override { return ""; }

protected:
    std::vector<SlotSpec> slots() const override { return {{"value", 1, true}}; }
    void sample(const Scene&, int x, int y, Sampler&, float* out, uint64_t& rays) const override {
        out[0] = (x == 1 && y == 2) ? std::nanf("") : float(x);
        ++rays;
    }
};
}  // namespace

TEST_CASE("tiled integrators: NaN samples are dropped, counted and located", "[pt][tiled]") {
    const SceneFile sf = load_scene_file(kScenes + "emitter-wall/scene.json");
    NanAt12 integ;
    RenderSettings st;
    st.spp = 5;
    FrameBuffer fb;
    std::mutex m;
    uint64_t last_samples = 0;
    const RenderStats rs = integ.render(*sf.scene, st, fb, [&](const Progress& p) {
        std::lock_guard<std::mutex> lock(m);
        last_samples = std::max(last_samples, p.samples);
    });
    CHECK(rs.nonfinite == 5);
    REQUIRE(!rs.nonfinite_pixels.empty());
    CHECK(rs.nonfinite_pixels[0] == std::pair<int, int>(1, 2));
    CHECK(fb.get("value").at(1, 2) == 0.f);
    CHECK(fb.get("value").at(3, 2) == 3.f);
    CHECK(fb.get("value_variance").at(3, 2) == 0.f);
    CHECK(rs.samples == uint64_t(5 * 10 * 8));
    CHECK(rs.rays == rs.samples);
    CHECK(last_samples == rs.samples);
    CHECK(fb.metadata().at("spp") == "5");
}

namespace {
// Writes numbers of its own sampler: a slot "a" (3 channels, with variance)
// and a slot "b" (1 channel, without). The test recomputes every sample.
class SamplerEcho final : public OneSampleIntegrator {
public:
    std::string describe() const override { return ""; }
    static void values(Sampler& s, float v[4]) {
        for (int c = 0; c < 3; ++c) v[c] = 10.f * s.next1d() - 2.f;
        v[3] = s.next1d();
    }

protected:
    std::vector<SlotSpec> slots() const override { return {{"a", 3, true}, {"b", 1, false}}; }
    void sample(const Scene&, int, int, Sampler& sampler, float* out, uint64_t& rays) const override {
        values(sampler, out);
        ++rays;
    }
};
}  // namespace

TEST_CASE("tiled integrators: layers are the samples' means and unbiased per-sample variances", "[pt][tiled]") {
    const SceneFile sf = load_scene_file(kScenes + "emitter-wall/scene.json");
    SamplerEcho integ;
    RenderSettings st;
    st.spp = 37;  // more than one pass of 16
    st.seed = 5;
    FrameBuffer fb;
    integ.render(*sf.scene, st, fb, {});
    REQUIRE(fb.has("a"));
    REQUIRE(fb.has("a_variance"));
    REQUIRE(fb.has("b"));
    CHECK(!fb.has("b_variance"));
    for (int y = 0; y < fb.height(); ++y)
        for (int x = 0; x < fb.width(); ++x) {
            double sum[4] = {}, sum2[3] = {};
            for (int i = 0; i < st.spp; ++i) {
                Sampler s(SampleKey{st.seed, uint32_t(x), uint32_t(y), uint32_t(i)});
                float v[4];
                SamplerEcho::values(s, v);
                for (int c = 0; c < 4; ++c) sum[c] += v[c];
                for (int c = 0; c < 3; ++c) sum2[c] += double(v[c]) * v[c];
            }
            const double n = double(st.spp);
            for (int c = 0; c < 3; ++c) {
                const double mean = sum[c] / n, var = (sum2[c] - n * mean * mean) / (n - 1.0);
                REQUIRE(fb.get("a").at(x, y, c) == Approx(mean).epsilon(1e-6));
                REQUIRE(fb.get("a_variance").at(x, y, c) == Approx(var).epsilon(1e-5));
            }
            REQUIRE(fb.get("b").at(x, y) == Approx(sum[3] / n).epsilon(1e-6));
        }
}

namespace {
// Writes 1000 plus a small uniform number of its sampler: a mean far above
// the spread, where single-precision sums of squares lose the variance.
class OffsetEcho final : public OneSampleIntegrator {
public:
    std::string describe() const override { return ""; }
    static float value(Sampler& s) { return 1000.f + 0.01f * (s.next1d() - 0.5f); }

protected:
    std::vector<SlotSpec> slots() const override { return {{"v", 1, true}}; }
    void sample(const Scene&, int, int, Sampler& sampler, float* out, uint64_t& rays) const override {
        out[0] = value(sampler);
        ++rays;
    }
};
}  // namespace

TEST_CASE("tiled integrators: single-precision accumulators keep the variance of a large mean", "[pt][tiled]") {
    // 4096 samples of 1000 + U(-0.005, 0.005): the variance (8.3e-6) is
    // 1e-11 of the squared mean, the hardest case for single precision. A
    // running mean stops moving once a sample's share of the difference is
    // below half a float spacing (6.1e-5 at 1000), here after about 170
    // samples, so the mean is that of the first ones: measured at most 6.9
    // spacings (4e-7 relative) from the exact one, and the variance at most
    // 2.0% off. Float sums and squared sums (computed here as the
    // deliberately wrong variant) are off by orders of magnitude. Where the
    // spread is comparable to the mean, as in renders, the running mean
    // keeps moving for about 1e7 samples.
    auto scene = test::small_box("Original", 4);
    OffsetEcho integ;
    RenderSettings st;
    st.spp = 4096;
    st.seed = 9;
    FrameBuffer fb;
    static_cast<Integrator&>(integ).render(*scene, st, fb);
    double worst_var = 0.0, worst_naive = 0.0, worst_mean = 0.0;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
            double sum = 0.0;
            float fsum = 0.f, fsum2 = 0.f;
            std::vector<double> v;
            for (int i = 0; i < st.spp; ++i) {
                Sampler s(SampleKey{st.seed, uint32_t(x), uint32_t(y), uint32_t(i)});
                v.push_back(OffsetEcho::value(s));
                sum += v.back(), fsum += float(v.back()), fsum2 += float(v.back()) * float(v.back());
            }
            const double n = double(st.spp), mean = sum / n;
            double m2 = 0.0;
            for (double a : v) m2 += (a - mean) * (a - mean);
            const double var = m2 / (n - 1.0);
            worst_mean = std::max(worst_mean, std::abs(fb.get("v").at(x, y) - mean) / 6.1e-5);  // float spacings at 1000
            worst_var = std::max(worst_var, std::abs(fb.get("v_variance").at(x, y) - var) / var);
            const double naive = (double(fsum2) - double(fsum) * double(fsum) / n) / (n - 1.0);
            worst_naive = std::max(worst_naive, std::abs(naive - var) / var);
        }
    UNSCOPED_INFO("worst mean error " << worst_mean << " float spacings; worst relative variance error: running "
                                      << worst_var << ", float sums " << worst_naive);
    CHECK(worst_mean < 10.0);
    CHECK(worst_var < 0.05);
    CHECK(worst_naive > 1.0);
}

TEST_CASE("tiled integrators: time budgets and cancellation end on whole passes", "[pt][tiled]") {
    const SceneFile sf = load_scene_file(kScenes + "emitter-wall/scene.json");
    auto pt = integrator_registry().create("pt", Params());
    FrameBuffer fb;
    RenderSettings st;
    st.time_budget = 0.05;
    const RenderStats timed = pt->render(*sf.scene, st, fb, {});
    CHECK(timed.spp >= 1);
    CHECK(fb.metadata().at("spp") == std::to_string(timed.spp));
    CHECK(timed.samples == uint64_t(timed.spp) * 80);
    // Cancelled before any pass finished: there is no image to return.
    std::atomic<bool> cancel{true};
    RenderSettings sc;
    sc.spp = 100;
    sc.cancel = &cancel;
    CHECK_THROWS_AS(pt->render(*sf.scene, sc, fb, {}), Interrupted);
    // Cancelled once the first pass (one sample per pixel, to measure the
    // rate) is done: the render ends on it.
    cancel = false;
    const RenderStats cancelled = pt->render(*sf.scene, sc, fb, [&](const Progress& p) {
        if (p.samples >= 80) cancel = true;
    });
    CHECK(cancelled.spp == 1);
    CHECK(fb.metadata().at("spp") == "1");
    CHECK(fb.get("color").rgb(0, 0) == Color(3.f, 2.f, 0.5f));
    RenderSettings bad;
    bad.spp = 0;
    CHECK_THROWS_AS(pt->render(*sf.scene, bad, fb, {}), ParameterError);
}

TEST_CASE("tiled integrators: a second render of the same object while one runs is refused", "[pt][tiled][errors]") {
    const SceneFile sf = load_scene_file(kScenes + "emitter-wall/scene.json");
    auto pt = integrator_registry().create("pt", Params());
    FrameBuffer fb, inner_fb;
    RenderSettings st;
    st.spp = 2;
    std::atomic<int> refused{0}, other{0};
    // The progress callback runs inside render(): a render started from there
    // overlaps the first, as one from another thread would.
    const RenderStats rs = pt->render(*sf.scene, st, fb, [&](const Progress&) {
        try {
            pt->render(*sf.scene, st, inner_fb, {});
        } catch (const RuntimeFailure&) {
            ++refused;
        } catch (...) {
            ++other;
        }
    });
    CHECK(refused > 0);
    CHECK(other == 0);
    CHECK(rs.spp == 2);
    CHECK(fb.get("color").rgb(0, 0) == Color(3.f, 2.f, 0.5f));
    // Once it has returned, the object renders again.
    CHECK_NOTHROW(pt->render(*sf.scene, st, inner_fb, {}));
}

TEST_CASE("tiled integrators: a render larger than the machine's memory is refused with the figure", "[pt][tiled][errors]") {
    const double have = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    // 2^32 pixels need ~450 GB of accumulators for pt; a machine with more would start rendering.
    if (have > 400e9) {
        WARN("not checked: this machine has more memory than the largest camera needs");
        return;
    }
    const fs::path dir = fs::temp_directory_path() / ("gdr-test-memory-" + std::to_string(getpid()));
    fs::create_directories(dir);
    std::ofstream(dir / "huge.json") << R"({"camera": {"width": 65536, "height": 65536}, "meshes": [")"
                                     << kScenes << R"(bad/triangle.obj"]})";
    const SceneFile sf = load_scene_file((dir / "huge.json").string());
    auto pt = integrator_registry().create("pt", Params());
    FrameBuffer fb;
    RenderSettings st;
    st.spp = 1;
    std::string msg;
    try {
        pt->render(*sf.scene, st, fb, {});
    } catch (const RuntimeFailure& e) {
        msg = e.what();
    }
    CHECK_THAT(msg, Contains("65536x65536") && Contains("GB"));
    fs::remove_all(dir);
}

TEST_CASE("pt: parameters are validated", "[pt][errors]") {
    CHECK_THROWS_AS(integrator_registry().create("pt", [] { Params p; p.set("max_depth", 0LL); return p; }()), ParameterError);
    CHECK_THROWS_AS(integrator_registry().create("pt", [] { Params p; p.set("rr_depth", 0LL); return p; }()), ParameterError);
    CHECK_THROWS_WITH(integrator_registry().create("pt", [] { Params p; p.set("mx_depth", 3LL); return p; }()),
                      Catch::Contains("'mx_depth'"));
    // Values that would wrap around when narrowed to int (3e9 became a negative depth).
    for (const char* text : {"max_depth=3000000000", "rr_depth=4294967297", "rr_depth=99999999999999999999"})
        for (const char* integ : {"pt", "gpt"}) {
            Params p;
            p.set_from_text(text);
            INFO(integ << " " << text);
            CHECK_THROWS_AS(integrator_registry().create(integ, p), ParameterError);
        }
}

TEST_CASE("pt: images do not depend on how many camera rays share a packet", "[pt][determinism]") {
    // 24x24 leaves partial tiles; 1 spp makes packets span pixels, 5 spp
    // makes them cross from one pixel's samples into the next pixel's.
    const SceneFile sf = load_scene_file(kScenes + "cornell-small.json");
    for (long long spp : {1LL, 5LL}) {
        const FrameBuffer ref = render(*sf.scene, spp, 3, "batch=1");
        for (const char* batch : {"batch=3", "batch=8"}) {
            const FrameBuffer fb = render(*sf.scene, spp, 3, batch);
            for (const auto& name : ref.names()) {
                INFO("spp " << spp << ", " << batch << ", layer " << name);
                const auto &a = ref.get(name).values(), &b = fb.get(name).values();
                REQUIRE(a.size() == b.size());
                CHECK(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
            }
        }
    }
    for (const char* bad : {"batch=0", "batch=9"}) {
        Params p("test");
        p.set_from_text(bad);
        CHECK_THROWS_WITH(integrator_registry().create("pt", p), Catch::Contains("batch must be between 1 and 8"));
    }
}

TEST_CASE("pt: each pixel's color is the mean of trace_path() over its samples' streams", "[pt]") {
    // The packet of camera rays is plumbing only: the render must equal
    // trace_path() run sample by sample on the same numbers (up to the
    // packet kernel's last-bit rounding of a hit, hence the tolerance).
    const SceneFile sf = load_scene_file(kScenes + "cornell-small.json");
    const Scene& scene = *sf.scene;
    const long long spp = 6;
    const uint64_t seed = 11;
    const FrameBuffer fb = render(scene, spp, seed);
    const int W = scene.camera().width(), H = scene.camera().height();
    double worst = 0, total = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const uint64_t pixel = SampleKey{seed, uint32_t(x), uint32_t(y), 0}.pixel_stream();
            Color sum(0.f);
            for (long long i = 0; i < spp; ++i) {
                Sampler s(SampleKey::stream_of(pixel, uint32_t(i)));
                s.set_dimension(dims::kFilm);
                const Vec2 film = Vec2(float(x), float(y)) + s.next2d();
                sum += trace_path(scene, scene.camera().generate_ray(film), s, PathOptions{}).radiance;
            }
            const Color mean = sum / float(spp), got = fb.get("color").rgb(x, y);
            for (int c = 0; c < 3; ++c) {
                worst = std::max(worst, std::abs(double(got[c]) - mean[c]) / (std::abs(double(mean[c])) + 1e-3));
                total += mean[c];
            }
        }
    CHECK(total > 0.0);
    CHECK(worst < 1e-5);
}

TEST_CASE("trace_path: a camera ray into an emitter returns its radiance and first-hit data", "[pt]") {
    const SceneFile sf = load_scene_file(kScenes + "emitter-wall/scene.json");
    Sampler s(SampleKey{1, 0, 0, 0});
    const PathResult r = trace_path(*sf.scene, Ray{Vec3(0.f), Vec3(0, 0, -1)}, s, PathOptions{});
    CHECK(r.radiance == Color(3.f, 2.f, 0.5f));
    CHECK(r.depth == Approx(2.f));
    CHECK(r.normal.z == Approx(1.f));
    CHECK(r.albedo == Color(0.f));
    CHECK(r.rays == 1);  // a black BSDF ends the path; a light sample in the emitter's own plane casts no shadow ray
}

namespace {
// Declares its slots and nothing else: computes no sample.
class NoSamples : public TiledIntegrator {
public:
    std::string describe() const override { return ""; }

protected:
    std::vector<SlotSpec> slots() const override { return {{"v", 1, false}}; }
};
// sample_batch() is the one way render() gets samples, and it is pure: an
// integrator that computes none cannot be made (a compile-time error, where
// it once was a render-time one).
static_assert(std::is_abstract_v<NoSamples>);
}  // namespace
