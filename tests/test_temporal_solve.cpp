// Spatio-temporal screened Poisson reconstruction (gdr/reconstruct/temporal.h):
// exactness of the DCT, CG and IRLS paths, agreement with a dense solve and
// between the solvers, unbiasedness of L2, the temporal term against
// flicker, seamless window blending and its memory bound, and bad input.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <unistd.h>

#include "gdr/io/reconstruct_files.h"
#include "gdr/io/exr.h"
#include "gdr/reconstruct/poisson.h"
#include "gdr/reconstruct/temporal.h"

using namespace gdr;

namespace {

struct Motion {
    float mx = 0, my = 0;  // per-frame motion as stored (pixels); rounds to (vx, vy)
    int vx = 0, vy = 0;
};

/// A smooth video: frame f shows g translated by f * (vx, vy) whole pixels and
/// brightened by `gain` per frame; values in about [0.05, 1.7].
Image truth_frame(int w, int h, int C, int f, const Motion& m, float gain = 0.05f, float base = 0.f) {
    Image img(w, h, C);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < C; ++c) {
                const float u = float(x - f * m.vx), v = float(y - f * m.vy);
                img.at(x, y, c) = base + (1.f + gain * f) * (0.65f + 0.35f * std::sin(0.23f * u + 0.11f * v + c) +
                                                             0.25f * std::cos(0.07f * u - 0.19f * v + 2.f * c));
            }
    return img;
}

/// Exact layers of a video of `truth` frames; unused entries hold junk that must be ignored.
std::vector<TemporalFrame> exact_frames(const std::vector<Image>& truth, const Motion& m, bool with_motion) {
    const int F = int(truth.size()), w = truth[0].width(), h = truth[0].height(), C = truth[0].channels();
    std::vector<TemporalFrame> out(F);
    for (int f = 0; f < F; ++f) {
        TemporalFrame& fr = out[f];
        fr.name = "frame " + std::to_string(f);
        const Image& t = truth[f];
        fr.primal = t;
        fr.dx = Image(w, h, C), fr.dy = Image(w, h, C);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < C; ++c) {
                    fr.dx.at(x, y, c) = x + 1 < w ? t.at(x + 1, y, c) - t.at(x, y, c) : 55.f;
                    fr.dy.at(x, y, c) = y + 1 < h ? t.at(x, y + 1, c) - t.at(x, y, c) : -55.f;
                }
        if (f + 1 == F) continue;
        fr.dt = Image(w, h, C);
        if (with_motion) {
            fr.motion = Image(w, h, 2);
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x) fr.motion.at(x, y, 0) = m.mx, fr.motion.at(x, y, 1) = m.my;
        }
        const int vx = with_motion ? m.vx : 0, vy = with_motion ? m.vy : 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < C; ++c) {
                    const int qx = x + vx, qy = y + vy;
                    const bool inside = qx >= 0 && qy >= 0 && qx < w && qy < h;
                    fr.dt.at(x, y, c) = inside ? truth[f + 1].at(qx, qy, c) - t.at(x, y, c) : 99.f;  // junk outside
                }
    }
    return out;
}

std::vector<Image> truth_video(int w, int h, int C, int F, const Motion& m, float gain = 0.05f, float base = 0.f) {
    std::vector<Image> v;
    for (int f = 0; f < F; ++f) v.push_back(truth_frame(w, h, C, f, m, gain, base));
    return v;
}

std::vector<TemporalFrameView> views(const std::vector<TemporalFrame>& frames) {
    std::vector<TemporalFrameView> v;
    for (const auto& f : frames) v.push_back(f.view());
    return v;
}

/// Solves one window; returns the frames.
std::vector<Image> solve(const std::vector<TemporalFrame>& frames, const TemporalOptions& opt,
                         TemporalReport* report = nullptr) {
    std::vector<Image> out;
    std::vector<float*> ptr;
    for (const auto& f : frames) out.emplace_back(f.primal.width(), f.primal.height(), f.primal.channels());
    for (auto& o : out) ptr.push_back(o.data());
    const TemporalReport rep = solve_temporal_window(views(frames), opt, ptr);
    if (report) *report = rep;
    return out;
}

