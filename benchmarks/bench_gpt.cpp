// G-PT cost and gradient noise against PT, and G-BDPT's cost against BDPT,
// measured in one run.
//  0. Peak memory of a 2048x2048 G-PT render (1 spp, the default
//     reconstructions), in a child process of its own, in bytes per pixel.
//  1. Cost of one G-PT sample relative to one PT sample (medians of interleaved
//     runs), in wall-clock time and in process CPU time (user + system, all
//     threads): on a shared virtual machine other guests inflate the first.
//     Whole renders include per-render fixed costs (allocating and zeroing the
//     accumulators, ~70 MB for G-PT at 512x512, and finalisation); the
//     marginal cost differences a short and a long render of each method so
//     that only the cost of the extra samples remains; the sampling cost takes
//     the process CPU time between the first and the last finished tile of the
//     long renders, which leaves out set-up and finalisation without
//     differencing two noisy figures.
//  2. Variance of the sampled gradients dx against the variance of finite
//     differences of the PT image, both at equal time (per-sample variances
//     scaled by the samples each method affords in the same time).
//  3. The same cost figures for a G-BDPT sample relative to a BDPT sample.
// Usage: bench_gpt [SCENE.json] [repeats]
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "gdr/core/args.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"
#include "run_stats.h"

using namespace gdr;

namespace {

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

// "q1-q3" of the runs, as printed.
std::string quartile_range(const std::vector<double>& v) {
    const auto [q1, q3] = bench::quartiles(v);
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f-%.2f", q1, q3);
    return buf;
}

double grey(const Image& img, int x, int y) {
    const Color c = img.rgb(x, y);
    return (double(c.r) + c.g + c.b) / 3.0;
}

}  // namespace

int run(const std::string& path, int repeats);
void peak_memory(const std::string& path);

