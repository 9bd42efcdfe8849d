// Bidirectional path tracing and the path-space core under it: bdpt equals
// pt in expectation on the bundled scenes, every (s, t) strategy alone is
// unbiased for its path length, light tracing alone equals pt, the MIS
// weights of a path's strategies sum to one and the connection's densities
// are the full path's, emission sampling and the camera's importance are
// normalised, and splatted images stay bit-identical for any thread count.
//
// Statistical checks are block z-tests over independent runs
// (block_stats.h): standard errors come from the run-to-run spread, so the
// splatted light tracing, whose per-pixel variance is only estimated, is
// tested like any other estimate. Each check shows its power on a wrong variant.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <random>

#include "block_stats.h"
#include "joined_densities.h"
#include "chi2.h"
#include "cycles_compare.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/path/dims.h"
#include "gdr/io/scene_file.h"
#include "gdr/path/connection.h"
#include "gdr/scene/warp.h"
#include "public_scenes.h"

using namespace gdr;
using namespace gdr::test;

namespace {

// A bundled scene file at a test resolution.
SceneFile scene_at(const std::string& rel, int res) {
    SceneFile sf = load_scene_file(std::string(GDR_SOURCE_DIR) + "/" + rel);
    set_resolution(sf, res, res);
    return sf;
}

}  // namespace

TEST_CASE("bdpt equals pt in expectation on the bundled scenes", "[bdpt][statistical]") {
    // 24 x 24 pixels, 16 runs each side, in 6 x 6 blocks (16 per scene, but see below):
    // |z| < 4.5 (t with 30 degrees of freedom) over the 88 tests keeps the
    // family-wise false-alarm rate near 1%. veach-bidir is where path
    // tracing fails: the rare paths through its lamp's glass make pt's block
    // means heavy-tailed (two 16384-spp pt renders of it at 32 x 32 differ by
    // 1% in their mean, two 1024-spp bdpt renders by 0.2%), so there pt takes
    // 32 times bdpt's samples and the blocks are 12 x 12. The glass sphere's
    // caustics on the walls do the same in a milder form: with 512 spp and
    // 6 x 6 blocks pt's corner block was 7% low at z 4.2, and agreed with
    // bdpt to 0.1% at 65536 spp; here pt takes 512 spp in 12 x 12 blocks.
    const int res = 24, runs = 16;
    struct Case {
        std::string name;
        std::unique_ptr<Scene> owned;
        SceneFile file;
        long long pt_spp, bdpt_spp;
        int block;
        const Scene& scene() const { return owned ? *owned : *file.scene; }
    };
    std::vector<Case> cases;
    for (const char* v : {"Original", "Mirror", "Glossy"}) cases.push_back({std::string("box ") + v, small_box(v, res), {}, 64, 16, 6});
    cases.push_back({"box Sphere", small_box("Sphere", res), {}, 512, 96, 12});
    cases.push_back({"veach-mis", nullptr, scene_at("scenes/veach-mis/scene.json", res), 64, 16, 6});
    cases.push_back({"veach-bidir", nullptr, scene_at("scenes/veach-bidir/scene.json", res), 512, 16, 12});
    if (!public_scene("bathroom-contemporary/bathroom.obj").empty())
        cases.push_back({"bathroom", nullptr, scene_at("scenes/bathroom/scene.json", res), 64, 16, 6});
    else
        WARN(public_scene_missing("bathroom-contemporary", false));
    for (const Case& c : cases) {
        INFO(c.name);
        const BlockStats pt = grey_stats(render_runs(c.scene(), "pt", Params(), c.pt_spp, runs, 100), "color", c.block);
        const BlockStats b = grey_stats(render_runs(c.scene(), "bdpt", Params(), c.bdpt_spp, runs, 200), "color", c.block);
        const double z = max_z(b, pt), z_dark = max_z(scaled(b, 0.95), pt);
        CAPTURE(z, z_dark);
        CHECK(z < 4.5);
        // Power: an image 5% too dark is rejected.
        CHECK(z_dark > 4.5);
    }
}

