// A renderer that has never heard of the rest of gdr: it has its own RGB float
// buffers (a noisy colour estimate and noisy forward-difference gradients, as
// a gradient-domain renderer produces them) and wants the reconstructed image.
//
// Two ways in: the Reconstructor registry on gdr::Image (one copy in, checks
// for NaN / Inf with the offending pixel, direct emitters added afterwards),
// or the solver core on its own memory without any copy (gdr/reconstruct/
// poisson.h). Prints the error of each against the noise-free image.
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "gdr/reconstruct/poisson.h"
#include "gdr/reconstruct/reconstructor.h"

namespace {

// The "renderer": a 320x240 image of a lit disc on a gradient background,
// with Monte Carlo-like noise: the colour estimate is much noisier than the
// gradient estimates, and a few samples are fireflies.
struct Frame {
    int width = 320, height = 240;
    std::vector<float> truth, color, dx, dy;  // interleaved RGB, row 0 at the top
};

Frame render() {
    Frame f;
    const int w = f.width, h = f.height;
    f.truth.resize(size_t(w) * h * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float disc = std::hypot(x - 160.f, y - 120.f) < 70.f ? 1.f : 0.f;
            const float base[3] = {0.2f + 0.3f * x / w, 0.25f, 0.3f + 0.2f * y / h};
            for (int c = 0; c < 3; ++c) f.truth[(size_t(y) * w + x) * 3 + c] = base[c] + disc * (0.6f - 0.2f * c);
        }
    std::mt19937 rng(1);
    std::normal_distribution<float> n(0.f, 1.f);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    auto noise = [&](float sigma) { return sigma * n(rng) + (u(rng) < 0.001f ? 10.f * u(rng) : 0.f); };
    f.color = f.truth, f.dx.assign(f.truth.size(), 0.f), f.dy.assign(f.truth.size(), 0.f);
    auto at = [&](const std::vector<float>& v, int x, int y, int c) { return v[(size_t(y) * w + x) * 3 + c]; };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                const size_t i = (size_t(y) * w + x) * 3 + c;
                f.color[i] += noise(0.2f);
                // Forward differences stored at the left / top pixel; the last column / row stay 0 (unused).
                if (x + 1 < w) f.dx[i] = at(f.truth, x + 1, y, c) - at(f.truth, x, y, c) + noise(0.05f);
                if (y + 1 < h) f.dy[i] = at(f.truth, x, y + 1, c) - at(f.truth, x, y, c) + noise(0.05f);
            }
    return f;
}

double rmse(const float* a, const std::vector<float>& ref) {
    double s = 0;
    for (size_t i = 0; i < ref.size(); ++i) s += (a[i] - ref[i]) * double(a[i] - ref[i]);
    return std::sqrt(s / double(ref.size()));
}

}  // namespace

int main() {
    const Frame f = render();
    std::printf("noisy colour estimate: RMSE %.4f\n", rmse(f.color.data(), f.truth));

    // 1. Through the registry: copy the buffers into gdr::Image once.
    auto image = [&](const std::vector<float>& v) {
        gdr::Image img(f.width, f.height, 3);
        img.values() = v;
        return img;
    };
    const gdr::Image color = image(f.color), dx = image(f.dx), dy = image(f.dy);
    const gdr::GradientBuffers buffers{&color, &dx, &dy, /*direct=*/nullptr};
    gdr::Params params("embed example");
    params.set("alpha", 0.2);
    try {
        const gdr::Image l2 = gdr::reconstruct("poisson-l2", params, buffers);
        const gdr::Image l1 = gdr::reconstruct("poisson-l1", params, buffers);
        std::printf("poisson-l2 (unbiased):           RMSE %.4f\n", rmse(l2.data(), f.truth));
        std::printf("poisson-l1 (robust to outliers): RMSE %.4f\n", rmse(l1.data(), f.truth));
    } catch (const gdr::Error& e) {  // bad input (NaN / Inf, shapes) or parameters
        std::fprintf(stderr, "reconstruction failed: %s\n", e.what());
        return 1;
    }

    // 2. The solver core straight on the renderer's own memory (no copies).
    std::vector<float> out(f.truth.size());
    const gdr::PoissonProblem problem{{f.color.data(), f.width, f.height, 3},
                                      {f.dx.data(), f.width, f.height, 3},
                                      {f.dy.data(), f.width, f.height, 3},
                                      /*alpha=*/0.2};
    gdr::poisson_l2(problem, out.data());
    std::printf("poisson_l2 on raw buffers:       RMSE %.4f\n", rmse(out.data(), f.truth));
    return 0;
}
