// A shift mapping written outside gdr: "late-reconnect" replays the base's
// random numbers at the first vertex and reconnects at the first connectable
// vertex after it. It is built from gdr's public shift building blocks,
// registered by name, validated, and used by the unmodified `gpt` and
// `gbdpt` integrators (gbdpt applies it to the camera side of bidirectional
// paths and validates it there too).
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
        // Registered under its kName; examples/plugin has a version with a parameter.
        gdr::register_shift<LateReconnectShift>(gdr::shift_registry(), "replay at the first vertex, reconnect later");

        const gdr::SceneFile sf = gdr::load_scene_file(argv[1]);
        gdr::ValidateOptions vopt;
        vopt.paths = 3000;
        const auto shift = gdr::shift_registry().create("late-reconnect", gdr::Params());
        const gdr::ShiftReport report = gdr::validate_shift(*sf.scene, *shift, gdr::ShiftConfig{}, vopt);
        std::printf("%s", report.summary().c_str());
        const gdr::ShiftReport bidir = gdr::validate_bidirectional_shift(*sf.scene, *shift, gdr::ShiftConfig{}, vopt);
        std::printf("%s", bidir.summary().c_str());

        gdr::Params p;
        p.set("shift", std::string("late-reconnect"));
        auto gpt = gdr::integrator_registry().create("gpt", p);
        gdr::RenderSettings st;
        st.spp = 2;
        gdr::FrameBuffer fb;
        const gdr::RenderStats rs = gpt->render(*sf.scene, st, fb);
        gdr::write_exr(argv[2], fb);
        std::printf("rendered %lld spp with gpt shift=late-reconnect in %.2f s -> %s\n", rs.spp, rs.seconds, argv[2]);
        // The same shift in gradient-domain bidirectional path tracing.
        auto gbdpt = gdr::integrator_registry().create("gbdpt", p);
        gdr::FrameBuffer fb2;
        const gdr::RenderStats rs2 = gbdpt->render(*sf.scene, st, fb2);
        const std::string out2 = std::string(argv[2]) + ".gbdpt.exr";
        gdr::write_exr(out2, fb2);
        std::printf("rendered %lld spp with gbdpt shift=late-reconnect in %.2f s -> %s\n", rs2.spp, rs2.seconds, out2.c_str());
        return report.passed && bidir.passed ? 0 : 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "custom_shift: %s\n", e.what());
        return 1;
    }
}
