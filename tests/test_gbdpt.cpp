// Gradient-domain bidirectional path tracing: an unbiased primal and
// unbiased gradients against bidirectional path tracing, strategy by
// strategy and with glossy connections dropped, for every built-in shift.
#include <catch2/catch.hpp>

#include <cstring>

#include "bad_shifts.h"
#include "block_stats.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"
#include "gdr/shift/shift.h"
#include "gdr/shift/steps.h"
#include "gdr/shift/validate.h"

using namespace gdr;
using namespace gdr::test;

namespace {

const char* const kShifts[] = {"half-vector", "reconnection", "replay", "replay-reconnect"};

SceneFile scene_at(const std::string& rel, int res) {
    SceneFile sf = load_scene_file(std::string(GDR_SOURCE_DIR) + "/" + rel);
    set_resolution(sf, res, res);
    return sf;
}

// Block statistics of the image differences I(x+1) - I(x) (along x) or
// I(y+1) - I(y) of layer `layer` of each render.
BlockStats difference_stats(const std::vector<FrameBuffer>& fbs, const std::string& layer, bool along_x, int block) {
    const int w = fbs.at(0).width(), h = fbs.at(0).height();
    return block_stats(int(fbs.size()), w, h, block, [&](int r, auto&& add) {
        const Image& c = fbs[r].get(layer);
        for (int y = 0; y < h - !along_x; ++y)
            for (int x = 0; x < w - along_x; ++x) add(x, y, grey(c, x + along_x, y + !along_x) - grey(c, x, y));
    });
}

// Block statistics of a gradient layer of each render, with the direct
// layer's own differences added back (gradients leave directly visible
// emitters out; they are added after reconstruction).
BlockStats gradient_stats(const std::vector<FrameBuffer>& fbs, const char* layer, bool along_x, int block) {
    const int w = fbs.at(0).width(), h = fbs.at(0).height();
    return block_stats(int(fbs.size()), w, h, block, [&](int r, auto&& add) {
        const Image& d = fbs[r].get(layer);
        const Image& e = fbs[r].get("direct");
        for (int y = 0; y < h - !along_x; ++y)
            for (int x = 0; x < w - along_x; ++x)
                add(x, y, grey(d, x, y) + grey(e, x + along_x, y + !along_x) - grey(e, x, y));
    });
}

}  // namespace

TEST_CASE("gbdpt gradients are unbiased: E[dx], E[dy] equal differences of the bdpt image", "[gbdpt][statistical]") {
    // 24 x 24 pixels in 6 x 6 blocks, 16 runs a side: |z| < 5 over the
    // 2 x 16 tests of each of 16 scene and shift cases keeps the family-wise
    // false-alarm rate near 1% (t with 30 degrees of freedom).
    // The glass sphere's caustics make block means heavy-tailed (see the bdpt
    // tests): there the blocks are 12 x 12 and the reference takes more samples.
    const int res = 24, runs = 16;
    for (const std::string variant : {"Original", "Glossy", "Sphere"}) {
        const auto scene = small_box(variant, res);
        const int block = variant == "Sphere" ? 12 : 6;
        const std::vector<FrameBuffer> ref = render_runs(*scene, "bdpt", Params(), variant == "Sphere" ? 256 : 64, runs, 1000);
        const BlockStats ref_dx = difference_stats(ref, "color", true, block);
        const BlockStats ref_dy = difference_stats(ref, "color", false, block);
        for (const char* shift : kShifts) {
            const std::vector<FrameBuffer> g = render_runs(*scene, "gbdpt", params({{"shift", shift}}), 16, runs, 1);
            const BlockStats dx = gradient_stats(g, "dx", true, block), dy = gradient_stats(g, "dy", false, block);
            const double zx = max_z(dx, ref_dx), zy = max_z(dy, ref_dy);
            INFO(variant << " " << shift);
            CAPTURE(zx, zy);
            CHECK(zx < 5.0);
            CHECK(zy < 5.0);
            // Power: gradients that miss a fifth of their value are rejected.
            CHECK(max_z(scaled(dx, 0.8), ref_dx) > 5.0);
        }
    }
}