/// Streams frames through a TemporalReconstructor and returns every output.
std::vector<Image> stream(const std::vector<TemporalFrame>& frames, const TemporalOptions& opt,
                          int* max_held = nullptr, int* max_blends = nullptr) {
    TemporalReconstructor rec(opt);
    std::vector<Image> out;
    for (const auto& f : frames) {
        rec.push(f);
        if (max_held) *max_held = std::max(*max_held, rec.held_frames());
        if (max_blends) *max_blends = std::max(*max_blends, rec.pending_blends());
        while (rec.ready()) out.push_back(rec.pop());
    }
    rec.finish();
    while (rec.ready()) out.push_back(rec.pop());
    return out;
}

/// max |a - b| / max |b| over all frames.
double rel_error(const std::vector<Image>& a, const std::vector<Image>& b) {
    double e = 0, m = 0;
    for (size_t f = 0; f < a.size(); ++f)
        for (size_t i = 0; i < a[f].values().size(); ++i) {
            e = std::max(e, double(std::abs(a[f].values()[i] - b[f].values()[i])));
            m = std::max(m, double(std::abs(b[f].values()[i])));
        }
    return e / std::max(m, 1e-30);
}

void add_noise(Image& img, float sigma, std::mt19937& rng) {
    std::normal_distribution<float> n(0.f, sigma);
    for (auto& v : img.values()) v += n(rng);
}

/// Dense double-precision solve of the L2 energy, built row by row from its
/// definition (independently of the solver): Cholesky of the normal equations.
std::vector<Image> dense_solve(const std::vector<TemporalFrame>& frames, double alpha, double ws, double wt) {
    const int F = int(frames.size()), w = frames[0].primal.width(), h = frames[0].primal.height();
    const int C = frames[0].primal.channels(), n = w * h, N = F * n;
    std::vector<double> A(size_t(N) * N, 0.0), b(size_t(N) * C, 0.0);
    auto row = [&](int i, int j, double weight, const float* g) {  // row: x_j - x_i - g
        A[size_t(i) * N + i] += weight, A[size_t(j) * N + j] += weight;
        A[size_t(i) * N + j] -= weight, A[size_t(j) * N + i] -= weight;
        for (int c = 0; c < C; ++c) b[size_t(j) * C + c] += weight * g[c], b[size_t(i) * C + c] -= weight * g[c];
    };
    for (int f = 0; f < F; ++f) {
        const TemporalFrame& fr = frames[f];
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const int p = y * w + x, i = f * n + p;
                A[size_t(i) * N + i] += alpha * alpha;
                for (int c = 0; c < C; ++c) b[size_t(i) * C + c] += alpha * alpha * fr.primal.at(x, y, c);
                if (x + 1 < w) row(i, i + 1, ws * ws, fr.dx.data() + size_t(p) * C);
                if (y + 1 < h) row(i, i + w, ws * ws, fr.dy.data() + size_t(p) * C);
                if (f + 1 < F && !fr.dt.empty() && (fr.valid.empty() || fr.valid.at(x, y) >= 0.5f)) {
                    const int qx = x + (fr.motion.empty() ? 0 : int(std::lround(fr.motion.at(x, y, 0))));
                    const int qy = y + (fr.motion.empty() ? 0 : int(std::lround(fr.motion.at(x, y, 1))));
                    if (qx >= 0 && qy >= 0 && qx < w && qy < h) row(i, (f + 1) * n + qy * w + qx, wt * wt, fr.dt.data() + size_t(p) * C);
                }
            }
    }
    for (int j = 0; j < N; ++j) {
        double d = A[size_t(j) * N + j];
        for (int k = 0; k < j; ++k) d -= A[size_t(j) * N + k] * A[size_t(j) * N + k];
        A[size_t(j) * N + j] = std::sqrt(d);
        for (int i = j + 1; i < N; ++i) {
            double s = A[size_t(i) * N + j];
            for (int k = 0; k < j; ++k) s -= A[size_t(i) * N + k] * A[size_t(j) * N + k];
            A[size_t(i) * N + j] = s / A[size_t(j) * N + j];
        }
    }
    std::vector<Image> out(F, Image(w, h, C));
    for (int c = 0; c < C; ++c) {
        std::vector<double> z(N);
        for (int i = 0; i < N; ++i) {
            double s = b[size_t(i) * C + c];
            for (int k = 0; k < i; ++k) s -= A[size_t(i) * N + k] * z[k];
            z[i] = s / A[size_t(i) * N + i];
        }
        for (int i = N - 1; i >= 0; --i) {
            double s = z[i];
            for (int k = i + 1; k < N; ++k) s -= A[size_t(k) * N + i] * z[k];
            z[i] = s / A[size_t(i) * N + i];
        }
        for (int i = 0; i < N; ++i) out[i / n].values()[size_t(i % n) * C + c] = float(z[i]);
    }
    return out;
}

