// Screened Poisson reconstruction at 1280x720 RGB: L2 and L1 wall time against
// the bound (a bare DCT solve) and the reference's CPU method (50 plain CG
// iterations, "L2D"), all measured in one run (medians of several repetitions),
// plus the default L1's energy gap to a converged L1 and, on the reference's
// own 512x512 buffers, the relMSE of poisson-l2 against its L2 output. Where
// the neural reconstructor's plugin is built, its inference time at the same
// size too (the shipped model; albedo, normal and depth are constant
// stand-ins, which change no operation count: the network is convolutions).
//
// Input: the reference cbox buffers tiled periodically to 1280x720 (real
// Monte Carlo noise; the seams act as edges), or a synthetic noisy image if
// the shared reference outputs are absent.
//
// Usage: bench_reconstruct [--reps N] [--with-reference] [--no-neural] [--frame FILE.exr]
//   --with-reference  also runs the reference's own L1 preset (20 IRLS x 50
//                     plain CG from the primal; ~15 CPU-seconds) for its energy.
//   --no-neural       leaves the neural reconstructor's timing out.
//   --frame FILE.exr  instead: a render's own layers (e.g. `gdr render ... --integrator
//                     gpt --set reconstruct=none`, with its variance and feature
//                     layers) timed with poisson-l1, poisson-weighted and the
//                     neural reconstructor, against the 2 s budget of a 1280x720
//                     frame scaled to the frame's pixel count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <tbb/info.h>

#include "gdr/io/reconstruct_files.h"
#include "gdr/core/args.h"
#include "gdr/plugin.h"
#include "gdr/io/exr.h"
#include "gdr/reconstruct/poisson.h"
#include "gdr/reconstruct/reconstructor.h"
#include "run_stats.h"

using namespace gdr;

namespace {

struct Timing {
    double wall = 0, cpu = 0;  // medians, seconds
};

/// Median wall and process-CPU seconds of `reps` runs of f.
Timing measure(int reps, const std::function<void()>& f) {
    std::vector<double> wall, cpu;
    for (int i = 0; i < reps; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const std::clock_t c0 = std::clock();
        f();
        cpu.push_back(double(std::clock() - c0) / CLOCKS_PER_SEC);
        wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(wall.begin(), wall.end()), std::sort(cpu.begin(), cpu.end());
    return {wall[wall.size() / 2], cpu[cpu.size() / 2]};
}

GradientFrame tiled(const GradientFrame& src, int w, int h) {
    auto tile = [&](const Image& in) {
        Image out(w, h, in.channels());
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < in.channels(); ++c) out.at(x, y, c) = in.at(x % in.width(), y % in.height(), c);
        return out;
    };
    GradientFrame f;
    f.primal = tile(src.primal), f.dx = tile(src.dx), f.dy = tile(src.dy);
    if (!src.direct.empty()) f.direct = tile(src.direct);
    return f;
}

GradientFrame synthetic(int w, int h) {
    std::mt19937 rng(7);
    std::normal_distribution<float> noise(0.f, 1.f);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    Image truth(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c)
                truth.at(x, y, c) = 0.4f + 0.3f * std::sin(0.02f * x * (c + 1) + 0.013f * y) +
                                    ((x / 160 + y / 120) % 2 ? 0.5f : 0.f);
    GradientFrame f;
    f.primal = truth, f.dx = Image(w, h, 3), f.dy = Image(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                // Heavy-tailed like Monte Carlo noise: mostly small, now and then a firefly.
                auto mc = [&](float s) { return s * noise(rng) + (u(rng) < 0.002f ? 20.f * u(rng) : 0.f); };
                f.primal.at(x, y, c) += mc(0.3f);
                if (x + 1 < w) f.dx.at(x, y, c) = truth.at(x + 1, y, c) - truth.at(x, y, c) + mc(0.1f);
                if (y + 1 < h) f.dy.at(x, y, c) = truth.at(x, y + 1, c) - truth.at(x, y, c) + mc(0.1f);
            }
    return f;
}

double relmse(const Image& x, const Image& r) {
    double s = 0;
    for (size_t i = 0; i < x.values().size(); ++i) {
        const double d = double(x.values()[i]) - r.values()[i];
        s += d * d / (double(r.values()[i]) * r.values()[i] + 0.01);
    }
    return s / double(x.values().size());
}

PoissonProblem problem_of(const GradientFrame& f, double alpha) {
    auto v = [](const Image& i) { return ImageView{i.data(), i.width(), i.height(), i.channels()}; };
    return PoissonProblem{v(f.primal), v(f.dx), v(f.dy), alpha};
}

/// Prints the 1-minute load average where /proc has it: other processes on
/// the machine change wall times a lot, so each run says how busy it was.
void print_load_average() {
    if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
        double l1 = 0;
        if (std::fscanf(f, "%lf", &l1) == 1) std::printf("load average (1 min) at start: %.2f\n", l1);
        std::fclose(f);
    }
}