TEST_CASE("bdpt: the images without light tracing's (2,1) strategy are rejected", "[bdpt][statistical]") {
    // The power of the comparison against pt for a mistake in one strategy:
    // the McGuire box with the weighted (2,1) contributions (light tracing of
    // two-segment paths, about a tenth of the image) taken out.
    const int res = 24, block = 6, runs = 16;
    const auto scene = small_box("Original", res);
    const BlockStats pt = grey_stats(render_runs(*scene, "pt", Params(), 64, runs, 100), "color", block);
    std::vector<FrameBuffer> bd = render_runs(*scene, "bdpt", params({{"strategy_layers", "true"}}), 16, runs, 300);
    CHECK(max_z(grey_stats(bd, "color", block), pt) < 4.5);
    for (FrameBuffer& fb : bd) {
        Image& c = fb.get("color");
        const Image& lt = fb.get("strategy_s2_t1");
        for (size_t i = 0; i < c.values().size(); ++i) c.values()[i] -= lt.values()[i];
    }
    CHECK(max_z(grey_stats(bd, "color", block), pt) > 4.5);
}

TEST_CASE("bdpt: hide_emitters estimates gpt's primal, which leaves the emitters seen directly out", "[bdpt][statistical]") {
    // The McGuire box sees its ceiling lamp. gpt keeps directly visible
    // emission in its `direct` layer, out of the primal; bdpt with
    // hide_emitters leaves out paths of one segment. Same blocks, runs and
    // bound as the test against pt above; measured largest |z| 1.8, and 49
    // for the wrong variant below.
    const int res = 24, block = 6, runs = 16;
    const auto scene = small_box("Original", res);
    const BlockStats primal = grey_stats(render_runs(*scene, "gpt", params({{"reconstruct", "none"}}), 16, runs, 100), "primal", block);
    const BlockStats hidden = grey_stats(render_runs(*scene, "bdpt", params({{"hide_emitters", "true"}}), 16, runs, 200), "color", block);
    CHECK(max_z(hidden, primal) < 4.5);
    // The wrong variant: bdpt's full image holds the lamp.
    const BlockStats full = grey_stats(render_runs(*scene, "bdpt", Params(), 16, runs, 200), "color", block);
    CHECK(max_z(full, primal) > 4.5);
}

TEST_CASE("bdpt: each (s, t) strategy alone is unbiased for its path length", "[bdpt][statistical]") {
    // The reference for paths of exactly k segments is pt(max_depth k) minus
    // pt(max_depth k - 1) with the same seed (the two share every path up to
    // k - 1 segments). 7 strategies x 16 blocks: |z| < 4.5.
    const int res = 24, block = 6, runs = 16;
    const auto scene = small_box("Original", res);
    const auto exact_length = [&](int k) {
        std::vector<FrameBuffer> a = render_runs(*scene, "pt", params({{"max_depth", std::to_string(k).c_str()}}), 64, runs, 400);
        const std::vector<FrameBuffer> b =
            render_runs(*scene, "pt", params({{"max_depth", std::to_string(k - 1).c_str()}}), 64, runs, 400);
        for (int r = 0; r < runs; ++r) {
            Image& c = a[r].get("color");
            for (size_t i = 0; i < c.values().size(); ++i) c.values()[i] -= b[r].get("color").values()[i];
        }
        return grey_stats(a, "color", block);
    };
    const BlockStats ref2 = exact_length(2), ref3 = exact_length(3);
    for (int k = 2; k <= 3; ++k)
        for (int t = 1; t <= k + 1; ++t) {
            const int s = k + 1 - t;
            const std::string st = std::to_string(s) + "," + std::to_string(t);
            INFO("strategy (" << st << ")");
            // Light tracing and NEE converge faster than the camera walk that must hit the small light.
            const long long spp = s == 0 ? 128 : 16;
            const BlockStats b = grey_stats(render_runs(*scene, "bdpt", params({{"strategy", st.c_str()}}), spp, runs, 500), "color", block);
            CHECK(max_z(b, k == 2 ? ref2 : ref3) < 4.5);
            // Power: the other path length is rejected.
            CHECK(max_z(b, k == 2 ? ref3 : ref2) > 4.5);
        }
}

TEST_CASE("bdpt: light tracing alone equals pt on a diffuse box", "[bdpt][statistical]") {
    // strategy=light: every path of two or more segments by light tracing
    // (t = 1, splatted), emitters the camera sees directly by s = 0.
    const int res = 24, block = 6, runs = 16;
    const auto scene = small_box("Original", res);
    const BlockStats pt = grey_stats(render_runs(*scene, "pt", Params(), 64, runs, 100), "color", block);
    const BlockStats lt = grey_stats(render_runs(*scene, "bdpt", params({{"strategy", "light"}}), 16, runs, 600), "color", block);
    CHECK(max_z(lt, pt) < 4.5);
    // Power: light tracing cut at three segments is rejected.
    const BlockStats lt3 =
        grey_stats(render_runs(*scene, "bdpt", params({{"strategy", "light"}, {"max_depth", "3"}}), 16, runs, 600), "color", block);
    CHECK(max_z(lt3, pt) > 4.5);
}

