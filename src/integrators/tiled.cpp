#include "gdr/integrators/tiled.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <new>

#include <sys/mman.h>
#include <unistd.h>
#include <cmath>
#include <mutex>

#include <fmt/core.h>
#include <tbb/global_control.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace gdr {

namespace {
constexpr int kTile = 16;
constexpr int kMaxBatch = 16;  // most jobs per sample_batch() call
using Clock = std::chrono::steady_clock;

// Uninitialised values on transparent huge pages where the kernel offers them:
// a 1280x720 render accumulates 50 MB (pt) to 240 MB (gpt), and faulting that in as 4 KiB pages
// costs more than a sample per pixel on a virtual machine.
template <typename T>
struct HugeArray {
    explicit HugeArray(size_t n) : bytes((std::max<size_t>(n, 1) * sizeof(T) + kHuge - 1) / kHuge * kHuge) {
        void* p = std::aligned_alloc(kHuge, bytes);
        if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
        madvise(p, bytes, MADV_HUGEPAGE);  // a hint; failure just means small pages
#endif
        data = static_cast<T*>(p);
    }
    ~HugeArray() { std::free(data); }
    HugeArray(const HugeArray&) = delete;
    HugeArray& operator=(const HugeArray&) = delete;
    T& operator[](size_t i) { return data[i]; }
    static constexpr size_t kHuge = size_t(2) << 20;
    size_t bytes;
    T* data = nullptr;
};
using HugeFloats = HugeArray<float>;
using HugeDoubles = HugeArray<double>;
// Where each slot's channels sit in a pixel's accumulators.
struct SlotLayout {
    std::vector<int> offset;      // per slot: first channel among the means
    std::vector<int> var_offset;  // per slot: first channel among the squared deviations (-1: none)
    int stride = 0;               // channels per pixel
    int var_stride = 0;           // channels with a variance per pixel
    // The sample values whose squared deviations are kept, as runs of
    // consecutive channels (from, to, length) in squared-deviation order:
    // slots with a variance usually come first, so one run covers them and
    // its loop vectorises.
    struct Run {
        int from, to, n;
    };
    std::vector<Run> squared;
};

SlotLayout slot_layout(const std::vector<SlotSpec>& specs) {
    SlotLayout l;
    for (const auto& s : specs) {
        l.offset.push_back(l.stride), l.stride += s.channels;
        l.var_offset.push_back(s.variance ? l.var_stride : -1), l.var_stride += s.variance ? s.channels : 0;
    }
    for (size_t s = 0; s < specs.size(); ++s)
        if (specs[s].variance) {
            if (!l.squared.empty() && l.squared.back().from + l.squared.back().n == l.offset[s] &&
                l.squared.back().to + l.squared.back().n == l.var_offset[s])
                l.squared.back().n += specs[s].channels;
            else
                l.squared.push_back({l.offset[s], l.var_offset[s], specs[s].channels});
        }
    return l;
}
}  // namespace

struct TiledIntegrator::Buffers {
    std::unique_ptr<HugeFloats> mean, m2;
    std::unique_ptr<HugeDoubles> splat_sum, splat_sum2;  // per pixel and splat layer, 3 channels
    // A kept buffer is reused if it holds at least n values and not more
    // than four times that (a small render does not pin a big render's memory).
    template <typename T>
    static HugeArray<T>& fit(std::unique_ptr<HugeArray<T>>& b, size_t n) {
        const size_t need = std::max<size_t>(n, 1) * sizeof(T);
        if (!b || b->bytes < need || b->bytes > 4 * need + HugeArray<T>::kHuge) {
            b.reset();  // free first: two large buffers need not coexist
            b = std::make_unique<HugeArray<T>>(n);
        }
        return *b;
    }
    // Bytes held.
    size_t bytes() const {
        size_t n = 0;
        if (mean) n += mean->bytes;
        if (m2) n += m2->bytes;
        if (splat_sum) n += splat_sum->bytes + splat_sum2->bytes;
        return n;
    }
};

void TiledIntegrator::sample(const Scene&, int, int, Sampler&, float*, uint64_t&) const {
    throw RuntimeFailure("an integrator derived from TiledIntegrator overrides neither sample() nor sample_batch()");
}