/// Loads the plugins of the build tree (or GDR_PLUGIN_PATH); "" if the neural
/// reconstructor is there, else why not.
std::string load_neural_plugin() {
    // libtorch's OpenMP threads wait passively, as the gdr tool sets them.
    setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
    const PluginLoad plugin = load_plugins_from(plugin_path_dirs({GDR_PLUGIN_BUILD_DIR}));
    if (reconstructor_registry().has("neural")) return "";
    std::string why = "its plugin is not built (it needs libtorch)";
    for (const auto& [file, reason] : plugin.skipped) why = file + ": " + reason;
    return why;
}

/// --frame: the reconstructions of one real render, timed in one process.
int run_frame(const std::string& path, int reps, bool with_neural) {
    const FrameBuffer fb = read_exr(path);
    const GradientBuffers in = gradient_buffers(fb);
    const int W = fb.width(), H = fb.height();
    const double budget = 2.0 * double(W) * H / (1280.0 * 720.0);
    std::printf("reconstruction of a render's own layers: %s (%dx%d)\n", path.c_str(), W, H);
    std::printf("threads: %d (TBB default concurrency); times: median of %d runs after one untimed, wall (process CPU)\n",
                tbb::info::default_concurrency(), reps);
    print_load_average();
    std::vector<std::string> methods = {"poisson-l1", "poisson-weighted"};
    if (with_neural) {
        const std::string why = load_neural_plugin();
        if (why.empty()) methods.push_back("neural");
        else std::printf("neural: not measured: %s\n", why.c_str());
    }
    std::printf("\ntimes\n");
    for (const std::string& m : methods) {
        const auto r = reconstructor_registry().create(m, Params("bench_reconstruct"));
        (void)r->reconstruct(in);  // one-time set-up (plans, libtorch's kernels) out of the timing
        const Timing t = measure(reps, [&] { (void)r->reconstruct(in); });
        std::string params = r->describe();
        for (char& c : params) c = c == '\n' ? ' ' : c;
        std::printf("  %-18s %8.1f ms  (%8.1f ms CPU)  %s\n", m.c_str(), t.wall * 1e3, t.cpu * 1e3,
                    m == "neural" ? params.c_str() : "");
        if (m == "neural")
            std::printf("\nratios\n  neural / %.2f s budget (2 s per 1280x720)  %8.2f   (target <= 1)\n", budget,
                        t.wall / budget);
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    int reps = 5;
    bool with_reference = false, with_neural = true;
    std::string frame_file;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--reps") && i + 1 < argc) {
            try {
                reps = int(gdr::ArgReader::parse_int("--reps", argv[++i], 1, 10000));
            } catch (const std::exception& e) {
                std::fprintf(stderr, "bench_reconstruct: error: %s\n", e.what());
                return 2;
            }
        }
        else if (!std::strcmp(argv[i], "--with-reference")) with_reference = true;
        else if (!std::strcmp(argv[i], "--no-neural")) with_neural = false;
        else if (!std::strcmp(argv[i], "--frame") && i + 1 < argc) frame_file = argv[++i];
        else {
            std::fprintf(stderr, "usage: %s [--reps N] [--with-reference] [--no-neural] [--frame FILE.exr]\n", argv[0]);
            return 2;
        }
    }
    std::printf("machine: %s\n", gdr::bench::machine_description().c_str());
    if (!frame_file.empty()) {
        try {
            return run_frame(frame_file, reps, with_neural);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "bench_reconstruct: error: %s\n", e.what());
            return 1;
        }
    }
    const int W = 1280, H = 720;
    const std::string ref_dir = std::string(GDR_SHARED_DIR) + "/reference-outputs/mitsuba-gpt-cbox-16spp";
    const bool have_ref = std::filesystem::exists(ref_dir + "/cbox-final.exr");
    GradientFrame cbox;
    if (have_ref) cbox = load_reference_layout(ref_dir + "/cbox");
    const GradientFrame frame = have_ref ? tiled(cbox, W, H) : synthetic(W, H);
    const GradientBuffers in = frame.buffers();
    const PoissonProblem prob = problem_of(frame, 0.2);

    std::printf("screened Poisson reconstruction benchmark, %dx%d RGB, alpha 0.2, input: %s\n", W, H,
                have_ref ? "reference cbox buffers tiled" : "synthetic (reference outputs not found)");
    std::printf("threads: %d (TBB default concurrency); times: median of %d runs, wall (process CPU)\n",
                tbb::info::default_concurrency(), reps);
    print_load_average();

    // The bound: one DCT solve of 3 planar channels (plans already cached).
    DctSolver dct(W, H);
    std::vector<float> rhs(size_t(W) * H * 3), sol(rhs.size());
    for (size_t i = 0; i < rhs.size(); ++i) rhs[i] = frame.primal.values()[i];
    dct.solve(rhs.data(), sol.data(), 3, 0.04, 1.0);
    const Timing t_dct = measure(reps, [&] { dct.solve(rhs.data(), sol.data(), 3, 0.04, 1.0); });

    Image l2;
    const Timing t_l2 = measure(reps, [&] { l2 = reconstruct("poisson-l2", Params(), in); });

    std::vector<float> cg(frame.primal.values());
    CgOptions l2d;
    l2d.max_iterations = 50, l2d.preconditioner = Preconditioner::none;
    const Timing t_l2d = measure(reps, [&] {
        cg = frame.primal.values();
        poisson_weighted(prob, nullptr, l2d, cg.data());
    });
    Image l2_only(W, H, 3);
    poisson_l2(prob, l2_only.data());
    Image cg_img(W, H, 3);
    cg_img.values() = cg;

    const L1Options def;
    Image l1;
    const Timing t_l1 = measure(reps, [&] { l1 = reconstruct("poisson-l1", Params(), in); });
    Image l1_only(W, H, 3);
    const L1Report rep_def = poisson_l1(prob, def, l1_only.data());

    L1Options conv;
    conv.iterations = 40, conv.cg_iterations = 30, conv.tolerance = 1e-4;
    Image l1_conv(W, H, 3);
    const std::clock_t c0 = std::clock();
    const L1Report rep_conv = poisson_l1(prob, conv, l1_conv.data());
    const double conv_cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;

    // The neural reconstructor, where its plugin is built (the build tree's,
    // unless GDR_PLUGIN_PATH says otherwise).
    std::string neural_note = "not measured (--no-neural)";
    Timing t_neural;
    if (with_neural) {
        const std::string why_not = load_neural_plugin();
        if (why_not.empty()) {
            const auto net = reconstructor_registry().create("neural", Params("bench_reconstruct"));
            FrameBuffer fb(W, H);
            fb.set("primal", frame.primal), fb.set("dx", frame.dx), fb.set("dy", frame.dy);
            fb.add("albedo", 3).values().assign(size_t(W) * H * 3, 0.5f);
            Image& normal = fb.add("normal", 3);
            for (size_t i = 2; i < normal.values().size(); i += 3) normal.values()[i] = 1.f;
            fb.add("depth", 1).values().assign(size_t(W) * H, 1.f);
            // The shipped model reads poisson-weighted's solve: stand-in
            // variances of 16-sample means (they change its iterations, not
            // its operations per iteration).
            for (const char* v : {"primal_variance", "dx_variance", "dy_variance"})
                fb.add(v, 3).values().assign(size_t(W) * H * 3, 0.05f);
            fb.add("spp", 1).values().assign(size_t(W) * H, 16.f);
            const GradientBuffers nb = gradient_buffers(fb);
            (void)net->reconstruct(nb);  // the first run includes torch's one-time set-up
            t_neural = measure(reps, [&] { (void)net->reconstruct(nb); });
            std::string params = net->describe();
            for (char& c : params) c = c == '\n' ? ' ' : c;
            neural_note = "measured: " + params;
        } else {
            neural_note = "not measured: " + why_not;
        }
    }

    auto line = [](const char* what, const Timing& t) {
        std::printf("  %-44s %8.1f ms  (%8.1f ms CPU)\n", what, t.wall * 1e3, t.cpu * 1e3);
    };
    std::printf("\ntimes\n");
    line("bare DCT solve (bound)", t_dct);
    line("poisson-l2 (checks, rhs, DCT, + direct)", t_l2);
    line("reference L2D: 50 plain CG iterations", t_l2d);
    line("poisson-l1 default", t_l1);
    if (t_neural.wall > 0) line("neural (U-Net, libtorch)", t_neural);
    std::printf("  neural: %s\n", neural_note.c_str());
    std::printf("\nratios\n");
    std::printf("  poisson-l2 / bare DCT solve              %8.2f   (target <= 2)\n", t_l2.wall / t_dct.wall);
    std::printf("  L2D (50 CG) / poisson-l2                 %8.2f\n", t_l2d.wall / t_l2.wall);
    std::printf("  poisson-l1 default / 1.5 s budget        %8.2f   (target <= 1)\n", t_l1.wall / 1.5);
    std::printf("\nquality\n");
    std::printf("  L2D vs exact L2: relMSE %.3e, L2 energy gap %.3e\n", relmse(cg_img, l2_only),
                poisson_energy_l2(prob, cg.data()) / poisson_energy_l2(prob, l2_only.data()) - 1);
    std::printf("  L1 energy: L2 solution %.6g, default %.6g (%d IRLS, %d CG), converged %.6g (%d IRLS, %d CG, %.1f s CPU)\n",
                poisson_energy_l1(prob, l2_only.data()), rep_def.energy, rep_def.irls_iterations,
                rep_def.cg_iterations, rep_conv.energy, rep_conv.irls_iterations, rep_conv.cg_iterations, conv_cpu);
    std::printf("  default L1 energy gap to converged       %.3e   (target <= 1e-2)\n",
                rep_def.energy / rep_conv.energy - 1);
    std::printf("  relMSE default L1 vs converged L1        %.3e\n", relmse(l1_only, l1_conv));
    {
        // Why multigrid: the same IRLS x CG budget with the constant-weight DCT solve as preconditioner.
        L1Options with_dct = def;
        with_dct.preconditioner = Preconditioner::dct;
        Image l1_dct(W, H, 3);
        const L1Report rd = poisson_l1(prob, with_dct, l1_dct.data());
        std::printf("  same budget, DCT preconditioner: gap    %.3e   (multigrid above)\n", rd.energy / rep_conv.energy - 1);
    }
    if (with_reference) {
        L1Options ref;
        ref.iterations = 20, ref.cg_iterations = 50, ref.tolerance = 0;
        ref.exact_l2_start = false, ref.preconditioner = Preconditioner::none;
        Image l1_ref(W, H, 3);
        const auto t0 = std::chrono::steady_clock::now();
        const L1Report rr = poisson_l1(prob, ref, l1_ref.data());
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("  reference L1D preset (20 x 50 plain CG): %.1f s, energy gap %.3e, relMSE default vs it %.3e\n", s,
                    rr.energy / rep_conv.energy - 1, relmse(l1_only, l1_ref));
    }
    if (have_ref) {
        const Image final_ref = read_exr_rgb(ref_dir + "/cbox-final.exr");
        const Image mine = reconstruct("poisson-l2", Params(), cbox.buffers());
        std::printf("  poisson-l2 vs the reference's cbox-final.exr (512x512): relMSE %.3e (eps 0.01, per channel)\n",
                    relmse(mine, final_ref));
    }
    return 0;
}