TEST_CASE("gbdpt on veach-bidir: unbiased primal and gradients for every built-in shift", "[gbdpt][statistical]") {
    // The lamp's glass makes block means heavy-tailed (see the bdpt tests):
    // 12 x 12 blocks, a 128-spp bdpt reference; 4 blocks a layer, |z| < 4.5.
    const int res = 24, block = 12, runs = 16;
    const SceneFile sf = scene_at("scenes/veach-bidir/scene.json", res);
    const std::vector<FrameBuffer> ref = render_runs(*sf.scene, "bdpt", Params(), 128, runs, 1000);
    const BlockStats ref_c = grey_stats(ref, "color", block);
    const BlockStats ref_dx = difference_stats(ref, "color", true, block);
    const BlockStats ref_dy = difference_stats(ref, "color", false, block);
    for (const char* shift : kShifts) {
        const std::vector<FrameBuffer> g = render_runs(*sf.scene, "gbdpt", params({{"shift", shift}}), 16, runs, 1);
        const BlockStats c = grey_stats(g, "color", block);
        const double z = max_z(c, ref_c), zx = max_z(gradient_stats(g, "dx", true, block), ref_dx),
                     zy = max_z(gradient_stats(g, "dy", false, block), ref_dy);
        INFO(shift);
        CAPTURE(z, zx, zy);
        CHECK(z < 4.5);
        CHECK(zx < 4.5);
        CHECK(zy < 4.5);
        CHECK(max_z(scaled(c, 0.9), ref_c) > 4.5);  // power: 10% too dark is rejected
    }
}

TEST_CASE("gbdpt primal equals bdpt in expectation", "[gbdpt][statistical]") {
    const int res = 24, runs = 16;  // 16 blocks a case: |z| < 4.5
    for (const std::string variant : {"Original", "Glossy", "Sphere"}) {
        const auto scene = small_box(variant, res);
        const int block = variant == "Sphere" ? 12 : 6;  // heavy tails, as above
        const BlockStats ref =
            grey_stats(render_runs(*scene, "bdpt", Params(), variant == "Sphere" ? 256 : 64, runs, 500), "color", block);
        const BlockStats g = grey_stats(render_runs(*scene, "gbdpt", Params(), 16, runs, 1), "color", block);
        // Power: an image 5% too dark is rejected (10% in the heavy-tailed case).
        const double z = max_z(g, ref), z_dark = max_z(scaled(g, variant == "Sphere" ? 0.9 : 0.95), ref);
        INFO(variant);
        CAPTURE(z, z_dark);
        CHECK(z < 4.5);
        CHECK(z_dark > 4.5);
    }
}

TEST_CASE("gbdpt: each (s, t) strategy's gradients alone are unbiased on a diffuse box", "[gbdpt][statistical]") {
    // strategy=s,t keeps one strategy, its base and offset weighed against
    // each other only: its dx, dy estimate the differences of that strategy's
    // own bdpt image. 7 strategies x 2 x 16 blocks: |z| < 5.
    const int res = 24, block = 6, runs = 16;
    const auto scene = small_box("Original", res);
    for (const char* st : {"0,3", "1,2", "2,1", "0,4", "1,3", "2,2", "3,1"}) {
        const bool camera_walk = st[0] == '0';  // must hit the small light: noisier
        const std::vector<FrameBuffer> ref =
            render_runs(*scene, "bdpt", params({{"strategy", st}}), camera_walk ? 512 : 64, runs, 300);
        const std::vector<FrameBuffer> g =
            render_runs(*scene, "gbdpt", params({{"strategy", st}}), camera_walk ? 128 : 16, runs, 1);
        const BlockStats ref_dx = difference_stats(ref, "color", true, block);
        const BlockStats ref_dy = difference_stats(ref, "color", false, block);
        const BlockStats dx = gradient_stats(g, "dx", true, block), dy = gradient_stats(g, "dy", false, block);
        const double zx = max_z(dx, ref_dx), zy = max_z(dy, ref_dy);
        INFO("strategy (" << st << ")");
        CAPTURE(zx, zy);
        CHECK(zx < 5.0);
        CHECK(zy < 5.0);
        CHECK(max_z(scaled(dx, camera_walk ? 0.5 : 0.7), ref_dx) > 5.0);  // power
        // And the primal is that strategy's image.
        CHECK(max_z(grey_stats(g, "primal", block), grey_stats(ref, "color", block)) < 5.0);
    }
}

TEST_CASE("gbdpt: dropping glossy connections leaves the primal and gradients unbiased", "[gbdpt][statistical]") {
    // The glossy box's floor and spheres have roughness below 0.5: with
    // drop=0.5 no strategy connects there, and s = 0 carries those paths.
    const int res = 24, block = 6, runs = 16;
    const auto scene = small_box("Glossy", res);
    const std::vector<FrameBuffer> ref = render_runs(*scene, "bdpt", Params(), 64, runs, 700);
    const std::vector<FrameBuffer> g = render_runs(*scene, "gbdpt", params({{"drop", "0.5"}}), 16, runs, 1);
    const BlockStats p = grey_stats(g, "color", block), pref = grey_stats(ref, "color", block);
    const double z = max_z(p, pref), zx = max_z(gradient_stats(g, "dx", true, block), difference_stats(ref, "color", true, block));
    CAPTURE(z, zx);
    CHECK(z < 4.5);
    CHECK(zx < 5.0);
    CHECK(max_z(scaled(p, 0.95), pref) > 4.5);
    // The drop changes the estimator: the images differ from the default's.
    const FrameBuffer a = render(*scene, "gbdpt", Params(), 2, 3), b = render(*scene, "gbdpt", params({{"drop", "0.5"}}), 2, 3);
    CHECK(std::memcmp(a.get("primal").data(), b.get("primal").data(), a.get("primal").values().size() * sizeof(float)) != 0);
}