void TiledIntegrator::sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                                   uint64_t& rays) const {
    for (int i = 0; i < n; ++i) sample(scene, jobs[i].x, jobs[i].y, jobs[i].sampler, out + size_t(i) * stride, rays);
}

int TiledIntegrator::batch_param(const Params& p, const std::string& who, int max_batch) {
    const long long batch = p.get_int("batch", max_batch);
    if (batch < 1 || batch > max_batch)
        throw ParameterError(who + ": batch must be between 1 and " + std::to_string(max_batch));
    return int(batch);
}

std::pair<int, int> TiledIntegrator::depth_params(const Params& p, const std::string& who) {
    const long long max_depth = p.get_int("max_depth", -1), rr_depth = p.get_int("rr_depth", 5);
    if (max_depth != -1 && (max_depth < 1 || max_depth > kMaxDepth))
        throw ParameterError(who + ": max_depth must be -1 (unlimited) or between 1 and " + std::to_string(kMaxDepth) +
                             ", got " + std::to_string(max_depth));
    if (rr_depth < 1 || rr_depth > kMaxDepth)
        throw ParameterError(who + ": rr_depth must be between 1 and " + std::to_string(kMaxDepth) + ", got " +
                             std::to_string(rr_depth));
    return {int(max_depth), int(rr_depth)};
}

TiledIntegrator::TiledIntegrator() : buffers_(std::make_unique<Buffers>()) {}
TiledIntegrator::~TiledIntegrator() = default;

size_t TiledIntegrator::release_buffers() {
    const size_t bytes = buffers_->bytes();
    buffers_->mean.reset();
    buffers_->m2.reset();
    buffers_->splat_sum.reset();
    buffers_->splat_sum2.reset();
    return bytes;
}

int Accumulated::slot(const std::string& name) const {
    for (size_t i = 0; i < specs.size(); ++i)
        if (specs[i].name == name) return int(i);
    throw ParameterError("no accumulated slot '" + name + "'");
}

Image Accumulated::count_image() const {
    Image im(width, height, 1);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) im.at(x, y) = float(count(x, y));
    return im;
}

std::vector<Image> Accumulated::images(const std::vector<Want>& wanted) const {
    std::vector<int> slots;
    std::vector<Image> out;
    for (const Want& w : wanted) {
        const int s = slot(w.slot);
        if (w.variance && !specs[s].variance)
            throw ParameterError("accumulated slot '" + w.slot + "' tracks no variance");
        slots.push_back(s);
        out.emplace_back(width, height, specs[s].channels);
    }
    // One pass: each pixel's sums are read while in cache, whatever the number of images.
    tbb::parallel_for(0, height, [&](int y) {
        for (int x = 0; x < width; ++x)
            for (size_t i = 0; i < wanted.size(); ++i) {
                const int s = slots[i];
                for (int c = 0; c < specs[s].channels; ++c)
                    out[i].at(x, y, c) = wanted[i].variance ? variance(s, x, y, c) : mean(s, x, y, c);
            }
    });
    return out;
}

