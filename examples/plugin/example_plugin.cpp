// A plugin of the gdr tool, written outside the library: it adds
//
//   - the reconstructor "jacobi-poisson": the screened Poisson L2 solve of
//     gdr's poisson-l2 (Lehtinen, Karras, Laine, Aittala, Durand and Aila,
//     "Gradient-Domain Metropolis Light Transport", 2013, section 5), by plain
//     Jacobi iteration instead of a DCT: a few lines, slow to converge for
//     the image's low frequencies, and so a reconstructor whose parameters
//     (alpha, iterations) visibly matter;
//   - the shift mapping "late-reconnect": random-number replay at the first
//     `replay_vertices` vertices of the path, then reconnection at the first
//     connectable vertex after them (replay where it cannot).
//
// Built as a MODULE library (examples/plugin/CMakeLists.txt); the gdr tool
// loads it from GDR_PLUGIN_PATH or <libdir>/gdr when a run names either:
//
//   GDR_PLUGIN_PATH=build/examples/plugin/plugins gdr render scene.json --integrator gpt
//       --set shift=late-reconnect --set shift.replay_vertices=2
//       --set reconstruct=l2,jacobi-poisson --set reconstruct.jacobi-poisson.iterations=800 -o out.exr
#include <algorithm>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "gdr/plugin.h"
#include "gdr/shift/steps.h"

namespace {

using namespace gdr;

/// Minimises alpha^2 |x - c|^2 + |Dx x - gx|^2 + |Dy x - gy|^2 (radiance;
/// Dx, Dy forward differences inside the image) per channel by Jacobi
/// iteration on its normal equations
///   (alpha^2 + n_p) x_p - sum_{q ~ p} x_q = alpha^2 c_p + (Dx^T gx + Dy^T gy)_p,
/// n_p the number of p's 4-neighbours, starting from x = c.
class JacobiPoisson final : public Reconstructor {
public:
    static constexpr const char* kName = "jacobi-poisson";

    explicit JacobiPoisson(const Params& p) {
        alpha_ = p.get_real("alpha", 0.2);
        iterations_ = p.get_int("iterations", 200);
        if (!(alpha_ > 0.0)) throw ParameterError(p.context() + ": parameter '" + p.key_prefix() + "alpha' must be positive");
        if (iterations_ < 0 || iterations_ > 1000000)
            throw ParameterError(p.context() + ": parameter '" + p.key_prefix() + "iterations' must be in 0..1000000");
    }
    std::string describe() const override {
        return fmt::format("alpha={}\niterations={}\n", alpha_, iterations_);
    }

protected:
    Image solve(const GradientBuffers& in) const override {
        const Image &c = *in.primal, &gx = *in.dx, &gy = *in.dy;
        const int W = c.width(), H = c.height(), C = c.channels();
        const double a2 = alpha_ * alpha_;
        // The right-hand side, fixed over the iterations.
        std::vector<double> b(size_t(W) * H * C), x(b.size()), next(b.size());
        const auto at = [&](int px, int py, int ch) { return (size_t(py) * W + px) * C + ch; };
        for (int py = 0; py < H; ++py)
            for (int px = 0; px < W; ++px)
                for (int ch = 0; ch < C; ++ch) {
                    double r = a2 * c.at(px, py, ch);
                    if (px > 0) r += gx.at(px - 1, py, ch);
                    if (px + 1 < W) r -= gx.at(px, py, ch);
                    if (py > 0) r += gy.at(px, py - 1, ch);
                    if (py + 1 < H) r -= gy.at(px, py, ch);
                    b[at(px, py, ch)] = r;
                    x[at(px, py, ch)] = c.at(px, py, ch);
                }
        for (long long it = 0; it < iterations_; ++it) {
            for (int py = 0; py < H; ++py)
                for (int px = 0; px < W; ++px)
                    for (int ch = 0; ch < C; ++ch) {
                        double sum = 0.0;
                        int n = 0;
                        if (px > 0) sum += x[at(px - 1, py, ch)], ++n;
                        if (px + 1 < W) sum += x[at(px + 1, py, ch)], ++n;
                        if (py > 0) sum += x[at(px, py - 1, ch)], ++n;
                        if (py + 1 < H) sum += x[at(px, py + 1, ch)], ++n;
                        next[at(px, py, ch)] = (b[at(px, py, ch)] + sum) / (a2 + n);
                    }
            std::swap(x, next);
        }
        Image out(W, H, C);
        for (int py = 0; py < H; ++py)
            for (int px = 0; px < W; ++px)
                for (int ch = 0; ch < C; ++ch) out.at(px, py, ch) = float(x[at(px, py, ch)]);
        return out;
    }

private:
    double alpha_ = 0.2;
    long long iterations_ = 200;
};

/// Replays the base's random numbers at its first `replay_vertices` vertices
/// (x_1 .. x_n), then reconnects where the offset may (replaying where it
/// may not, which keeps the map invertible).
struct LateReconnectShift {
    static constexpr std::string_view kName = "late-reconnect";
    size_t replay_vertices = 1;

    explicit LateReconnectShift(const Params& p) {
        const long long n = p.get_int("replay_vertices", 1);
        if (n < 1 || n > 1024)
            throw ParameterError(p.context() + ": parameter '" + p.key_prefix() + "replay_vertices' must be in 1..1024, got " +
                                 std::to_string(n));
        replay_vertices = size_t(n);
    }

    ShiftStep step(const ShiftStepInput& in) const {
        if (!shift::base_has_next(in)) return ShiftStep{};
        if (in.k <= replay_vertices) return shift::replay(in);  // base.v[0] is the camera, v[1] the first hit
        return shift::reconnect_or(in, shift::replay);
    }
};
static_assert(ShiftMapping<LateReconnectShift>);

void add_example(PluginRegistries& r) {
    r.reconstructors->add(JacobiPoisson::kName,
                          "example plugin: screened Poisson L2 by Jacobi iteration (alpha, iterations)",
                          [](const Params& p) { return std::make_unique<JacobiPoisson>(p); });
    register_shift<LateReconnectShift>(*r.shifts,
                                       "example plugin: replay at the first replay_vertices vertices, then reconnect");
}

}  // namespace

GDR_EXPORT_PLUGIN(add_example)