TemporalOptions l2_options(TemporalSolver solver = TemporalSolver::automatic) {
    TemporalOptions o;
    o.norm = TemporalNorm::l2;
    o.solver = solver;
    o.tolerance = 1e-7;
    o.cg_iterations = 1000;
    return o;
}

const Motion kShift{2.3f, -0.6f, 2, -1};  // rounds to (2, -1): tests the rounding too

}  // namespace

TEST_CASE("temporal: exact inputs give back the video by DCT, CG and IRLS", "[temporal]") {
    const int w = 24, h = 16, C = 3, F = 6;
    SECTION("no motion: the exact 3-D DCT solve") {
        const auto truth = truth_video(w, h, C, F, Motion{});
        const auto frames = exact_frames(truth, Motion{}, false);
        TemporalReport rep;
        const auto x = solve(frames, l2_options(), &rep);
        CHECK(rep.direct_solve);
        CHECK(rep.temporal_rows == (F - 1) * w * h);
        CHECK(rel_error(x, truth) < 1e-5);
        const auto xc = solve(frames, l2_options(TemporalSolver::cg), &rep);
        CHECK_FALSE(rep.direct_solve);
        CHECK(rel_error(xc, truth) < 1e-5);
        TemporalOptions l1;
        CHECK(rel_error(solve(frames, l1), truth) < 1e-5);
    }
    SECTION("translating motion: CG, and IRLS") {
        const auto truth = truth_video(w, h, C, F, kShift);
        const auto frames = exact_frames(truth, kShift, true);
        TemporalReport rep;
        const auto x = solve(frames, l2_options(), &rep);
        CHECK_FALSE(rep.direct_solve);
        // Rows whose motion leaves the image are dropped: 2 columns and 1 row per frame.
        CHECK(rep.temporal_rows == (F - 1) * (w - 2) * (h - 1));
        INFO("CG iterations " << rep.cg_iterations << ", residual " << rep.relative_residual);
        CHECK(rep.cg_iterations > 1);
        CHECK(rel_error(x, truth) < 1e-5);
        TemporalOptions mg = l2_options(TemporalSolver::cg);
        mg.l2_preconditioner = TemporalPreconditioner::frame_multigrid;
        CHECK(rel_error(solve(frames, mg), truth) < 1e-5);
        TemporalOptions l1;
        CHECK(rel_error(solve(frames, l1, &rep), truth) < 1e-5);
        CHECK(rep.irls_iterations == 20);
    }
}

TEST_CASE("temporal: exact inputs on tiny frames and one-frame windows", "[temporal]") {
    for (auto [w, h, F] : {std::tuple{1, 1, 3}, std::tuple{1, 9, 4}, std::tuple{9, 1, 4}, std::tuple{5, 4, 1}}) {
        const auto truth = truth_video(w, h, 2, F, Motion{});
        const auto frames = exact_frames(truth, Motion{}, false);
        INFO(w << "x" << h << ", " << F << " frames");
        CHECK(rel_error(solve(frames, l2_options()), truth) < 1e-5);
        CHECK(rel_error(solve(frames, l2_options(TemporalSolver::cg)), truth) < 1e-5);
        CHECK(rel_error(solve(frames, TemporalOptions{}), truth) < 1e-5);
    }
}

TEST_CASE("temporal: the 3-D DCT solve equals CG on the same motion-free problem", "[temporal]") {
    const int w = 31, h = 20, C = 3, F = 7;
    auto frames = exact_frames(truth_video(w, h, C, F, Motion{}), Motion{}, false);
    std::mt19937 rng(7);
    for (auto& f : frames) {
        add_noise(f.primal, 0.3f, rng), add_noise(f.dx, 0.1f, rng), add_noise(f.dy, 0.1f, rng);
        if (!f.dt.empty()) add_noise(f.dt, 0.1f, rng);
    }
    // CG preconditioned by something other than the DCT, so the two share no code but the operator's definition.
    for (double wt : {1.0, 3.0})
        for (auto pre : {TemporalPreconditioner::frame_multigrid, TemporalPreconditioner::none}) {
            TemporalOptions dct = l2_options(TemporalSolver::dct), cg = l2_options(TemporalSolver::cg);
            dct.w_t = cg.w_t = wt, dct.w_s = cg.w_s = 0.7;
            cg.l2_preconditioner = pre;
            TemporalReport rep;
            const auto a = solve(frames, dct, &rep);
            CHECK(rep.direct_solve);
            const auto b = solve(frames, cg, &rep);
            INFO("w_t " << wt << ", preconditioner " << int(pre) << ": CG iterations " << rep.cg_iterations
                        << ", residual " << rep.relative_residual);
            CHECK_FALSE(rep.direct_solve);
            CHECK(rep.relative_residual <= 1e-7);
            CHECK(rel_error(a, b) < 1e-5);
        }
}