TEST_CASE("mis: the weights of a path's strategies sum to one", "[bdpt][mis]") {
    // Random full paths of 2 to 9 vertices: densities log-uniform over six
    // decades, a fifth of the vertices delta (their densities 0, as the walk
    // records them). Over the possible strategies the weights sum to 1 to
    // rounding, for both heuristics, and each lies in [0, 1].
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> logp(-3.0, 3.0), u(0.0, 1.0);
    int paths = 0, with_delta = 0;
    double worst = 0.0, worst_without_lt = 0.0;
    for (int n = 2; n <= 9; ++n)
        for (int i = 0; i < 300; ++i) {
            PathDensities d;
            d.resize(n);
            for (int k = 1; k < n; ++k) d.fwd[k] = std::pow(10.0, logp(rng)), d.rev[k] = std::pow(10.0, logp(rng));
            d.rev[0] = std::pow(10.0, logp(rng));
            for (int k = 1; k < n - 1; ++k)
                if (u(rng) < 0.2) {
                    d.delta[k] = 1;
                    if (k + 1 < n) d.fwd[k + 1] = 0.0;
                    d.rev[k - 1] = 0.0;
                }
            bool any = false;
            for (int t = 1; t <= n; ++t) any |= strategy_possible(d, t);
            if (!any) continue;
            ++paths;
            for (int k = 0; k < n; ++k) with_delta += d.delta[k] ? 1 : 0;
            for (MisHeuristic h : {MisHeuristic::Power, MisHeuristic::Balance}) {
                double sum = 0.0, sum_without_lt = 0.0;
                for (int t = 1; t <= n; ++t) {
                    if (!strategy_possible(d, t)) continue;
                    const double w = strategy_weight({h, -1}, d, t);
                    REQUIRE(w >= 0.0);
                    REQUIRE(w <= 1.0 + 1e-12);
                    sum += w;
                    if (t >= 2) sum_without_lt += w;
                }
                worst = std::max(worst, std::abs(sum - 1.0));
                if (strategy_possible(d, 1)) worst_without_lt = std::max(worst_without_lt, std::abs(sum_without_lt - 1.0));
            }
        }
    CAPTURE(paths, with_delta);
    CHECK(paths > 2000);
    CHECK(with_delta > 500);
    CHECK(worst < 1e-12);
    // Power: a renderer that forgot the light-tracing strategy would weigh
    // its other strategies to a sum well below one.
    CHECK(worst_without_lt > 0.1);
}

TEST_CASE("connections: the densities of a joined path are the full path's, vertex by vertex", "[bdpt][mis]") {
    // For traced subpaths on the glossy and glass boxes, every (s, t)
    // connection with s != 1 that contributes: the densities
    // connection_densities() assembles from the subpaths' pdf_fwd / pdf_rev
    // and four recomputed values equal the densities computed from scratch
    // along the joined path's vertices, and their weights sum to one
    // (tests/joined_densities.h).
    test::DensityTally tally;
    for (const char* variant : {"Glossy", "Sphere"}) {
        const auto scene = small_box(variant, 16);
        Subpath camera, light;
        for (uint32_t i = 0; i < 400; ++i) {
            const Sampler sampler(SampleKey{3, i % 16, (i / 16) % 16, i});
            const Vec2 film = Vec2(float(i % 16), float((i / 16) % 16)) + sampler.at2(dims::kFilm);
            trace_camera_subpath(*scene, film, sampler, {8, 5}, camera);
            trace_light_subpath(*scene, sampler, {7, 5}, light);
            for (int t = 1; t <= camera.size(); ++t)
                for (int s = 0; s <= light.size(); ++s) {
                    if (s == 1 || s + t < 2 || s + t > 9 || (s == 0 && t == 1)) continue;
                    INFO(variant << " sample " << i);
                    test::check_joined_densities(*scene, light, camera, {s, t}, sampler, tally);
                }
        }
    }
    CAPTURE(tally.worst, tally.compared, tally.loose);
    CHECK(tally.checked > 1000);
    CHECK(tally.loose < tally.compared / 20);
    CHECK(tally.worst < 0.05);
}

