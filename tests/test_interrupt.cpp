// Stopping a render: a cancel abandons a long pass and undoes it, so that the
// image returned holds exactly the passes that finished, and is the same as
// an uninterrupted render of that many samples.
#include <catch2/catch.hpp>

#include <atomic>

#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"

using namespace gdr;

namespace {

const std::string kScene = GDR_SOURCE_DIR "/tests/scenes/cornell-small.json";

// Largest absolute difference between two renders' layers of the same name.
double worst_difference(const FrameBuffer& a, const FrameBuffer& b) {
    double worst = 0.0;
    for (const auto& name : a.names()) {
        REQUIRE(b.has(name));
        const auto &va = a.get(name).values(), &vb = b.get(name).values();
        REQUIRE(va.size() == vb.size());
        for (size_t i = 0; i < va.size(); ++i) worst = std::max(worst, double(std::abs(va[i] - vb[i])));
    }
    return worst;
}

}  // namespace

TEST_CASE("interrupt: a pass abandoned part-way is undone exactly", "[interrupt]") {
    const SceneFile sf = load_scene_file(kScene);
    const int npix = sf.scene->camera().width() * sf.scene->camera().height();
    for (const char* name : {"pt", "gpt"}) {
        INFO(name);
        auto integrator = integrator_registry().create(name, Params("test"));
        std::atomic<bool> cancel{false};
        RenderSettings st;
        st.spp = 64;
        st.seed = 7;
        // One thread: tiles run in order, so the cancel falls inside the pass.
        st.threads = 1;
        st.cancel = &cancel;
        // No wait at all: every pass after the first takes one sample per
        // pixel and can be abandoned.
        st.stop_latency = 0.0;
        // Cancelled when the sixth pass is about half done: its finished tiles
        // must be undone, leaving five whole passes.
        const uint64_t trigger = uint64_t(5) * npix + uint64_t(npix) / 2;
        FrameBuffer stopped;
        const RenderStats rs = integrator->render(*sf.scene, st, stopped, [&](const Progress& p) {
            if (p.samples >= trigger) cancel = true;
        });
        CHECK(rs.spp == 5);
        CHECK(rs.samples == uint64_t(5) * npix);
        CHECK(stopped.metadata().at("spp") == "5");
        // The same image as five samples per pixel taken without interruption,
        // to the last bit: the undo restores the sums, it does not subtract.
        RenderSettings five = st;
        five.spp = 5;
        five.cancel = nullptr;
        FrameBuffer whole;
        integrator->render(*sf.scene, five, whole);
        CHECK(worst_difference(stopped, whole) == 0.0);
    }
}

TEST_CASE("interrupt: an abort before the first pass finished leaves no image", "[interrupt]") {
    const SceneFile sf = load_scene_file(kScene);
    auto integrator = integrator_registry().create("pt", Params("test"));
    std::atomic<bool> abort{false};
    RenderSettings st;
    st.spp = 4;
    st.threads = 1;
    st.abort = &abort;
    FrameBuffer fb;
    CHECK_THROWS_AS(integrator->render(*sf.scene, st, fb, [&](const Progress&) { abort = true; }), Interrupted);
    // A cancel after the first pass keeps the finished passes; an abort skips
    // the reconstructions (recomputed on merge), so that the render stops at once.
    auto gpt = integrator_registry().create("gpt", Params("test"));
    abort = false;
    std::atomic<bool> cancel{false};
    st.abort = &abort;
    st.cancel = &cancel;
    st.spp = 64;
    const int npix = sf.scene->camera().width() * sf.scene->camera().height();
    gpt->render(*sf.scene, st, fb, [&](const Progress& p) {
        if (p.samples >= uint64_t(npix)) abort = true;
    });
    CHECK(fb.has("dx"));
    CHECK_FALSE(fb.has("reconstruction_l1"));
    CHECK_FALSE(fb.has("reconstruction_l2"));
    CHECK(std::stoll(fb.metadata().at("spp")) >= 1);
}