TEST_CASE("temporal: CG with motion and a mask equals a dense solve of the energy", "[temporal]") {
    const int w = 7, h = 5, C = 2, F = 4;
    const auto truth = truth_video(w, h, C, F, kShift);
    auto frames = exact_frames(truth, kShift, true);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1.6f, 1.6f);
    for (auto& f : frames) {
        add_noise(f.primal, 0.3f, rng), add_noise(f.dx, 0.2f, rng), add_noise(f.dy, 0.2f, rng);
        if (f.dt.empty()) continue;
        add_noise(f.dt, 0.2f, rng);
        // Irregular motion (several pixels onto one) and a mask with junk where it is 0.
        f.valid = Image(w, h, 1, 1.f);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                f.motion.at(x, y, 0) = u(rng), f.motion.at(x, y, 1) = u(rng);
                if ((x * 3 + y) % 5 == 0) f.valid.at(x, y) = 0.f, f.dt.at(x, y, 0) = 1e6f;
            }
    }
    const auto ref = dense_solve(frames, 0.2, 0.8, 1.5);
    TemporalOptions o = l2_options(TemporalSolver::cg);
    o.w_s = 0.8, o.w_t = 1.5;
    for (auto pre : {TemporalPreconditioner::dct, TemporalPreconditioner::frame_multigrid, TemporalPreconditioner::none}) {
        o.l2_preconditioner = pre;
        TemporalReport rep;
        const auto x = solve(frames, o, &rep);
        INFO("preconditioner " << int(pre) << ": " << rep.cg_iterations << " iterations");
        CHECK(rel_error(x, ref) < 1e-5);
    }
}

TEST_CASE("temporal L1: IRLS ignores an outlier temporal difference and lowers the L1 energy", "[temporal]") {
    const int w = 20, h = 14, C = 3, F = 6;
    const auto truth = truth_video(w, h, C, F, kShift);
    auto frames = exact_frames(truth, kShift, true);
    for (int c = 0; c < C; ++c) frames[2].dt.at(9, 6, c) = 40.f;  // one firefly-like row
    const auto l2 = solve(frames, l2_options());
    TemporalOptions l1;
    const auto x1 = solve(frames, l1);
    const double e2 = rel_error(l2, truth), e1 = rel_error(x1, truth);
    INFO("max relative error: L2 " << e2 << ", L1 " << e1);
    // Measured: L2 4.2, L1 0.0044 (what 20 IRLS steps of 2 CG iterations from
    // the displaced L2 start leave).
    CHECK(e2 > 0.5);
    CHECK(e1 < 0.01);
    // On noisy inputs the IRLS result has a lower L1 energy than the L2 solution.
    std::mt19937 rng(9);
    for (auto& f : frames) {
        add_noise(f.primal, 0.3f, rng), add_noise(f.dx, 0.1f, rng), add_noise(f.dy, 0.1f, rng);
        if (!f.dt.empty()) add_noise(f.dt, 0.1f, rng);
    }
    const auto n2 = solve(frames, l2_options());
    TemporalReport rep;
    const auto n1 = solve(frames, l1, &rep);
    std::vector<const float*> p2, p1;
    for (int f = 0; f < F; ++f) p2.push_back(n2[f].data()), p1.push_back(n1[f].data());
    const double energy2 = temporal_energy(views(frames), l1, p2, TemporalNorm::l1);
    const double energy1 = temporal_energy(views(frames), l1, p1, TemporalNorm::l1);
    INFO("L1 energy of the L2 solution " << energy2 << ", of the IRLS result " << energy1);
    CHECK(energy1 == Approx(rep.energy).epsilon(1e-9));
    CHECK(energy1 < 0.97 * energy2);
}