TEST_CASE("gbdpt: images are bit-identical for 1 and 2 threads and any batch size", "[gbdpt][determinism]") {
    const auto scene = small_box("Sphere", 16);
    const auto run = [&](int threads, const char* batch, uint64_t seed = 5) {
        auto integ = integrator_registry().create("gbdpt", params({{"batch", batch}}));
        RenderSettings st;
        st.spp = 4;
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
    CHECK(std::memcmp(a.get("dx").data(), d.get("dx").data(), a.get("dx").values().size() * sizeof(float)) != 0);
}

TEST_CASE("gbdpt writes gpt's layers and rejects bad parameters", "[gbdpt]") {
    const auto scene = small_box("Original", 8);
    const FrameBuffer fb = render(*scene, "gbdpt", Params(), 1, 1);
    for (const char* l : {"color", "primal", "dx", "dy", "direct", "primal_variance", "dx_variance", "dy_variance",
                          "reconstruction_weighted", "reconstruction_l1", "reconstruction_l2", "albedo", "normal",
                          "depth", "spp"})
        CHECK(fb.has(l));
    CHECK_THROWS_AS(integrator_registry().create("gbdpt", params({{"drop", "0.0001"}})), ParameterError);
    CHECK_THROWS_AS(integrator_registry().create("gbdpt", params({{"strategy", "1,1"}})), ParameterError);
    CHECK_THROWS_AS(integrator_registry().create("gbdpt", params({{"shift", "nope"}})), ParameterError);
    CHECK_THROWS_AS(integrator_registry().create("gbdpt", params({{"alpha", "0"}})), ParameterError);
}

namespace {
// The built-in reconnection shift, registered from outside the library under another name.
struct OutsideReconnection {
    static constexpr std::string_view kName = "outside-reconnection";
    ShiftStep step(const ShiftStepInput& in) const {
        if (in.k == 1 && shift::can_reconnect(in)) return shift::reconnect(in);
        return ShiftStep{};
    }
};
}  // namespace

TEST_CASE("the bidirectional validator passes every built-in shift and catches a wrong Jacobian", "[gbdpt][shift]") {
    for (const char* rel : {"scenes/cornell-box/scene.json", "scenes/cornell-box/sphere.json", "scenes/veach-bidir/scene.json"}) {
        const SceneFile sf = load_scene_file(std::string(GDR_SOURCE_DIR) + "/" + rel);
        ValidateOptions opt;
        opt.paths = 1500;
        for (const char* name : kShifts) {
            const auto shift = shift_registry().create(name, Params());
            const ShiftReport rep = validate_bidirectional_shift(*sf.scene, *shift, ShiftConfig{}, opt);
            INFO(rel << "\n" << rep.summary());
            CHECK(rep.passed);
            CHECK(rep.base_paths > 300);
            CHECK(rep.reverse_ok == rep.reverse_checked - rep.reverse_failed_shift);
            // Replay never reconnects, so gbdpt gives it no offsets; the others reconnect.
            if (std::string(name) != "replay") {
                CHECK(rep.failure_rate() < 0.5);
                CHECK(rep.jacobian_checked > 200);
                CHECK(rep.jacobian_worst_error < 0.1);
            }
        }
    }
    const SceneFile sf = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/scene.json");
    ValidateOptions opt;
    opt.paths = 1500;
    const ShiftReport bad = validate_bidirectional_shift(*sf.scene, *make_shift(BadReconnection{}), ShiftConfig{}, opt);
    INFO(bad.summary());
    CHECK_FALSE(bad.passed);
}

TEST_CASE("gbdpt renders with a shift registered from outside the library", "[gbdpt][shift]") {
    if (!shift_registry().has("outside-reconnection"))
        shift_registry().add("outside-reconnection", "test: the reconnection shift, registered by a user",
                             [](const Params&) { return make_shift(OutsideReconnection{}); });
    const auto scene = small_box("Original", 16);
    const FrameBuffer a = render(*scene, "gbdpt", params({{"shift", "outside-reconnection"}}), 4, 9);
    const FrameBuffer b = render(*scene, "gbdpt", params({{"shift", "reconnection"}}), 4, 9);
    for (const char* l : {"primal", "dx", "dy"})
        CHECK(std::memcmp(a.get(l).data(), b.get(l).data(), a.get(l).values().size() * sizeof(float)) == 0);
}
