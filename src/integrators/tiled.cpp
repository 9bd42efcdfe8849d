#include "gdr/integrators/tiled.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace gdr {

namespace {
constexpr int kTile = 16;
using Clock = std::chrono::steady_clock;
}  // namespace

const Image& Accumulated::mean_of(const std::string& name) const {
    for (size_t i = 0; i < specs.size(); ++i)
        if (specs[i].name == name) return mean[i];
    throw ParameterError("no accumulated slot '" + name + "'");
}

const Image& Accumulated::variance_of(const std::string& name) const {
    for (size_t i = 0; i < specs.size(); ++i)
        if (specs[i].name == name) return variance[i];
    throw ParameterError("no accumulated slot '" + name + "'");
}

RenderStats TiledIntegrator::render(const Scene& scene, const RenderSettings& st, FrameBuffer& out,
                                    const ProgressFn& progress) {
    if (st.time_budget <= 0.0 && st.spp <= 0) throw ParameterError("spp must be positive");
    if (st.first_sample < 0) throw ParameterError("first sample index must be non-negative");
    prepare(scene);
    const int W = scene.camera().width(), H = scene.camera().height();
    const std::vector<SlotSpec> specs = slots();
    std::vector<int> offset;
    int stride = 0;
    for (const auto& s : specs) offset.push_back(stride), stride += s.channels;

    // Double sums keep the variance formula stable for thousands of samples.
    std::vector<double> sum(size_t(W) * H * stride, 0.0), sum2(size_t(W) * H * stride, 0.0);

    struct Tile {
        int x0, y0, x1, y1;
    };
    std::vector<Tile> tiles;
    for (int y = 0; y < H; y += kTile)
        for (int x = 0; x < W; x += kTile) tiles.push_back({x, y, std::min(W, x + kTile), std::min(H, y + kTile)});

    RenderStats stats;
    std::atomic<uint64_t> rays{0}, samples{0}, nonfinite{0};
    std::mutex nan_mutex;
    const auto t0 = Clock::now();
    const auto seconds = [&] { return std::chrono::duration<double>(Clock::now() - t0).count(); };
    const bool timed = st.time_budget > 0.0;
    const uint64_t total_samples = timed ? 0 : uint64_t(st.spp) * W * H;

    tbb::task_arena arena(st.threads > 0 ? st.threads : tbb::task_arena::automatic);
    long long done = 0;  // samples per pixel finished
    const auto cancelled = [&] { return st.cancel && st.cancel->load(); };
    auto run_pass = [&](long long first, long long count) {
        arena.execute([&] {
            tbb::parallel_for(size_t(0), tiles.size(), [&](size_t ti) {
                const Tile& t = tiles[ti];
                std::vector<float> v(stride);
                uint64_t local_rays = 0, local_nan = 0;
                for (int y = t.y0; y < t.y1; ++y)
                    for (int x = t.x0; x < t.x1; ++x) {
                        double* ps = &sum[(size_t(y) * W + x) * stride];
                        double* pq = &sum2[(size_t(y) * W + x) * stride];
                        for (long long i = first; i < first + count; ++i) {
                            std::fill(v.begin(), v.end(), 0.f);
                            Sampler sampler(SampleKey{st.seed, uint32_t(x), uint32_t(y), uint32_t(i)});
                            sample(scene, x, y, sampler, v.data(), local_rays);
                            bool ok = true;
                            for (float f : v) ok &= std::isfinite(f);
                            if (!ok) {
                                // A NaN/Inf sample is reported with its pixel and dropped as zero.
                                ++local_nan;
                                std::lock_guard<std::mutex> lock(nan_mutex);
                                if (stats.nonfinite_pixels.size() < 8) stats.nonfinite_pixels.emplace_back(x, y);
                                continue;
                            }
                            for (int k = 0; k < stride; ++k) ps[k] += v[k], pq[k] += double(v[k]) * v[k];
                        }
                    }
                rays += local_rays;
                nonfinite += local_nan;
                const uint64_t s = samples += uint64_t(count) * (t.x1 - t.x0) * (t.y1 - t.y0);
                if (progress) {
                    Progress p;
                    p.samples = s;
                    p.seconds = seconds();
                    p.fraction = timed ? std::min(1.0, p.seconds / st.time_budget) : double(s) / double(total_samples);
                    progress(p);
                }
            });
        });
    };

    if (timed) {
        // Whole passes of one sample per pixel until the budget is spent: an
        // equal-time comparison then compares complete images, not partial ones.
        do {
            run_pass(st.first_sample + done, 1);
            ++done;
        } while (seconds() < st.time_budget && !cancelled());
    } else {
        // Passes bound the loss of an interrupted render and keep progress smooth.
        const long long pass = std::max(1LL, std::min(st.spp, 16LL));
        while (done < st.spp && !(done > 0 && cancelled())) {
            const long long n = std::min(pass, st.spp - done);
            run_pass(st.first_sample + done, n);
            done += n;
        }
    }

    Accumulated acc;
    acc.specs = specs;
    acc.spp = done;
    for (size_t s = 0; s < specs.size(); ++s) {
        Image m(W, H, specs[s].channels), var;
        if (specs[s].variance) var = Image(W, H, specs[s].channels);
        for (size_t p = 0; p < size_t(W) * H; ++p)
            for (int c = 0; c < specs[s].channels; ++c) {
                const double a = sum[p * stride + offset[s] + c], b = sum2[p * stride + offset[s] + c];
                const double mean = a / double(done);
                m.values()[p * specs[s].channels + c] = float(mean);
                if (specs[s].variance)
                    var.values()[p * specs[s].channels + c] =
                        done > 1 ? float(std::max(0.0, (b - a * mean) / double(done - 1))) : 0.f;
            }
        acc.mean.push_back(std::move(m));
        acc.variance.push_back(std::move(var));
    }
    out = FrameBuffer(W, H);
    finalize(acc, out);
    out.add("spp", 1);
    std::fill(out.get("spp").values().begin(), out.get("spp").values().end(), float(done));
    out.metadata()["spp"] = std::to_string(done);
    out.metadata()["seed"] = std::to_string(st.seed);
    out.metadata()["first_sample"] = std::to_string(st.first_sample);
    out.metadata()["integrator_params"] = describe();

    stats.seconds = seconds();
    stats.samples = samples;
    stats.rays = rays;
    stats.nonfinite = nonfinite;
    stats.spp = done;
    return stats;
}

void TiledIntegrator::finalize(const Accumulated& acc, FrameBuffer& out) const {
    for (size_t s = 0; s < acc.specs.size(); ++s) {
        out.set(acc.specs[s].name, acc.mean[s]);
        if (acc.specs[s].variance) out.set(acc.specs[s].name + "_variance", acc.variance[s]);
    }
}

}  // namespace gdr