TEST_CASE("temporal: L2 of noisy unbiased inputs is unbiased", "[temporal][statistical]") {
    // Truth from about -0.45 to 1.2, so that a biased variant (clamping negative
    // results at zero, as a renderer might) shows.
    const int w = 14, h = 10, C = 3, F = 5, runs = 200;
    const auto truth = truth_video(w, h, C, F, kShift, 0.05f, -0.5f);
    const auto exact = exact_frames(truth, kShift, true);
    const size_t per = truth[0].values().size();
    std::vector<double> sum(F * per, 0.0), sum2(F * per, 0.0);
    double run_sum = 0, run_sum2 = 0;  // of each run's mean error over all values
    for (int s = 0; s < runs; ++s) {
        std::mt19937 rng(1000 + s);
        auto frames = exact;
        for (auto& f : frames) {
            add_noise(f.primal, 0.3f, rng), add_noise(f.dx, 0.1f, rng), add_noise(f.dy, 0.1f, rng);
            if (!f.dt.empty()) add_noise(f.dt, 0.1f, rng);
        }
        const auto x = solve(frames, l2_options());
        double run_mean = 0;
        for (int f = 0; f < F; ++f)
            for (size_t i = 0; i < per; ++i) {
                const double e = double(x[f].values()[i]) - truth[f].values()[i];
                sum[f * per + i] += e, sum2[f * per + i] += e * e;
                run_mean += e / double(F * per);
            }
        run_sum += run_mean, run_sum2 += run_mean * run_mean;
    }
    // Per value a t-test of the mean error against 0; |t| > 5.5 has probability
    // below 1e-6 for 199 degrees of freedom, so below 0.3% over the 2100 values.
    double worst = 0;
    for (size_t k = 0; k < sum.size(); ++k) {
        const double m = sum[k] / runs, var = (sum2[k] - runs * m * m) / (runs - 1);
        worst = std::max(worst, std::abs(m) / std::sqrt(var / runs));
    }
    // And the mean error over the whole video, a t-test over the runs (|t| < 4).
    const double mean = run_sum / runs, sd = std::sqrt((run_sum2 - runs * mean * mean) / (runs - 1));
    const double t_all = mean / (sd / std::sqrt(double(runs)));
    INFO("largest per-value |t| " << worst << "; mean error " << mean << ", its t " << t_all);
    CHECK(worst < 5.5);
    CHECK(std::abs(t_all) < 4.0);
}

TEST_CASE("temporal: exact dt removes flicker that per-frame solves keep", "[temporal][statistical]") {
    const int w = 32, h = 24, C = 3, F = 8;
    const auto truth = truth_video(w, h, C, F, Motion{}, 0.08f);
    auto frames = exact_frames(truth, Motion{}, false);
    std::mt19937 rng(11);
    for (auto& f : frames) add_noise(f.primal, 0.3f, rng), add_noise(f.dx, 0.05f, rng), add_noise(f.dy, 0.05f, rng);
    TemporalOptions opt = l2_options();
    opt.window = F;
    const auto temporal = solve(frames, opt);
    std::vector<Image> single;
    for (const auto& f : frames) {
        Image o(w, h, C);
        const auto v = f.view();
        poisson_l2(PoissonProblem{v.primal, v.dx, v.dy, 0.2}, o.data());
        single.push_back(o);
    }
    // Temporal relMSE (as gdr compare --frames): the error of frame-to-frame
    // differences relative to the reference radiance of the pair.
    auto flicker = [&](const std::vector<Image>& x) {
        double s = 0;
        size_t count = 0;
        for (int f = 0; f + 1 < F; ++f)
            for (size_t i = 0; i < x[f].values().size(); ++i) {
                const double d = (x[f + 1].values()[i] - x[f].values()[i]) -
                                 (truth[f + 1].values()[i] - truth[f].values()[i]);
                const double r = 0.5 * (truth[f + 1].values()[i] + truth[f].values()[i]);
                s += d * d / (r * r + 0.01), ++count;
            }
        return s / double(count);
    };
    const double ft = flicker(temporal), fs = flicker(single);
    INFO("flicker relMSE: temporal " << ft << ", per-frame 2-D " << fs);
    CHECK(ft * 2 <= fs);
}

