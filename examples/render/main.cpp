// The smallest program that renders with gdr: load a scene file, create an
// integrator by name, render into a frame buffer of named layers, and write
// every layer to one EXR. The README's C++ quick start is this file.
#include <cstdio>

#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: render SCENE.json|SCENE.xml OUT.exr\n");
        return 2;
    }
    try {
        gdr::SceneFile sf = gdr::load_scene_file(argv[1]);
        gdr::set_resolution(sf, 128, 0);                          // 128 pixels wide, the camera's aspect ratio
        gdr::Params params;
        params.set_from_text("shift=reconnection");               // as gdr render --set
        auto gpt = gdr::integrator_registry().create("gpt", params);
        gdr::RenderSettings settings;                              // spp, time_budget, threads, seed
        settings.spp = 16;
        gdr::FrameBuffer fb;
        gpt->render(*sf.scene, settings, fb);
        const gdr::Image& image = fb.get("reconstruction_l1");     // the G-PT image; fb also holds dx, dy, ...
        gdr::write_exr(argv[2], fb);                               // every layer
        std::printf("rendered %dx%d at %lld spp -> %s\n", image.width(), image.height(), settings.spp, argv[2]);
        return 0;
    } catch (const gdr::Error& e) {  // a bad scene file, parameter or output path, named in the message
        std::fprintf(stderr, "render: %s\n", e.what());
        return 1;
    }
}