void TiledIntegrator::check_settings(const RenderSettings& st, int W, int H) const {
    if (st.time_budget <= 0.0 && st.spp <= 0) throw ParameterError("spp must be positive");
    if (st.first_sample < 0) throw ParameterError("first sample index must be non-negative");
    // A sample's number is 32 bits of its sampler key: past 2^32 a pixel's
    // sample streams would repeat, and the image would stop converging.
    if (st.first_sample + (st.time_budget > 0.0 ? 0 : st.spp) > (1LL << 32))
        throw ParameterError(fmt::format("spp {} from sample {} on exceeds the 2^32 samples per pixel a sampler "
                                         "numbers",
                                         st.spp, st.first_sample));
    const Image* density = st.sample_density;
    if (density) {
        if (splat_layers() > 0)
            throw ParameterError("adaptive sampling: this integrator splats light-tracing samples onto other pixels, "
                                 "which share one sample count, so it samples uniformly only");
        if (density->width() != W || density->height() != H || density->channels() != 1)
            throw ParameterError(fmt::format("adaptive sampling: the sample density is {}x{} with {} channels, not "
                                             "{}x{} with 1",
                                             density->width(), density->height(), density->channels(), W, H));
        float most = 0.f;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const float d = density->at(x, y);
                if (!(d >= 0.f && d <= kMaxSampleDensity))
                    throw ParameterError(fmt::format("adaptive sampling: the sample density at pixel ({}, {}) is {}, "
                                                     "not between 0 and {}",
                                                     x, y, d, kMaxSampleDensity));
                most = std::max(most, d);
            }
        if (st.time_budget <= 0.0 && sample_count(st.first_sample + st.spp, most) > (1LL << 32))
            throw ParameterError(fmt::format("adaptive sampling: a pixel of density {} would take more than the 2^32 "
                                             "samples a sampler numbers",
                                             most));
    }
    const Image* mask = st.gradient_mask;
    if (mask) {
        if (!takes_gradient_mask())
            throw ParameterError("gradient mask: this integrator does not take one (only gpt chooses per pixel whether "
                                 "to estimate gradients)");
        if (mask->width() != W || mask->height() != H || mask->channels() != 1)
            throw ParameterError(fmt::format("gradient mask: it is {}x{} with {} channels, not {}x{} with 1",
                                             mask->width(), mask->height(), mask->channels(), W, H));
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                if (const float m = mask->at(x, y); m != 0.f && m != 1.f)
                    throw ParameterError(
                        fmt::format("gradient mask: pixel ({}, {}) holds {}, not 0 or 1", x, y, m));
    }
}