TEST_CASE("temporal windows: constant video stays constant across window boundaries", "[temporal][windows]") {
    const int w = 12, h = 9, C = 3, N = 23;
    std::vector<TemporalFrame> frames(N);
    for (int f = 0; f < N; ++f) {
        frames[f].name = "frame " + std::to_string(f);
        frames[f].primal = Image(w, h, C, 0.7f);
        frames[f].dx = Image(w, h, C), frames[f].dy = Image(w, h, C);
        if (f + 1 < N) frames[f].dt = Image(w, h, C);
    }
    for (TemporalNorm norm : {TemporalNorm::l1, TemporalNorm::l2}) {
        TemporalOptions o;
        o.norm = norm;
        const auto out = stream(frames, o);
        REQUIRE(out.size() == size_t(N));
        double worst = 0;
        for (const auto& img : out)
            for (float v : img.values()) worst = std::max(worst, std::abs(double(v) - 0.7));
        CHECK(worst < 1e-5);
    }
}

TEST_CASE("temporal windows: a brightening video through windows equals the one-window solve", "[temporal][windows]") {
    const int w = 16, h = 12, C = 3;
    for (int N : {27, 13, 7}) {  // several windows with a short last one; one window
        const auto truth = truth_video(w, h, C, N, kShift, 0.04f);
        const auto frames = exact_frames(truth, kShift, true);
        for (TemporalNorm norm : {TemporalNorm::l2, TemporalNorm::l1}) {
            TemporalOptions o = l2_options();
            o.norm = norm;
            const auto windowed = stream(frames, o);
            TemporalOptions one = o;
            one.window = one.step = N;
            const auto whole = solve(frames, one);
            INFO("N " << N << " norm " << int(norm));
            REQUIRE(windowed.size() == size_t(N));
            CHECK(rel_error(windowed, whole) < 1e-5);
            CHECK(rel_error(windowed, truth) < 1e-5);
        }
    }
}

TEST_CASE("temporal windows: the blend leaves no seam in a noisy video", "[temporal][windows]") {
    // Exact gradients and dt, noisy primal: within a window the frame
    // differences are exact and only the window's mean primal noise is left,
    // which changes from window to window. Hann blending spreads that change
    // over the overlap; windows that merely abut (step = window) jump at the
    // boundary. Measured per consecutive pair: the RMS error of the frame
    // difference x[f+1] - x[f] against the truth's.
    const int w = 16, h = 12, C = 3, N = 30;
    const auto truth = truth_video(w, h, C, N, Motion{}, 0.04f);
    auto frames = exact_frames(truth, Motion{}, false);
    std::mt19937 rng(5);
    for (auto& f : frames) add_noise(f.primal, 0.3f, rng);
    auto pair_errors = [&](int window, int step) {
        TemporalOptions o = l2_options();
        o.window = window, o.step = step;
        const auto x = stream(frames, o);
        std::vector<double> e;
        for (int f = 0; f + 1 < N; ++f) {
            double s = 0;
            for (size_t i = 0; i < x[f].values().size(); ++i)
                s += std::pow((x[f + 1].values()[i] - x[f].values()[i]) - (truth[f + 1].values()[i] - truth[f].values()[i]), 2);
            e.push_back(std::sqrt(s / double(x[f].values().size())));
        }
        return e;
    };
    const auto blended = pair_errors(10, 5), abutting = pair_errors(10, 10);
    const double worst_blended = *std::max_element(blended.begin(), blended.end());
    const double seam = std::max({abutting[9], abutting[19]});  // pairs (9, 10) and (19, 20)
    double inside = 0;
    for (int f = 0; f + 1 < N; ++f)
        if (f != 9 && f != 19) inside = std::max(inside, abutting[f]);
    INFO("largest pair error: blended " << worst_blended << "; abutting windows: " << seam << " at the boundaries, "
                                        << inside << " elsewhere");
    // The abutting windows show the seam the measure is made to catch (measured
    // 4.5 times the pairs inside a window) ...
    CHECK(seam > 3 * inside);
    // ... and with the blend no pair is worse than 1.5 times the pairs inside
    // one window (measured 1.15).
    CHECK(worst_blended < 1.5 * inside);
}

