// Spatio-temporal reconstruction: time, CG iterations and, for L1, the energy
// gap to a converged IRLS of one window of a synthetic noisy video, per
// solver and preconditioner (gdr/reconstruct/temporal.h).
//
//   bench_temporal [--width W] [--height H] [--frames F]
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <random>
#include <string>

#include "gdr/reconstruct/temporal.h"

using namespace gdr;

namespace {

/// A translating, brightening smooth video with edges; motion (mx, 0) px per frame.
std::vector<TemporalFrame> video(int w, int h, int F, int mx, uint32_t seed) {
    auto value = [&](int f, int x, int y, int c) {
        const float u = float(x - f * mx), v = float(y);
        const float edge = (int(std::floor(u / 37.f)) + int(std::floor(v / 29.f))) % 2 == 0 ? 0.4f : 0.f;
        return (1.f + 0.03f * f) * (0.5f + 0.3f * std::sin(0.05f * u + 0.07f * v + c) + edge);
    };
    std::mt19937 rng(seed);
    std::normal_distribution<float> n(0.f, 1.f);
    std::vector<TemporalFrame> frames(F);
    for (int f = 0; f < F; ++f) {
        TemporalFrame& fr = frames[f];
        fr.name = "frame " + std::to_string(f);
        fr.primal = Image(w, h, 3), fr.dx = Image(w, h, 3), fr.dy = Image(w, h, 3);
        if (f + 1 < F) fr.dt = Image(w, h, 3), fr.motion = Image(w, h, 2);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < 3; ++c) {
                    const float v = value(f, x, y, c);
                    fr.primal.at(x, y, c) = v + 0.3f * n(rng);
                    fr.dx.at(x, y, c) = (x + 1 < w ? value(f, x + 1, y, c) - v : 0.f) + 0.05f * n(rng);
                    fr.dy.at(x, y, c) = (y + 1 < h ? value(f, x, y + 1, c) - v : 0.f) + 0.05f * n(rng);
                    if (f + 1 < F) {
                        fr.dt.at(x, y, c) = value(f + 1, x + mx, y, c) - v + 0.05f * n(rng);
                        fr.motion.at(x, y, 0) = float(mx);
                    }
                }
    }
    return frames;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
    int w = 320, h = 180, F = 10;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string a = argv[i];
        if (a == "--width") w = std::stoi(argv[i + 1]);
        else if (a == "--height") h = std::stoi(argv[i + 1]);
        else if (a == "--frames") F = std::stoi(argv[i + 1]);
    }
    fmt::print("window of {} frames of {}x{}x3\n", F, w, h);
    auto run = [&](const std::vector<TemporalFrame>& frames, const TemporalOptions& o, std::vector<Image>& out) {
        std::vector<TemporalFrameView> v;
        std::vector<float*> p;
        out.clear();
        for (const auto& f : frames) v.push_back(f.view()), out.emplace_back(w, h, 3);
        for (auto& img : out) p.push_back(img.data());
        const auto t0 = std::chrono::steady_clock::now();
        const TemporalReport r = solve_temporal_window(v, o, p);
        return std::pair{r, seconds_since(t0)};
    };
    std::vector<Image> out;
    for (int mx : {0, 1}) {
        const auto frames = video(w, h, F, mx, 1);
        TemporalOptions l2;
        l2.norm = TemporalNorm::l2;
        for (auto [name, solver, pre] :
             {std::tuple{"auto", TemporalSolver::automatic, TemporalPreconditioner::dct},
              std::tuple{"cg+dct", TemporalSolver::cg, TemporalPreconditioner::dct},
              std::tuple{"cg+multigrid", TemporalSolver::cg, TemporalPreconditioner::frame_multigrid}}) {
            l2.solver = solver, l2.l2_preconditioner = pre;
            const auto [r, s] = run(frames, l2, out);
            fmt::print("L2 motion {} {:<13} {:6.3f} s  direct {}  CG {:3d}  residual {:.1e}\n", mx, name, s,
                       r.direct_solve, r.cg_iterations, r.relative_residual);
        }
        TemporalOptions conv;
        conv.irls_cg_iterations = 100, conv.irls_tolerance = 1e-6, conv.irls_iterations = 20;
        const double ref = run(frames, conv, out).first.energy;
        for (auto pre : {TemporalPreconditioner::frame_multigrid, TemporalPreconditioner::dct})
            for (int cg : {1, 2, 4, 8}) {
                TemporalOptions l1;
                l1.irls_cg_iterations = cg, l1.irls_preconditioner = pre;
                const auto [r, s] = run(frames, l1, out);
                fmt::print("L1 motion {} {:<10} x{}  {:6.3f} s  CG {:4d}  energy gap {:.3f}%\n", mx,
                           pre == TemporalPreconditioner::dct ? "dct" : "multigrid", cg, s, r.irls_cg_iterations,
                           100.0 * (r.energy - ref) / ref);
            }
    }
    return 0;
}
