// G-PT cost and gradient noise against PT, measured in one run.
//  1. Cost of one G-PT sample relative to one PT sample (medians of interleaved runs).
//  2. Variance of the sampled gradients dx against the variance of finite
//     differences of the PT image, both at equal time (per-sample variances
//     scaled by the samples each method affords in the same time).
// Usage: bench_gpt [SCENE.json] [repeats]
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"

using namespace gdr;

namespace {

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

double grey(const Image& img, int x, int y) {
    const Color c = img.rgb(x, y);
    return (double(c.r) + c.g + c.b) / 3.0;
}

}  // namespace

int main(int argc, char** argv) {
    const std::string path = argc > 1 ? argv[1] : GDR_SOURCE_DIR "/scenes/cornell-box/scene.json";
    const int repeats = argc > 2 ? std::atoi(argv[2]) : 3;
    const SceneFile sf = load_scene_file(path);
    const Scene& scene = *sf.scene;
    auto pt = integrator_registry().create("pt", Params());
    // Sample cost only: the reconstructions are timed by bench_reconstruct.
    Params gp;
    gp.set("reconstruct", std::string("none"));
    auto gpt = integrator_registry().create("gpt", gp);
    RenderSettings st;
    std::vector<double> pt_rate, gpt_rate;
    FrameBuffer pt_fb, gpt_fb;
    for (int r = 0; r < repeats; ++r) {
        st.seed = uint64_t(r);
        // Enough samples that per-render fixed costs (buffers, finalisation) fade.
        st.spp = 32;
        const RenderStats a = pt->render(scene, st, pt_fb);
        st.spp = 12;
        const RenderStats b = gpt->render(scene, st, gpt_fb);
        pt_rate.push_back(double(a.samples) / a.seconds);
        gpt_rate.push_back(double(b.samples) / b.seconds);
        std::printf("run %d: pt %.3f M samples/s (%.2f M rays/s), gpt %.3f M samples/s (%.2f M rays/s)\n", r,
                    pt_rate.back() * 1e-6, double(a.rays) / a.seconds * 1e-6, gpt_rate.back() * 1e-6,
                    double(b.rays) / b.seconds * 1e-6);
    }
    const double cost = median(pt_rate) / median(gpt_rate);
    std::printf("\n%s (%dx%d)\n", path.c_str(), scene.camera().width(), scene.camera().height());
    std::printf("median PT  : %.3f M samples/s\n", median(pt_rate) * 1e-6);
    std::printf("median G-PT: %.3f M samples/s\n", median(gpt_rate) * 1e-6);
    std::printf("cost of a G-PT sample / a PT sample: %.2fx (median of %d interleaved runs)\n", cost, repeats);

    // Equal time: per-sample variances divided by the samples each affords, PT getting `cost` times more.
    const Image& vpt = pt_fb.get("variance");
    const Image& vdx = gpt_fb.get("dx_variance");
    const int W = scene.camera().width(), H = scene.camera().height();
    double sum_g = 0.0, sum_fd = 0.0;
    std::vector<double> ratios;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x + 1 < W; ++x) {
            const double g = grey(vdx, x, y);
            const double fd = (grey(vpt, x, y) + grey(vpt, x + 1, y)) / cost;
            sum_g += g, sum_fd += fd;
            if (fd > 0.0) ratios.push_back(g / fd);
        }
    std::printf("equal-time variance of dx: sampled gradients %.4g, PT finite differences %.4g (mean over pixels)\n",
                sum_g / ((W - 1.0) * H), sum_fd / ((W - 1.0) * H));
    std::printf("  ratio FD / gradients: %.2fx less variance (mean); median per-pixel ratio gradients/FD %.3g\n",
                sum_fd / sum_g, ratios.empty() ? 0.0 : median(ratios));
    return 0;
}