int main(int argc, char** argv) {
    try {
        if (argc > 3 || (argc > 1 && (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help"))) {
            std::printf("usage: bench_gpt [SCENE.json] [repeats]\n");
            return argc > 3 ? 1 : 0;
        }
        const std::string path = argc > 1 ? argv[1] : GDR_SOURCE_DIR "/scenes/cornell-box/scene.json";
        int repeats = 3;
        if (argc > 2) repeats = int(ArgReader::parse_int("repeats", argv[2], 1, 10000));
        std::printf("machine: %s\n", bench::machine_description().c_str());
        // First, while this process has started no threads: a child forked
        // from a process with running TBB workers could not start its own.
        peak_memory(path);
        return run(path, repeats);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_gpt: error: %s\n", e.what());
        return 1;
    }
}

int run(const std::string& path, int repeats) {
    const SceneFile sf = load_scene_file(path);
    const Scene& scene = *sf.scene;
    auto pt = integrator_registry().create("pt", Params());
    // Sample cost only: the reconstructions are timed by bench_reconstruct.
    Params gp;
    gp.set("reconstruct", std::string("none"));
    auto gpt = integrator_registry().create("gpt", gp);
    std::vector<double> pt_rate, gpt_rate, cpu_cost, marginal_wall, marginal_cpu, sampling_cpu;
    FrameBuffer pt_fb, gpt_fb, scratch;
    // A render with its wall-clock figures, the CPU seconds it used, and the
    // CPU seconds per sample while it was sampling.
    struct Timed {
        RenderStats stats;
        double cpu = 0.0;
        double sampling_cpu_per_sample = 0.0;
    };
    const auto timed = [&](Integrator& integ, long long spp, uint64_t seed, FrameBuffer& fb) {
        RenderSettings st;
        st.spp = spp;
        st.seed = seed;
        // Process CPU time at the first and the last finished tile: what lies
        // between is sampling only, without the render's set-up and finalisation.
        std::mutex m;
        double cpu_first = -1.0, cpu_last = 0.0;
        uint64_t samples_first = 0, samples_last = 0;
        const auto progress = [&](const Progress& p) {
            const double c = bench::cpu_seconds();
            std::lock_guard<std::mutex> lock(m);
            if (cpu_first < 0.0) cpu_first = c, samples_first = p.samples;
            if (p.samples > samples_last) cpu_last = c, samples_last = p.samples;
        };
        const double c0 = bench::cpu_seconds();
        Timed t;
        t.stats = integ.render(scene, st, fb, progress);
        t.cpu = bench::cpu_seconds() - c0;
        if (samples_last > samples_first)
            t.sampling_cpu_per_sample = (cpu_last - cpu_first) / double(samples_last - samples_first);
        return t;
    };
    for (int r = 0; r < repeats; ++r) {
        // Short renders for the marginal cost (PT 8 spp, G-PT 3 spp), then renders
        // long enough that per-render fixed costs (buffers, finalisation) fade.
        const Timed pa = timed(*pt, 8, uint64_t(r), scratch), ga = timed(*gpt, 3, uint64_t(r), scratch);
        const Timed ta = timed(*pt, 32, uint64_t(r), pt_fb), tb = timed(*gpt, 12, uint64_t(r), gpt_fb);
        const RenderStats &a = ta.stats, &b = tb.stats;
        pt_rate.push_back(double(a.samples) / a.seconds);
        gpt_rate.push_back(double(b.samples) / b.seconds);
        cpu_cost.push_back((tb.cpu / double(b.samples)) / (ta.cpu / double(a.samples)));
        const double pt_extra = double(a.samples - pa.stats.samples), gpt_extra = double(b.samples - ga.stats.samples);
        marginal_wall.push_back(((b.seconds - ga.stats.seconds) / gpt_extra) / ((a.seconds - pa.stats.seconds) / pt_extra));
        marginal_cpu.push_back(((tb.cpu - ga.cpu) / gpt_extra) / ((ta.cpu - pa.cpu) / pt_extra));
        sampling_cpu.push_back(tb.sampling_cpu_per_sample / ta.sampling_cpu_per_sample);
        std::printf("run %d: pt %.3f M samples/s (%.2f M rays/s), gpt %.3f M samples/s (%.2f M rays/s), "
                    "CPU time per sample gpt/pt %.2f, marginal %.2f wall %.2f CPU, sampling %.2f CPU\n",
                    r, pt_rate.back() * 1e-6, double(a.rays) / a.seconds * 1e-6, gpt_rate.back() * 1e-6,
                    double(b.rays) / b.seconds * 1e-6, cpu_cost.back(), marginal_wall.back(), marginal_cpu.back(),
                    sampling_cpu.back());
    }
    const double cost = median(pt_rate) / median(gpt_rate);
    std::printf("\n%s (%dx%d)\n", path.c_str(), scene.camera().width(), scene.camera().height());
    std::printf("median PT  : %.3f M samples/s\n", median(pt_rate) * 1e-6);
    std::printf("median G-PT: %.3f M samples/s\n", median(gpt_rate) * 1e-6);
    std::printf("cost of a G-PT sample / a PT sample: %.2fx wall-clock, %.2fx CPU time (medians of %d interleaved runs)\n",
                cost, median(cpu_cost), repeats);
    std::printf("marginal cost of a sample, per-render fixed costs differenced out: %.2fx wall-clock, %.2fx CPU time\n",
                median(marginal_wall), median(marginal_cpu));
    std::printf("while sampling (CPU time from the first to the last finished tile of the long renders): %.2fx\n",
                median(sampling_cpu));
    std::printf("quartiles of the runs: whole renders %s CPU time, marginal %s CPU time, sampling %s CPU time\n",
                quartile_range(cpu_cost).c_str(), quartile_range(marginal_cpu).c_str(),
                quartile_range(sampling_cpu).c_str());

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

    // G-BDPT against BDPT: the same interleaved short and long renders (fewer
    // samples: both cost several PT samples each).
    auto bdpt = integrator_registry().create("bdpt", Params());
    auto gbdpt = integrator_registry().create("gbdpt", gp);
    std::vector<double> g_cpu, g_marginal, g_sampling;
    for (int r = 0; r < repeats; ++r) {
        const Timed pa = timed(*bdpt, 2, uint64_t(r), scratch), ga = timed(*gbdpt, 1, uint64_t(r), scratch);
        const Timed ta = timed(*bdpt, 8, uint64_t(r), scratch), tb = timed(*gbdpt, 4, uint64_t(r), scratch);
        g_cpu.push_back((tb.cpu / double(tb.stats.samples)) / (ta.cpu / double(ta.stats.samples)));
        g_marginal.push_back(((tb.cpu - ga.cpu) / double(tb.stats.samples - ga.stats.samples)) /
                             ((ta.cpu - pa.cpu) / double(ta.stats.samples - pa.stats.samples)));
        g_sampling.push_back(tb.sampling_cpu_per_sample / ta.sampling_cpu_per_sample);
        std::printf("run %d: bdpt %.3f M samples/s, gbdpt %.3f M samples/s, CPU time per sample gbdpt/bdpt %.2f, "
                    "marginal %.2f, sampling %.2f\n",
                    r, double(ta.stats.samples) / ta.stats.seconds * 1e-6, double(tb.stats.samples) / tb.stats.seconds * 1e-6,
                    g_cpu.back(), g_marginal.back(), g_sampling.back());
    }
    std::printf("cost of a G-BDPT sample / a BDPT sample: %.2fx CPU time whole renders, %.2fx marginal, %.2fx while "
                "sampling (medians of %d interleaved runs)\n",
                median(g_cpu), median(g_marginal), median(g_sampling), repeats);
    return 0;
}

// Peak resident memory of one 2048x2048 G-PT render of 1 spp with the
// default reconstructions, from a child process that does nothing else (the
// parent's own peak would include the renders above). The sample count does
// not change the accumulators' size.
void peak_memory(const std::string& path) {
    constexpr int kSide = 2048;
    std::fflush(stdout);
    const pid_t child = fork();
    if (child < 0) throw RuntimeFailure("bench_gpt: fork failed for the peak-memory render");
    if (child == 0) {
        try {
            SceneFile sf = load_scene_file(path);
            set_resolution(sf, kSide, kSide);
            auto gpt = integrator_registry().create("gpt", Params());
            RenderSettings st;
            st.spp = 1;
            FrameBuffer fb;
            gpt->render(*sf.scene, st, fb);
            _exit(0);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "bench_gpt: peak-memory render: %s\n", e.what());
            _exit(1);
        }
    }
    int status = 0;
    rusage use{};
    if (wait4(child, &status, 0, &use) != child || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
        throw RuntimeFailure("bench_gpt: the peak-memory render failed");
    const double bytes = double(use.ru_maxrss) * 1024.0;  // ru_maxrss is in KiB on Linux
    std::printf("peak memory of a %dx%d gpt render (1 spp, default reconstructions): %.2f GB, %.0f bytes a pixel\n",
                kSide, kSide, bytes * 1e-9, bytes / (double(kSide) * kSide));
}