TEST_CASE("emission sampling: points by power and area, cosine directions, densities recorded", "[bdpt][statistical]") {
    // A closed grey cube with a square emitter under its ceiling, facing
    // down: every emitted ray hits. The emitted directions follow cos / pi
    // about the light's normal (chi-square); the
    // subpath records the densities it sampled with.
    TriangleMesh m;
    auto quad = [&](Vec3 a, Vec3 b, Vec3 c, Vec3 d, uint32_t mat) {  // counter-clockwise seen from the front
        m.positions.insert(m.positions.end(), {a, b, c, a, c, d});
        m.material_ids.insert(m.material_ids.end(), {mat, mat});
    };
    quad({-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1}, 0);  // floor, facing up
    quad({-1, 1, -1}, {-1, 1, 1}, {1, 1, 1}, {1, 1, -1}, 0);      // ceiling, facing down
    quad({-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}, 0);  // left wall, facing +x
    quad({1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1}, 0);      // right wall, facing -x
    quad({-1, -1, -1}, {-1, 1, -1}, {1, 1, -1}, {1, -1, -1}, 0);  // back wall, facing +z
    quad({-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}, 0);      // front wall, facing -z
    quad({-0.3f, 0.9f, -0.3f}, {0.3f, 0.9f, -0.3f}, {0.3f, 0.9f, 0.3f}, {-0.3f, 0.9f, 0.3f}, 1);  // the light, facing down
    auto grey = make_lambertian(make_constant_texture(Color(0.5f)));
    std::vector<Material> mats = {{"grey", grey, Color(0.f)}, {"light", grey, Color(4.f)}};
    const auto scene = std::make_unique<Scene>(std::move(m), std::move(mats), Camera(), "closed cube");
    const Vec3 n = Vec3(0.f, -1.f, 0.f);
    Subpath light;
    auto sample = [&](Sampler& s) -> std::optional<Vec3> {
        trace_light_subpath(*scene, s, {1, 5}, light);
        if (light.size() < 2) return std::nullopt;
        return -light.v[1].wo;  // the emitted ray's direction
    };
    auto pdf = [&](const Vec3& w) { return std::max(0.0, double(glm::dot(n, w))) / M_PI; };
    test::SphericalChi2Options opt;
    opt.samples = 200000;
    const test::Chi2Result r = test::spherical_chi2(sample, pdf, opt);
    INFO(r.message);
    CHECK(r.passed);
    // Power: a uniform-hemisphere claim is rejected.
    const test::Chi2Result wrong = test::spherical_chi2(sample, [&](const Vec3& w) { return glm::dot(n, w) > 0.f ? 0.5 / M_PI : 0.0; }, opt);
    CHECK_FALSE(wrong.passed);
    for (uint32_t i = 0; i < 200; ++i) {
        const Sampler s(SampleKey{9, 0, 0, i});
        trace_light_subpath(*scene, s, {1, 5}, light);
        REQUIRE(light.size() == 2);
        const Vertex &l = light.v[0], &x = light.v[1];
        // The origin is the point sample_light() picks with the same numbers, at its density.
        const LightSample ls = scene->sample_light(l.si.p + l.si.ng, s.at(dims::light_origin() + dims::kEmitSelect),
                                                   s.at2(dims::light_origin() + dims::kEmitPoint));
        CHECK(glm::length(ls.p - l.si.p) < 1e-6f);
        CHECK(l.pdf_fwd == Approx(scene->light_pdf_a(l.si.prim)));
        CHECK(l.beta.r == Approx(ls.radiance.r / ls.pdf_a));
        // Recomputed from the hit point rather than the sampled direction: the
        // ray's origin offset moves grazing densities by up to about 1e-3.
        CHECK(x.pdf_fwd == Approx(pdf_light_direction(l, x)).epsilon(1e-2));
        CHECK(x.beta.r == Approx(l.beta.r * M_PI).epsilon(1e-5));
    }
}

