// A shift mapping written outside gdr: "late-reconnect" replays the base's
// random numbers at the first vertex and reconnects at the first connectable
// vertex after it. It is built from gdr's public shift building blocks,
// registered by name, validated, and used by the unmodified `gpt` integrator.
#include <cstdio>
#include <string>

#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/shift/steps.h"
#include "gdr/shift/validate.h"

namespace {

struct LateReconnectShift {
    static constexpr std::string_view kName = "late-reconnect";

    gdr::ShiftStep step(const gdr::ShiftStepInput& in) const {
        using namespace gdr;
        if (!shift::base_has_next(in)) return ShiftStep{};
        if (in.k == 1) return shift::replay(in);  // never reconnect from the first hit (base.v[0] is the camera)
        // Later: reconnect where allowed, replay otherwise (keeping the map invertible).
        return shift::reconnect_or(in, shift::replay);
    }
};
static_assert(gdr::ShiftMapping<LateReconnectShift>);

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: custom_shift SCENE.json OUT.exr\n");
        return 2;
    }
    try {
        gdr::shift_registry().add("late-reconnect", "replay at the first vertex, reconnect later",
                                  [](const gdr::Params&) { return gdr::make_shift(LateReconnectShift{}); });

        const gdr::SceneFile sf = gdr::load_scene_file(argv[1]);
        gdr::ValidateOptions vopt;
        vopt.paths = 3000;
        const auto shift = gdr::shift_registry().create("late-reconnect", gdr::Params());
        const gdr::ShiftReport report = gdr::validate_shift(*sf.scene, *shift, gdr::ShiftConfig{}, vopt);
        std::printf("%s", report.summary().c_str());

        gdr::Params p;
        p.set("shift", std::string("late-reconnect"));
        auto gpt = gdr::integrator_registry().create("gpt", p);
        gdr::RenderSettings st;
        st.spp = 2;
        gdr::FrameBuffer fb;
        const gdr::RenderStats rs = gpt->render(*sf.scene, st, fb);
        gdr::write_exr(argv[2], fb);
        std::printf("rendered %lld spp with gpt shift=late-reconnect in %.2f s -> %s\n", rs.spp, rs.seconds, argv[2]);
        return report.passed ? 0 : 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "custom_shift: %s\n", e.what());
        return 1;
    }
}