TEST_CASE("temporal windows: outputs depend only on their windows and at most W frames are held", "[temporal][windows]") {
    const int w = 10, h = 8, C = 3, N = 20;  // windows [0,10), [5,15), [10,20)
    const auto truth = truth_video(w, h, C, N, kShift);
    const auto frames = exact_frames(truth, kShift, true);
    TemporalOptions o;  // L1, W = 10, S = 5
    int held = 0, blends = 0;
    const auto base = stream(frames, o, &held, &blends);
    CHECK(held <= o.window);
    CHECK(blends <= o.window);
    auto changed = [&](int frame) {
        auto f2 = frames;
        for (auto& v : f2[frame].primal.values()) v += 0.5f;
        const auto out = stream(f2, o);
        std::vector<bool> diff(N);
        for (int f = 0; f < N; ++f) diff[f] = out[f].values() != base[f].values();
        return diff;
    };
    const auto late = changed(17);  // in window [10,20) only
    for (int f = 0; f < 10; ++f) CHECK_FALSE(late[f]);
    for (int f = 10; f < 20; ++f) CHECK(late[f]);
    const auto early = changed(3);  // in window [0,10) only
    for (int f = 0; f < 10; ++f) CHECK(early[f]);
    for (int f = 10; f < 20; ++f) CHECK_FALSE(early[f]);
    // Finished frames come out as soon as no later window covers them.
    TemporalReconstructor rec(o);
    for (int f = 0; f < 9; ++f) rec.push(frames[f]);
    CHECK_FALSE(rec.ready());
    rec.push(frames[9]);
    int ready = 0;
    while (rec.ready()) rec.pop(), ++ready;
    CHECK(ready == 5);
    CHECK(rec.held_frames() == 5);
}