TEST_CASE("camera: importance integrates to one over the film, and primary rays follow its direction density", "[bdpt][statistical]") {
    CameraDesc cd;
    cd.position = {0.f, 1.f, 3.5f};
    cd.target = {0.3f, 0.8f, 0.f};
    cd.fov_deg = 50.f;
    cd.width = 40, cd.height = 30;
    const Camera cam(cd);
    // Monte Carlo over the sphere: integral of We cos theta and of the direction density.
    double we_integral = 0.0, pdf_integral = 0.0, wrong_integral = 0.0;
    const int n = 1 << 21;
    for (int i = 0; i < n; ++i) {
        const Sampler s(SampleKey{1, 0, 0, uint32_t(i)});
        const Vec3 w = warp::square_to_uniform_sphere(s.at2(0));
        Vec2 film;
        const float we = cam.importance(w, film);
        const float c = glm::dot(w, cam.forward());
        we_integral += we * c * 4.0 * M_PI / n;
        pdf_integral += cam.direction_pdf(w) * 4.0 * M_PI / n;
        wrong_integral += we * 4.0 * M_PI / n;  // without the cosine
        if (we > 0.f) {
            // The raster point is the one the direction passes through.
            const Ray r = cam.generate_ray(film);
            REQUIRE(glm::dot(r.d, w) > 0.99999f);
        }
    }
    CHECK(we_integral == Approx(1.0).epsilon(0.01));
    CHECK(pdf_integral == Approx(1.0).epsilon(0.01));
    CHECK(std::abs(wrong_integral - 1.0) > 0.05);
    // Primary rays through uniform film points have the claimed direction density.
    auto sample = [&](Sampler& s) -> std::optional<Vec3> {
        const Vec2 u = s.next2d();
        return cam.generate_ray(Vec2(u.x * float(cd.width), u.y * float(cd.height))).d;
    };
    test::SphericalChi2Options opt;
    opt.samples = 200000;
    const test::Chi2Result r = test::spherical_chi2(sample, [&](const Vec3& w) { return double(cam.direction_pdf(w)); }, opt);
    INFO(r.message);
    CHECK(r.passed);
}

TEST_CASE("bdpt: images are bit-identical for 1 and 2 threads and any batch size, splats included", "[bdpt][determinism]") {
    const auto scene = small_box("Sphere", 16);
    const auto run = [&](int threads, const char* batch, uint64_t seed = 5) {
        auto integ = integrator_registry().create("bdpt", params({{"batch", batch}, {"strategy_layers", "true"}}));
        RenderSettings st;
        st.spp = 6;
        st.seed = seed;
        st.threads = threads;
        FrameBuffer fb;
        integ->render(*scene, st, fb);
        return fb;
    };
    const FrameBuffer a = run(1, "16"), b = run(2, "16"), c = run(2, "1"), d = run(2, "16", 6);
    REQUIRE(a.names() == b.names());
    for (const auto& name : a.names()) {
        INFO(name);
        const auto &va = a.get(name).values(), &vb = b.get(name).values(), &vc = c.get(name).values();
        CHECK(std::memcmp(va.data(), vb.data(), va.size() * sizeof(float)) == 0);
        CHECK(std::memcmp(va.data(), vc.data(), va.size() * sizeof(float)) == 0);
    }
    CHECK(std::memcmp(a.get("color").data(), d.get("color").data(), a.get("color").values().size() * sizeof(float)) != 0);
}

TEST_CASE("bdpt: strategy layers add up to the image of short paths, parameters are validated", "[bdpt]") {
    const auto scene = small_box("Glossy", 12);
    const FrameBuffer fb = render(*scene, "bdpt", params({{"max_depth", "4"}, {"strategy_layers", "true"}}), 8, 3);
    for (const char* layer : {"color", "albedo", "normal", "depth", "variance", "spp", "strategy_s0_t2", "strategy_s2_t1",
                              "strategy_s1_t4", "strategy_s4_t1"})
        CHECK(fb.has(layer));
    CHECK_FALSE(fb.has("strategy_s1_t1"));
    const Image& c = fb.get("color");
    double worst = 0.0;
    for (int y = 0; y < fb.height(); ++y)
        for (int x = 0; x < fb.width(); ++x)
            for (int ch = 0; ch < 3; ++ch) {
                double sum = 0.0;
                for (const auto& name : fb.names())
                    if (name.rfind("strategy_", 0) == 0) sum += fb.get(name).at(x, y, ch);
                worst = std::max(worst, std::abs(sum - c.at(x, y, ch)) / std::max(1e-3, double(c.at(x, y, ch))));
            }
    CHECK(worst < 1e-4);
    auto& reg = integrator_registry();
    for (const char* bad : {"strategy=1,1", "strategy=0,1", "strategy=two", "strategy=2,", "mis=cheap", "max_depth=0"}) {
        INFO(bad);
        Params p("test");
        p.set_from_text(bad);
        CHECK_THROWS_AS(reg.create("bdpt", p), ParameterError);
    }
}

