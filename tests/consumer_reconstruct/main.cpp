// Reconstructs an image from its exact gradients and a noisy primal with the
// installed gdr::reconstruct component alone (no renderer, no file format):
// the way a renderer with its own gradient-domain buffers uses gdr.
#include <cmath>
#include <cstdio>

#include "gdr/core/error.h"
#include "gdr/reconstruct/reconstructor.h"

int main() {
    try {
        const int W = 40, H = 30;
        gdr::Image truth(W, H, 3), primal(W, H, 3), dx(W, H, 3), dy(W, H, 3);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const float v = 0.5f + 0.4f * std::sin(0.2f * float(x)) * std::cos(0.15f * float(y));
                truth.set_rgb(x, y, gdr::Color(v, 0.5f * v, 0.25f * v));
                // A primal off by a checkerboard of +-0.1: noise the gradients do not have.
                const float noise = (x + y) % 2 ? 0.1f : -0.1f;
                primal.set_rgb(x, y, gdr::Color(v + noise, 0.5f * v + noise, 0.25f * v + noise));
            }
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                if (x + 1 < W) dx.set_rgb(x, y, truth.rgb(x + 1, y) - truth.rgb(x, y));
                if (y + 1 < H) dy.set_rgb(x, y, truth.rgb(x, y + 1) - truth.rgb(x, y));
            }
        gdr::GradientBuffers in;
        in.primal = &primal, in.dx = &dx, in.dy = &dy;
        const gdr::Image out = gdr::reconstruct("poisson-l2", gdr::Params(), in);
        double err_primal = 0.0, err_out = 0.0;
        for (size_t i = 0; i < truth.values().size(); ++i) {
            err_primal += std::abs(double(primal.values()[i]) - truth.values()[i]);
            err_out += std::abs(double(out.values()[i]) - truth.values()[i]);
        }
        std::printf("consumer_reconstruct: mean absolute error %.4f (primal %.4f), reconstructors:",
                    err_out / double(truth.values().size()), err_primal / double(truth.values().size()));
        for (const auto& name : gdr::reconstructor_registry().names()) std::printf(" %s", name.c_str());
        std::printf("\n");
        // Exact gradients and an alternating primal error: the solve removes nearly all of it.
        return err_out < 0.1 * err_primal ? 0 : 1;
    } catch (const gdr::Error& e) {
        std::fprintf(stderr, "consumer_reconstruct: error: %s\n", e.what());
        return 1;
    }
}
