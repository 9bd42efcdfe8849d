// Renders a scene with "simple-gpt", a gradient-domain path tracer written
// outside gdr on its public film (simple_gpt.h), and checks what it wrote
// against gdr's own gpt: both estimate the same primal and gradients, so the
// two images' means agree within their noise.
//
//   gradient_integrator SCENE.json OUT.exr [--spp N] [--shift NAME]
#include <cmath>
#include <cstdio>
#include <string>

#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "simple_gpt.h"

namespace {

// Mean of a layer over the image (radiance), and its standard error from the per-sample variance layer.
std::pair<double, double> mean_and_error(const gdr::FrameBuffer& fb, const std::string& layer, long long spp) {
    const gdr::Image& v = fb.get(layer);
    const gdr::Image& var = fb.get(layer + "_variance");
    double sum = 0.0, var_sum = 0.0;
    for (size_t i = 0; i < v.values().size(); ++i) sum += v.values()[i], var_sum += var.values()[i];
    const double n = double(v.values().size());
    // Pixels are independent: the mean's variance is the sum of theirs over n^2.
    return {sum / n, std::sqrt(var_sum / double(spp)) / n};
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 3 || argc % 2 == 0) {
        std::fprintf(stderr, "usage: gradient_integrator SCENE.json OUT.exr [--spp N] [--shift NAME]\n");
        return 2;
    }
    const std::string scene_path = argv[1], out = argv[2];
    long long spp = 16;
    std::string shift = "half-vector";
    for (int i = 3; i + 1 < argc; i += 2) {
        const std::string opt = argv[i], value = argv[i + 1];
        if (opt == "--spp") spp = std::stoll(value);
        else if (opt == "--shift") shift = value;
        else {
            std::fprintf(stderr, "gradient_integrator: unknown option %s\n", opt.c_str());
            return 2;
        }
    }
    try {
        example::register_simple_gpt();
        const gdr::SceneFile sf = gdr::load_scene_file(scene_path);
        gdr::Params p("gradient_integrator");
        p.set("shift", shift);
        p.set("reconstruct", std::string("l1"));
        gdr::RenderSettings st;
        st.spp = spp;
        gdr::FrameBuffer mine, theirs;
        gdr::integrator_registry().create("simple-gpt", p)->render(*sf.scene, st, mine);
        st.seed = 1;  // independent samples for the comparison
        gdr::integrator_registry().create("gpt", p)->render(*sf.scene, st, theirs);
        gdr::write_exr(out, mine);
        bool ok = mine.has("reconstruction_l1");
        for (const char* layer : {"primal", "dx", "dy"}) {
            const auto [a, ea] = mean_and_error(mine, layer, spp);
            const auto [b, eb] = mean_and_error(theirs, layer, spp);
            const double z = std::abs(a - b) / std::sqrt(ea * ea + eb * eb);
            std::printf("%-6s simple-gpt %.6f +- %.6f, gpt %.6f +- %.6f, z %.2f\n", layer, a, ea, b, eb, z);
            ok = ok && z < 4.0;
        }
        std::printf("wrote %s\n", out.c_str());
        if (!ok) {
            std::fprintf(stderr, "gradient_integrator: simple-gpt and gpt disagree beyond their noise\n");
            return 1;
        }
        return 0;
    } catch (const gdr::Error& e) {
        std::fprintf(stderr, "gradient_integrator: error: %s\n", e.what());
        return 1;
    }
}