RenderStats TiledIntegrator::render(const Scene& scene, const RenderSettings& st, FrameBuffer& out,
                                    const ProgressFn& progress) {
    if (rendering_.exchange(true))
        throw RuntimeFailure("this integrator is already rendering: concurrent renders need one integrator each");
    struct Release {
        std::atomic<bool>& flag;
        const Image*& density;
        const Image*& mask;
        ~Release() { flag = false, density = nullptr, mask = nullptr; }
    } release{rendering_, density_, mask_};
    const int W = scene.camera().width(), H = scene.camera().height();
    check_settings(st, W, H);
    const Image* density = st.sample_density;
    const Image* mask = st.gradient_mask;
    density_ = density;
    mask_ = mask;
    prepare(scene);
    begin_render(scene, st);
    const std::vector<SlotSpec> specs = slots();
    const SlotLayout layout = slot_layout(specs);
    const std::vector<int>&offset = layout.offset, &var_offset = layout.var_offset;
    const int stride = layout.stride, var_stride = layout.var_stride;
    const std::vector<SlotLayout::Run>& squared = layout.squared;

    // Each pixel keeps the running mean of every channel and, where a
    // variance is asked for, the sum of squared deviations from it, updated
    // sample by sample (Welford, "Note on a method for calculating corrected
    // sums of squares and products", 1962): stable for any number of samples
    // in single precision, unlike a float sum of squares, at half the memory
    // of double sums; each update rounds once, so a mean after n samples is
    // within about sqrt(n) float roundings of the exact one. The buffers are
    // left uninitialised here and zeroed tile by tile by the workers in the
    // first pass: a serial memset of a large image would cost as much as a
    // few samples per pixel, and first touch on the worker places the pages.
    const size_t npix = size_t(W) * H;
    const int splat_layers = std::max(0, this->splat_layers());
    const bool splatting = splat_layers > 0;
    const size_t splat_values = npix * size_t(splat_layers) * 3;
    // Accumulators plus the float layers finalize() writes (about one per
    // accumulated channel): refused up front when they exceed the machine's
    // memory, where the kernel would otherwise grant them and kill the
    // process part-way through the render.
    const double need = double(npix) * (double(stride + var_stride) * sizeof(float) + double(stride) * sizeof(float)) +
                        double(splat_values) * (2 * sizeof(double) + sizeof(float));
    const double have = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    const auto too_big = [&] {
        return RuntimeFailure(fmt::format("a {}x{} render with this integrator needs about {:.1f} GB of memory, "
                                          "the machine has {:.1f} GB: render fewer pixels",
                                          W, H, need * 1e-9, have * 1e-9));
    };
    if (have > 0.0 && need > have) throw too_big();
    HugeFloats* mean_p = nullptr;
    HugeFloats* m2_p = nullptr;
    try {
        mean_p = &Buffers::fit(buffers_->mean, npix * stride);
        m2_p = &Buffers::fit(buffers_->m2, npix * var_stride);
        if (splatting) {
            Buffers::fit(buffers_->splat_sum, splat_values);
            Buffers::fit(buffers_->splat_sum2, splat_values);
        }
    } catch (const std::bad_alloc&) {
        throw too_big();
    }
    HugeFloats& mean = *mean_p;
    HugeFloats& m2 = *m2_p;

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
    // Samples pixel (x, y) holds after `passes` passes.
    const auto count_at = [&](int x, int y, long long passes) {
        return density ? sample_count(passes, density->at(x, y)) : passes;
    };
    uint64_t total_samples = timed ? 0 : uint64_t(st.spp) * W * H;
    if (density && !timed) {
        total_samples = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                total_samples += uint64_t(count_at(x, y, st.first_sample + st.spp) - count_at(x, y, st.first_sample));
    }

    const int batch = std::clamp(batch_size(), 1, kMaxBatch);
    const bool use_jobs = splatting || jobs_only();
    tbb::task_arena arena(st.threads > 0 ? st.threads : tbb::task_arena::automatic);
    long long done = 0;  // samples per pixel finished
    const auto cancelled = [&] { return st.cancel && st.cancel->load(); };
    const auto aborted = [&] { return st.abort && st.abort->load(); };
    bool first_pass = true;
    // A pass that is abandoned part-way (an interrupt that cannot wait for its
    // end) restores the tiles it already added to from this copy of their
    // accumulators, so that every pixel keeps the same number of samples.
    std::unique_ptr<HugeFloats> backup_mean, backup_m2;
    std::vector<uint8_t> tile_done(tiles.size());
    std::vector<uint64_t> tile_samples(tiles.size());  // samples each tile took in the pass under way
    // Each tile's splats of the pass under way, added to the splat sums in
    // tile order once the pass is whole (an abandoned pass drops them).
    std::vector<SplatList> tile_splats(splatting ? tiles.size() : 0);
    for (SplatList& l : tile_splats) l.width_ = W, l.height_ = H;
    double* splat_sum = splatting ? buffers_->splat_sum->data : nullptr;
    double* splat_sum2 = splatting ? buffers_->splat_sum2->data : nullptr;
    if (splatting)
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, splat_values, size_t(1) << 16), [&](const auto& r) {
                std::fill(splat_sum + r.begin(), splat_sum + r.end(), 0.0);
                std::fill(splat_sum2 + r.begin(), splat_sum2 + r.end(), 0.0);
            });
        });
    // Runs passes [first, first + count): one sample per pixel each, or each
    // pixel's share under adaptive sampling. With `abandonable`, a tile not
    // yet started once a cancel or abort is seen is skipped, and the pass is
    // then undone (from the backup, when it is not the first): returns false
    // in that case.
    auto run_pass = [&](long long first, long long count, bool abandonable) {
        std::atomic<bool> skipped{false};
        std::fill(tile_done.begin(), tile_done.end(), uint8_t(0));
        const bool keep = abandonable && !first_pass;
        const auto tile_rows = [&](const auto& t, const auto& fn) {
            for (int y = t.y0; y < t.y1; ++y) {
                const size_t a = size_t(y) * W + t.x0, b = size_t(y) * W + t.x1;
                fn(a * stride, b * stride, a * var_stride, b * var_stride);
            }
        };
        arena.execute([&] {
            tbb::parallel_for(size_t(0), tiles.size(), [&](size_t ti) {
                const Tile& t = tiles[ti];
                if (abandonable && (skipped.load(std::memory_order_relaxed) || cancelled() || aborted())) {
                    skipped = true;
                    return;
                }
                if (keep)
                    tile_rows(t, [&](size_t s0, size_t s1, size_t q0, size_t q1) {
                        std::copy(mean.data + s0, mean.data + s1, backup_mean->data + s0);
                        std::copy(m2.data + q0, m2.data + q1, backup_m2->data + q0);
                    });
                // Jobs in pixel order, sample order within a pixel, handed to
                // sample_batch() `batch` at a time (across pixels when passes
                // are short); each pixel's sums still add its samples in order.
                float v[64];
                std::vector<float> v_heap;
                float* vp = v;
                if (size_t(stride) * batch > 64) v_heap.resize(size_t(stride) * batch), vp = v_heap.data();
                float zero_stack[64] = {};  // a dropped sample's values
                std::vector<float> zero_heap;
                const float* zeros = zero_stack;
                if (stride > 64) zero_heap.assign(size_t(stride), 0.f), zeros = zero_heap.data();
                SampleJob jobs[kMaxBatch];
                long long job_taken[kMaxBatch];  // per job: the render's samples of its pixel before it
                int n = 0;
                SplatList* splats = splatting ? &tile_splats[ti] : nullptr;
                if (splats) splats->splats_.clear();
                uint64_t local_rays = 0, local_nan = 0, local_samples = 0;
                // Adds one sample's values `a`, the pixel's sample `k` + 1 of
                // this render, to pixel (x, y)'s running means `pm` and squared
                // deviations `pq`, or reports it if any value is not finite
                // and adds it as zero.
                const auto add = [&](const float* a, int x, int y, long long k, float* pm,
                                     float* pq) __attribute__((always_inline)) {
                    // Non-finite floats have all exponent bits set. Integer
                    // tests, unlike float compares with NaN, vectorise.
                    uint32_t bad = 0;
                    for (int c = 0; c < stride; ++c)
                        bad |= uint32_t((std::bit_cast<uint32_t>(a[c]) & 0x7f800000u) == 0x7f800000u);
                    if (bad) [[unlikely]] {
                        // A NaN/Inf sample is reported with its pixel and dropped as zero.
                        ++local_nan;
                        {
                            std::lock_guard<std::mutex> lock(nan_mutex);
                            if (stats.nonfinite_pixels.size() < 8) stats.nonfinite_pixels.emplace_back(x, y);
                        }
                        a = zeros;
                    }
                    const double inv = 1.0 / double(k + 1);
                    // Squared deviations first: they need the mean before and after.
                    for (const SlotLayout::Run& run : squared) {
                        const float* r = a + run.from;
                        const float* m = pm + run.from;
                        float* q = pq + run.to;
                        for (int i = 0; i < run.n; ++i) {
                            const double d = double(r[i]) - double(m[i]);
                            const double after = double(m[i]) + d * inv;
                            q[i] = float(double(q[i]) + d * (double(r[i]) - after));
                        }
                    }
                    for (int c = 0; c < stride; ++c) pm[c] = float(double(pm[c]) + (double(a[c]) - double(pm[c])) * inv);
                };
                const auto flush = [&] {
                    std::fill(vp, vp + size_t(n) * stride, 0.f);
                    sample_batch(scene, jobs, n, vp, stride, local_rays);
                    for (int j = 0; j < n; ++j) {
                        const size_t at = size_t(jobs[j].y) * W + jobs[j].x;
                        add(vp + size_t(j) * stride, jobs[j].x, jobs[j].y, job_taken[j],
                            &mean[at * stride], &m2[at * var_stride]);
                    }
                    n = 0;
                };
                for (int y = t.y0; y < t.y1; ++y)
                    for (int x = t.x0; x < t.x1; ++x) {
                        float* pm = &mean[(size_t(y) * W + x) * stride];
                        float* pq = &m2[(size_t(y) * W + x) * var_stride];
                        if (first_pass) {
                            std::fill(pm, pm + stride, 0.f);
                            std::fill(pq, pq + var_stride, 0.f);
                        }
                        const uint64_t pixel_stream = SampleKey{st.seed, uint32_t(x), uint32_t(y), 0}.pixel_stream();
                        const long long i0 = count_at(x, y, first), i1 = count_at(x, y, first + count);
                        // The render's own samples of the pixel before its sample number i are i - before.
                        const long long before = count_at(x, y, st.first_sample);
                        local_samples += uint64_t(i1 - i0);
                        for (long long i = i0; i < i1; ++i) {
                            if (batch == 1 && !use_jobs) {
                                // One at a time: no job queue between the sample and its sums.
                                std::fill(vp, vp + stride, 0.f);
                                SampleJob one{x, y, Sampler(SampleKey::stream_of(pixel_stream, uint32_t(i)))};
                                one.index = uint32_t(i);
                                sample_batch(scene, &one, 1, vp, stride, local_rays);
                                add(vp, x, y, i - before, pm, pq);
                                continue;
                            }
                            jobs[n].x = x, jobs[n].y = y, jobs[n].index = uint32_t(i);
                            job_taken[n] = i - before;
                            jobs[n].sampler = Sampler(SampleKey::stream_of(pixel_stream, uint32_t(i)));
                            jobs[n].splats = splats;
                            if (++n == batch) flush();
                        }
                    }
                if (n > 0) flush();
                tile_done[ti] = 1;
                tile_samples[ti] = local_samples;
                rays += local_rays;
                nonfinite += local_nan;
                const uint64_t s = samples += local_samples;
                if (progress) {
                    Progress p;
                    p.samples = s;
                    p.seconds = seconds();
                    p.fraction = timed ? std::min(1.0, p.seconds / st.time_budget) : double(s) / double(total_samples);
                    progress(p);
                }
            });
        });
        if (!skipped) {
            first_pass = false;
            // Serial, in tile order: a pixel's splat sums then add the same
            // values in the same order whatever the threads did.
            uint64_t bad = 0;
            for (size_t ti = 0; ti < tile_splats.size(); ++ti)
                for (const SplatList::Splat& sp : tile_splats[ti].splats_) {
                    if (!(std::isfinite(sp.v[0]) && std::isfinite(sp.v[1]) && std::isfinite(sp.v[2]))) {
                        ++bad;
                        if (stats.nonfinite_pixels.size() < 8)
                            stats.nonfinite_pixels.emplace_back(int(sp.pixel % uint32_t(W)), int(sp.pixel / uint32_t(W)));
                        continue;
                    }
                    const size_t at = (size_t(sp.pixel) * splat_layers + sp.layer) * 3;
                    for (int c = 0; c < 3; ++c) {
                        splat_sum[at + c] += sp.v[c];
                        splat_sum2[at + c] += double(sp.v[c]) * double(sp.v[c]);
                    }
                }
            nonfinite += bad;
            return true;
        }
        for (size_t ti = 0; ti < tiles.size(); ++ti) {
            if (!tile_done[ti]) continue;
            const Tile& t = tiles[ti];
            samples -= tile_samples[ti];
            if (keep)
                tile_rows(t, [&](size_t s0, size_t s1, size_t q0, size_t q1) {
                    std::copy(backup_mean->data + s0, backup_mean->data + s1, mean.data + s0);
                    std::copy(backup_m2->data + q0, backup_m2->data + q1, m2.data + q0);
                });
        }
        return false;
    };

    // Passes are sized to last about st.stop_latency, measured as the render
    // goes (at most 16 samples per pixel): a cancel then waits at most about
    // that long. A pass predicted to last over 1.5 times as long (one sample
    // per pixel of a large or slow image) can be abandoned part-way and
    // undone from a copy of the sums, when memory allows one. The division
    // into passes does not change the image: every pixel still adds its
    // samples in order. Shorter passes cost throughput: passes of half a
    // second made a 32-spp Cornell box render 1.6% slower on one thread
    // than passes of 16 spp (benchmarks/ab.sh, 5 rounds).
    const double pass_seconds = std::max(0.0, st.stop_latency), wait_seconds = 1.5 * pass_seconds;
    double seconds_per_spp = 0.0;  // of the last pass; 0 before the first
    const double backup_bytes = double(npix) * double(stride + var_stride) * sizeof(float);
    const auto long_pass = [&](long long n) { return seconds_per_spp * double(n) >= wait_seconds; };
    const auto ensure_backup = [&] {
        if (backup_mean) return true;
        if (have > 0.0 && need + backup_bytes > have) return false;
        try {
            backup_mean = std::make_unique<HugeFloats>(npix * stride);
            backup_m2 = std::make_unique<HugeFloats>(npix * var_stride);
        } catch (const std::bad_alloc&) {
            backup_mean.reset();
            return false;
        }
        return true;
    };
    // An abandoned first pass leaves nothing to undo, and no image: a render
    // needs a sample in every pixel, so render() then throws Interrupted.
    const auto pass = [&](long long first, long long n) {
        const auto t = seconds();
        const bool ok = run_pass(first, n, first_pass || (long_pass(n) && ensure_backup()));
        if (ok) seconds_per_spp = (seconds() - t) / double(n);
        return ok;
    };
    const auto next_count = [&](long long left) {
        if (!(seconds_per_spp > 0.0)) return std::min(left, 16LL);
        return std::clamp((long long)(pass_seconds / seconds_per_spp), 1LL, std::min(left, 16LL));
    };

    if (timed) {
        // Whole passes of one sample per pixel until the budget is spent: an
        // equal-time comparison then compares complete images, not partial ones.
        do {
            if (!pass(st.first_sample + done, 1)) break;
            ++done;
        } while (seconds() < st.time_budget && !cancelled() && !aborted());
    } else {
        // The first pass takes one sample per pixel, to measure the rate.
        long long n = 1;
        while (done < st.spp && !(done > 0 && (cancelled() || aborted()))) {
            if (!pass(st.first_sample + done, n)) break;
            done += n;
            n = next_count(st.spp - done);
        }
    }
    if (done == 0) throw Interrupted("the render was stopped before its first pass finished: there is no image to keep");

    // Means and variances are read from the accumulators by finalize() itself: a slot
    // that only feeds a combined layer (G-PT's splats and one-sided
    // gradients) then costs no image of its own.
    Accumulated acc;
    acc.specs = specs;
    acc.spp = done;
    acc.derived = !aborted();
    acc.width = W, acc.height = H;
    acc.mean_ = mean.data, acc.m2_ = m2.data;
    std::vector<uint32_t> counts;
    if (density) {
        counts.resize(npix);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                counts[size_t(y) * W + x] =
                    uint32_t(count_at(x, y, st.first_sample + done) - count_at(x, y, st.first_sample));
        acc.counts_ = counts.data();
    }
    acc.stride_ = stride, acc.var_stride_ = var_stride;
    acc.offset_ = offset, acc.var_offset_ = var_offset;
    acc.splat_sum_ = splat_sum, acc.splat_sum2_ = splat_sum2, acc.splat_layers_ = splat_layers;
    out = FrameBuffer(W, H);
    // The mask fixed which pixels have gradients: a resumed or merged render
    // needs the same, and finalize()'s reconstructions read it.
    if (mask) out.set("gradient_mask", *mask);
    arena.execute([&] { finalize(acc, out); });
    if (density) {
        // Each pixel's own count, and the density that fixed it (a resumed or
        // merged render needs it to continue each pixel's sample numbers).
        out.set("spp", acc.count_image());
        out.set("sample_density", *density);
    } else {
        out.add("spp", 1);
        std::fill(out.get("spp").values().begin(), out.get("spp").values().end(), float(done));
    }
    out.metadata()["spp"] = std::to_string(done);
    out.metadata()["seed"] = std::to_string(st.seed);
    out.metadata()["first_sample"] = std::to_string(st.first_sample);
    out.metadata()["integrator_params"] = describe();
    // The layers derived from the means (reconstructions) last, after large
    // accumulators are freed: their solvers' memory then reuses the
    // accumulators' instead of adding to it.
    backup_mean.reset(), backup_m2.reset();
    if (buffers_->bytes() > kKeptBufferBytes) release_buffers();
    if (acc.derived) arena.execute([&] { update_merged(out); });

    stats.seconds = seconds();
    stats.samples = samples;
    stats.rays = rays;
    stats.nonfinite = nonfinite;
    stats.spp = done;
    return stats;
}

void TiledIntegrator::finalize(const Accumulated& acc, FrameBuffer& out) const {
    std::vector<Accumulated::Want> wanted;
    for (const SlotSpec& spec : acc.specs) {
        wanted.push_back({spec.name, false});
        if (spec.variance) wanted.push_back({spec.name, true});
    }
    std::vector<Image> images = acc.images(wanted);
    for (size_t i = 0; i < wanted.size(); ++i)
        out.set(wanted[i].variance ? wanted[i].slot + "_variance" : wanted[i].slot, std::move(images[i]));
}

}  // namespace gdr
