// Renders a scene with the installed library's path tracer and checks the
// result: the smallest program that proves headers, the static library and
// its dependencies all resolve through find_package(gdr).
//
//   consumer SCENE.json   (a camera facing an emitter of radiance (3, 2, 0.5))
#include <cstdio>

#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: consumer SCENE.json\n");
        return 2;
    }
    try {
        const gdr::SceneFile sf = gdr::load_scene_file(argv[1]);
        auto pt = gdr::integrator_registry().create("pt", gdr::Params());
        gdr::RenderSettings st;
        st.spp = 4;
        gdr::FrameBuffer fb;
        pt->render(*sf.scene, st, fb, {});
        const gdr::Color c = fb.get("color").rgb(fb.width() / 2, fb.height() / 2);
        std::printf("consumer: centre pixel %g %g %g\n", c.r, c.g, c.b);
        return c == gdr::Color(3.f, 2.f, 0.5f) ? 0 : 1;
    } catch (const gdr::Error& e) {
        std::fprintf(stderr, "consumer: error: %s\n", e.what());
        return 1;
    }
}