TEST_CASE("bdpt: Cornell boxes agree with Blender Cycles", "[bdpt][statistical][reference]") {
    // As pt's test of the same name (test_pt.cpp, cycles_compare.h), with
    // block variances from the per-pixel variance layer, which for bdpt
    // includes the splats' estimated share (Accumulated::splat_variance).
    // Every block and channel is tested at a family-wise level of 1e-3, and
    // so is the image mean; the power check rejects an image 0.5% off.
    struct Case {
        const char* scene;
        const char* reference;
        long long spp;
    };
    const Case c = GENERATE(Case{"scenes/cornell-box/scene.json", "cycles-cornell-box.json", 8},
                            Case{"tests/scenes/cornell-cc0-256.json", "cycles-cornell-cc0-256.json", 32});
    INFO(c.scene);
    const CyclesReference ref(c.reference);
    const SceneFile sf = load_scene_file(std::string(GDR_SOURCE_DIR "/") + c.scene);
    REQUIRE(sf.scene->camera().width() == ref.width);
    const FrameBuffer fb = render(*sf.scene, "bdpt", Params(), c.spp, 7);
    const CyclesWorst as_rendered = compare_with_cycles(fb, ref, 1.0);
    CAPTURE(as_rendered.block, as_rendered.image);
    CHECK(as_rendered.block < z_threshold(ref.blocks * 3));
    CHECK(as_rendered.image < z_threshold(3));
    CHECK(compare_with_cycles(fb, ref, 1.005).image > z_threshold(3));
    CHECK(compare_with_cycles(fb, ref, 0.995).image > z_threshold(3));
}

TEST_CASE("bdpt: a render's splats start from zero, also in buffers kept from the last render", "[bdpt][tiled][determinism]") {
    // The splat sums are reused from one render to the next (as the slot
    // sums are) and must be cleared: a second render by the same object
    // equals a first render by a fresh one, bit for bit.
    const auto scene = small_box("Original", 16);
    auto integ = integrator_registry().create("bdpt", Params());
    RenderSettings st;
    st.spp = 4;
    st.seed = 11;
    FrameBuffer first, second, fresh;
    integ->render(*scene, st, first);
    integ->render(*scene, st, second);
    integrator_registry().create("bdpt", Params())->render(*scene, st, fresh);
    for (const FrameBuffer* fb : {&second, &fresh}) {
        const auto &a = first.get("color").values(), &b = fb->get("color").values();
        CHECK(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
    }
}

TEST_CASE("connections: a path tracer's two-strategy weight is the general weight restricted to s <= 1", "[bdpt][mis]") {
    // connect() computes the weights of StrategySet max_s 1 from the last
    // vertex's two densities; they must equal strategy_weight() over the
    // whole path's densities with the set restricted, for s = 0 and s = 1
    // (whose light point is sampled again here from the same numbers).
    const auto scene = small_box("Glossy", 16);
    Subpath camera;
    const Subpath no_light;
    int checked = 0;
    for (uint32_t i = 0; i < 300; ++i) {
        const Sampler sampler(SampleKey{5, i % 16, (i / 16) % 16, i});
        trace_camera_subpath(*scene, Vec2(float(i % 16) + 0.5f, float((i / 16) % 16) + 0.5f), sampler, {8, 5}, camera);
        for (int t = 2; t <= camera.size(); ++t)
            for (int s = 0; s <= 1; ++s) {
                if (s + t < 3) continue;
                for (MisHeuristic h : {MisHeuristic::Power, MisHeuristic::Balance}) {
                    uint64_t rays = 0;
                    const ConnectionResult c = connect(*scene, no_light, camera, {s, t}, sampler, {h, 1}, true, rays);
                    if (is_black(c.value)) continue;
                    Vertex light;
                    if (s == 1) {
                        const uint32_t b = dims::vertex(t - 1);
                        const LightSample ls = scene->sample_emitter_point(sampler.at(b + dims::kLightSelect),
                                                                           sampler.at2(b + dims::kLightPoint));
                        light.type = VertexType::Light;
                        light.si.p = ls.p, light.si.ng = ls.n, light.si.prim = ls.prim, light.pdf_fwd = ls.pdf_a;
                    }
                    PathDensities d;
                    connection_densities(*scene, no_light, camera, {s, t}, s == 1 ? &light : nullptr, d);
                    INFO("sample " << i << " (s, t) = (" << s << ", " << t << ")");
                    CHECK(c.weight == Approx(strategy_weight({h, 1}, d, t)).epsilon(1e-4));
                    ++checked;
                }
            }
    }
    CHECK(checked > 500);
}