TEST_CASE("temporal: bad input names the frame, the layer and the pixel", "[temporal][errors]") {
    const int w = 8, h = 6, C = 3;
    const auto truth = truth_video(w, h, C, 3, Motion{});
    const auto frames = exact_frames(truth, Motion{}, false);
    auto message = [](auto&& fn) {
        try {
            fn();
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    using Catch::Matchers::Contains;
    // A frame buffer without dx.
    FrameBuffer fb(w, h);
    fb.set("primal", truth[0]);
    fb.set("dy", frames[0].dy);
    CHECK_THROWS_AS(temporal_frame(fb, "in.0003.exr"), InputError);
    const std::string m1 = message([&] { temporal_frame(fb, "in.0003.exr"); });
    CHECK_THAT(m1, Contains("in.0003.exr") && Contains("'dx'"));
    // dt missing on a frame that is followed by another.
    {
        TemporalReconstructor rec;
        auto f0 = frames[0];
        f0.dt = Image();
        rec.push(f0);
        const std::string m = message([&] { rec.push(frames[1]); });
        CHECK_THAT(m, Contains("frame 0") && Contains("'dt'") && Contains("frame 1"));
        // ... but a last frame without dt is fine.
        TemporalReconstructor ok;
        ok.push(frames[0]), ok.push(frames[1]), ok.push(frames[2]);
        ok.finish();
        CHECK(ok.ready());
    }
    // Mismatched sizes: within a frame and between frames.
    {
        auto f = frames[0];
        f.dt = Image(w, h + 1, C);
        CHECK_THAT(message([&] { check_temporal_frame(f); }), Contains("frame 0") && Contains("'dt'") && Contains("8x7x3"));
        f = frames[0];
        f.motion = Image(w, h, 3);
        CHECK_THAT(message([&] { check_temporal_frame(f); }), Contains("'motion_fwd'") && Contains("8x6x2"));
        TemporalReconstructor rec;
        rec.push(frames[0]);
        auto big = frames[1];
        big.primal = Image(w + 1, h, C), big.dx = big.primal, big.dy = big.primal, big.dt = big.primal;
        big.name = "b.exr";
        CHECK_THAT(message([&] { rec.push(big); }), Contains("b.exr") && Contains("frame 0") && Contains("9x6x3"));
    }
    // NaN in dt, in the motion, in the primal.
    {
        auto f = frames[0];
        f.dt.at(3, 2, 1) = std::nanf("");
        CHECK_THROWS_AS(check_temporal_frame(f), InputError);
        CHECK_THAT(message([&] { check_temporal_frame(f); }), Contains("frame 0") && Contains("'dt'") && Contains("(3, 2)"));
        f = frames[0];
        f.motion = Image(w, h, 2);
        f.motion.at(5, 1, 0) = INFINITY;
        CHECK_THAT(message([&] { check_temporal_frame(f); }), Contains("'motion_fwd'") && Contains("(5, 1)"));
        TemporalReconstructor rec;
        f = frames[0];
        f.primal.at(0, 4, 2) = std::nanf("");
        CHECK_THAT(message([&] { rec.push(f); }), Contains("'primal'") && Contains("(0, 4)"));
    }
    // Options.
    TemporalOptions bad;
    bad.step = 11;
    CHECK_THROWS_AS(TemporalReconstructor(bad), ParameterError);
    Params p("--set");
    p.set("windw", 4LL);
    CHECK_THAT(message([&] { temporal_options(p); }), Contains("windw"));
}

TEST_CASE("temporal options round-trip through parameters", "[temporal]") {
    TemporalOptions o;
    o.alpha = 0.3, o.w_t = 2.5, o.norm = TemporalNorm::l2, o.solver = TemporalSolver::cg;
    o.l2_preconditioner = TemporalPreconditioner::none, o.irls_preconditioner = TemporalPreconditioner::dct;
    o.window = 8, o.step = 3, o.require_dt = false, o.eps_factor = 0.25;
    Params p("header");
    std::string text = describe(o);
    for (size_t at = 0; at < text.size();) {
        const size_t end = text.find('\n', at);
        p.set_from_text(text.substr(at, end - at));
        at = end + 1;
    }
    CHECK(describe(temporal_options(p)) == text);
    CHECK(describe(temporal_options(Params())) == describe(TemporalOptions{}));
}

TEST_CASE("temporal: frame files are read, reconstructed and written, never over an input", "[temporal][files]") {
    namespace fs = std::filesystem;
    const fs::path dir = fs::temp_directory_path() / ("gdr-temporal-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const int w = 10, h = 7, C = 3, N = 8;
    const std::string in = (dir / "in.%04d.exr").string(), out = (dir / "out.%04d.exr").string();
    const auto truth = truth_video(w, h, C, N, kShift);
    auto frames = exact_frames(truth, kShift, true);
    std::mt19937 rng(2);
    for (int f = 0; f < N; ++f) {
        add_noise(frames[f].primal, 0.2f, rng);
        frames[f].direct = Image(w, h, C, 0.f);
        frames[f].direct.at(1, 1, 0) = 5.f;
        FrameBuffer fb(w, h);
        fb.set("primal", frames[f].primal), fb.set("dx", frames[f].dx), fb.set("dy", frames[f].dy);
        fb.set("direct", frames[f].direct);
        if (!frames[f].dt.empty()) fb.set("dt", frames[f].dt), fb.set("motion_fwd", frames[f].motion);
        write_exr(frame_path(in, 1000 + f), fb);
    }
    CHECK(frame_path(in, 1003) == (dir / "in.1003.exr").string());
    CHECK(frame_path("a%%b.%d.exr", 7) == "a%b.7.exr");
    CHECK_THROWS_AS(frame_path("a.exr", 1), ParameterError);
    CHECK_THROWS_AS(frame_path("a.%d.%d.exr", 1), ParameterError);
    TemporalOptions o;
    o.window = 4, o.step = 2;
    const auto rep = reconstruct_frame_sequence(in, 1000, 1007, out, o);
    CHECK(rep.frames == N);
    CHECK(rep.windows.size() == 3);  // [0,4), [2,6), [4,8)
    const auto expected = stream(frames, o);
    for (int f = 0; f < N; ++f) {
        const FrameBuffer r = read_exr(frame_path(out, 1000 + f));
        CHECK(r.get("color").values() == expected[f].values());
        CHECK(r.metadata().at("frame") == std::to_string(1000 + f));
        CHECK(r.get("color").at(1, 1, 0) > 4.f);  // direct added
    }
    // Never over an input; missing files and layers are named.
    CHECK_THROWS_AS(reconstruct_frame_sequence(in, 1000, 1007, in, o), ParameterError);
    const std::string missing = (dir / "in.1008.exr").string();
    try {
        reconstruct_frame_sequence(in, 1000, 1008, out, o);
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK_THAT(e.what(), Catch::Matchers::Contains(missing));
    }
    FrameBuffer no_dt(w, h);
    no_dt.set("primal", frames[0].primal), no_dt.set("dx", frames[0].dx), no_dt.set("dy", frames[0].dy);
    write_exr((dir / "in.1003.exr").string(), no_dt);
    try {
        reconstruct_frame_sequence(in, 1000, 1007, out, o);
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK_THAT(e.what(), Catch::Matchers::Contains("in.1003.exr") && Catch::Matchers::Contains("'dt'"));
    }
    fs::remove_all(dir);
}
