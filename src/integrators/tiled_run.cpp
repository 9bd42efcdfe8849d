// One render() of a TiledIntegrator: the pass loop over tiles, the
// accumulation of samples and splats, interruption and undo, and the frame
// buffer written at the end (gdr/integrators/tiled.h).
#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <new>

#include <unistd.h>

#include <fmt/core.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "gdr/integrators/tiled.h"
#include "tiled_storage.h"

namespace gdr {

namespace {
constexpr int kTile = 16;
constexpr int kMaxBatch = 16;  // most jobs per sample_batch() call
using Clock = std::chrono::steady_clock;
using detail::HugeFloats;
using detail::SlotLayout;
using detail::slot_layout;
}  // namespace

// One call of render(), in the order it runs: allocate() the accumulators,
// run the passes (sample_passes(): each pass samples every tile, sample_tile(),
// then adds the tiles' splats, add_splats(), or is undone, undo_pass()), and
// finish() the frame buffer from the accumulators.
//
// Each pixel keeps the running mean of every channel and, where a variance is
// asked for, the sum of squared deviations from it, updated sample by sample
// (Welford, "Note on a method for calculating corrected sums of squares and
// products", 1962): stable for any number of samples in single precision,
// unlike a float sum of squares, at half the memory of double sums; each
// update rounds once, so a mean after n samples is within about sqrt(n) float
// roundings of the exact one. The buffers are left uninitialised by
// allocate() and zeroed tile by tile by the workers in the first pass: a
// serial memset of a large image would cost as much as a few samples per
// pixel, and first touch on the worker places the pages.
class TiledIntegrator::RenderRun {
public:
    RenderRun(TiledIntegrator& integrator, const Scene& scene, const RenderSettings& st, const ProgressFn& progress);
    /// Reserves the accumulators; RuntimeFailure if they exceed the machine's memory.
    void allocate();
    /// Runs passes until the sample count or the time budget is reached, or
    /// the render is cancelled or aborted; Interrupted if not one pass finished.
    void sample_passes();
    /// Writes the frame buffer (finalize(), spp, metadata, update_merged()) and the statistics.
    RenderStats finish(FrameBuffer& out);

private:
    struct Tile {
        int x0, y0, x1, y1;
    };
    // Samples pixel (x, y) holds after `passes` passes.
    long long count_at(int x, int y, long long passes) const {
        return density_ ? sample_count(passes, density_->at(x, y)) : passes;
    }
    double seconds() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }
    bool cancelled() const { return st_.cancel && st_.cancel->load(); }
    bool aborted() const { return st_.abort && st_.abort->load(); }
    // Runs passes [first, first + count): one sample per pixel each, or each
    // pixel's share under adaptive sampling. With `abandonable`, a tile not
    // yet started once a cancel or abort is seen is skipped, and the pass is
    // then undone (from the backup, when it is not the first): returns false
    // in that case.
    bool run_pass(long long first, long long count, bool abandonable);
    // Tile `ti`'s samples of passes [first, first + count), added to its
    // pixels' accumulators (saved to the backup first when `keep`).
    void sample_tile(size_t ti, long long first, long long count, bool keep);
    // After a whole pass, serially and in tile order: a pixel's splat sums then
    // add the same values in the same order whatever the threads did.
    void add_splats();
    // After an abandoned pass: the tiles it finished get their accumulators
    // back from the backup (`keep`) and their samples are uncounted.
    void undo_pass(bool keep);
    // A copy of the accumulators for undoing a long pass; false where memory
    // does not allow one.
    bool ensure_backup();
    // Calls `fn(s0, s1, q0, q1)` for each row of tile `t`: its ranges among the means and the squared deviations.
    template <typename Fn>
    void tile_rows(const Tile& t, const Fn& fn) const {
        for (int y = t.y0; y < t.y1; ++y) {
            const size_t a = size_t(y) * W_ + t.x0, b = size_t(y) * W_ + t.x1;
            fn(a * stride_, b * stride_, a * var_stride_, b * var_stride_);
        }
    }

    TiledIntegrator& in_;
    const Scene& scene_;
    const RenderSettings& st_;
    const ProgressFn& progress_;
    const Image* density_;
    const Image* mask_;
    const int W_, H_;
    const size_t npix_;
    const std::vector<SlotSpec> specs_;
    const SlotLayout layout_;
    const int stride_, var_stride_;
    const int splat_layers_;
    const size_t splat_values_;
    const int batch_;
    const bool use_jobs_;
    const bool timed_;
    tbb::task_arena arena_;
    double need_ = 0.0, have_ = 0.0;  // bytes the render needs, bytes the machine has
    HugeFloats* mean_ = nullptr;
    HugeFloats* m2_ = nullptr;
    double* splat_sum_ = nullptr;
    double* splat_sum2_ = nullptr;
    std::vector<Tile> tiles_;
    std::vector<uint8_t> tile_done_;
    std::vector<uint64_t> tile_samples_;  // samples each tile took in the pass under way
    // Each tile's splats of the pass under way, added to the splat sums in
    // tile order once the pass is whole (an abandoned pass drops them).
    std::vector<SplatList> tile_splats_;
    // A pass that is abandoned part-way (an interrupt that cannot wait for its
    // end) restores the tiles it already added to from this copy of their
    // accumulators, so that every pixel keeps the same number of samples.
    std::unique_ptr<HugeFloats> backup_mean_, backup_m2_;
    bool first_pass_ = true;
    long long done_ = 0;  // samples per pixel finished
    uint64_t total_samples_ = 0;
    RenderStats stats_;
    std::atomic<uint64_t> rays_{0}, samples_{0}, nonfinite_{0};
    std::mutex nan_mutex_;
    const Clock::time_point t0_;
};

TiledIntegrator::RenderRun::RenderRun(TiledIntegrator& integrator, const Scene& scene, const RenderSettings& st,
                                      const ProgressFn& progress)
    : in_(integrator),
      scene_(scene),
      st_(st),
      progress_(progress),
      density_(st.sample_density),
      mask_(st.gradient_mask),
      W_(scene.camera().width()),
      H_(scene.camera().height()),
      npix_(size_t(W_) * H_),
      specs_(integrator.slots()),
      layout_(slot_layout(specs_)),
      stride_(layout_.stride),
      var_stride_(layout_.var_stride),
      splat_layers_(std::max(0, integrator.splat_layers())),
      splat_values_(npix_ * size_t(splat_layers_) * 3),
      batch_(std::clamp(integrator.batch_size(), 1, kMaxBatch)),
      use_jobs_(splat_layers_ > 0 || integrator.jobs_only()),
      timed_(st.time_budget > 0.0),
      arena_(st.threads > 0 ? st.threads : tbb::task_arena::automatic),
      t0_(Clock::now()) {
    for (int y = 0; y < H_; y += kTile)
        for (int x = 0; x < W_; x += kTile) tiles_.push_back({x, y, std::min(W_, x + kTile), std::min(H_, y + kTile)});
    tile_done_.resize(tiles_.size());
    tile_samples_.resize(tiles_.size());
    tile_splats_.resize(splat_layers_ > 0 ? tiles_.size() : 0);
    for (SplatList& l : tile_splats_) l.width_ = W_, l.height_ = H_;
    total_samples_ = timed_ ? 0 : uint64_t(st.spp) * W_ * H_;
    if (density_ && !timed_) {
        total_samples_ = 0;
        for (int y = 0; y < H_; ++y)
            for (int x = 0; x < W_; ++x)
                total_samples_ += uint64_t(count_at(x, y, st.first_sample + st.spp) - count_at(x, y, st.first_sample));
    }
}

void TiledIntegrator::RenderRun::allocate() {
    // Accumulators plus the float layers finalize() writes (about one per
    // accumulated channel): refused up front when they exceed the machine's
    // memory, where the kernel would otherwise grant them and kill the
    // process part-way through the render.
    need_ = double(npix_) * (double(stride_ + var_stride_) * sizeof(float) + double(stride_) * sizeof(float)) +
            double(splat_values_) * (2 * sizeof(double) + sizeof(float));
    have_ = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    const auto too_big = [&] {
        return RuntimeFailure(fmt::format("a {}x{} render with this integrator needs about {:.1f} GB of memory, "
                                          "the machine has {:.1f} GB: render fewer pixels",
                                          W_, H_, need_ * 1e-9, have_ * 1e-9));
    };
    if (have_ > 0.0 && need_ > have_) throw too_big();
    Buffers& buffers = *in_.buffers_;
    try {
        mean_ = &Buffers::fit(buffers.mean, npix_ * stride_);
        m2_ = &Buffers::fit(buffers.m2, npix_ * var_stride_);
        if (splat_layers_ > 0) {
            splat_sum_ = Buffers::fit(buffers.splat_sum, splat_values_).data;
            splat_sum2_ = Buffers::fit(buffers.splat_sum2, splat_values_).data;
        }
    } catch (const std::bad_alloc&) {
        throw too_big();
    }
    if (splat_layers_ > 0)
        arena_.execute([&] {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, splat_values_, size_t(1) << 16), [&](const auto& r) {
                std::fill(splat_sum_ + r.begin(), splat_sum_ + r.end(), 0.0);
                std::fill(splat_sum2_ + r.begin(), splat_sum2_ + r.end(), 0.0);
            });
        });
}

void TiledIntegrator::RenderRun::sample_tile(size_t ti, long long first, long long count, bool keep) {
    const Tile& t = tiles_[ti];
    const int W = W_, stride = stride_, var_stride = var_stride_, batch = batch_;
    float* const mean = mean_->data;
    float* const m2 = m2_->data;
    const std::vector<SlotLayout::Run>& squared = layout_.squared;
    if (keep)
        tile_rows(t, [&](size_t s0, size_t s1, size_t q0, size_t q1) {
            std::copy(mean + s0, mean + s1, backup_mean_->data + s0);
            std::copy(m2 + q0, m2 + q1, backup_m2_->data + q0);
        });
    // Jobs in pixel order, sample order within a pixel, handed to
    // sample_batch() `batch` at a time (across pixels when passes are short);
    // each pixel's sums still add its samples in order.
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
    SplatList* splats = splat_layers_ > 0 ? &tile_splats_[ti] : nullptr;
    if (splats) splats->splats_.clear();
    uint64_t local_rays = 0, local_nan = 0, local_samples = 0;
    // Adds one sample's values `a`, the pixel's sample `k` + 1 of this
    // render, to pixel (x, y)'s running means `pm` and squared deviations
    // `pq`, or reports it if any value is not finite and adds it as zero.
    const auto add = [&](const float* a, int x, int y, long long k, float* pm, float* pq) __attribute__((always_inline)) {
        // Non-finite floats have all exponent bits set. Integer tests, unlike
        // float compares with NaN, vectorise.
        uint32_t bad = 0;
        for (int c = 0; c < stride; ++c) bad |= uint32_t((std::bit_cast<uint32_t>(a[c]) & 0x7f800000u) == 0x7f800000u);
        if (bad) [[unlikely]] {
            // A NaN/Inf sample is reported with its pixel and dropped as zero.
            ++local_nan;
            {
                std::lock_guard<std::mutex> lock(nan_mutex_);
                if (stats_.nonfinite_pixels.size() < 8) stats_.nonfinite_pixels.emplace_back(x, y);
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
        in_.sample_batch(scene_, jobs, n, vp, stride, local_rays);
        for (int j = 0; j < n; ++j) {
            const size_t at = size_t(jobs[j].y) * W + jobs[j].x;
            add(vp + size_t(j) * stride, jobs[j].x, jobs[j].y, job_taken[j], &mean[at * stride], &m2[at * var_stride]);
        }
        n = 0;
    };
    const bool one_at_a_time = batch == 1 && !use_jobs_;
    for (int y = t.y0; y < t.y1; ++y)
        for (int x = t.x0; x < t.x1; ++x) {
            float* pm = &mean[(size_t(y) * W + x) * stride];
            float* pq = &m2[(size_t(y) * W + x) * var_stride];
            if (first_pass_) {
                std::fill(pm, pm + stride, 0.f);
                std::fill(pq, pq + var_stride, 0.f);
            }
            const uint64_t pixel_stream = SampleKey{st_.seed, uint32_t(x), uint32_t(y), 0}.pixel_stream();
            const long long i0 = count_at(x, y, first), i1 = count_at(x, y, first + count);
            // The render's own samples of the pixel before its sample number i are i - before.
            const long long before = count_at(x, y, st_.first_sample);
            local_samples += uint64_t(i1 - i0);
            for (long long i = i0; i < i1; ++i) {
                if (one_at_a_time) {
                    // No job queue between the sample and its sums.
                    std::fill(vp, vp + stride, 0.f);
                    SampleJob one{x, y, Sampler(SampleKey::stream_of(pixel_stream, uint32_t(i)))};
                    one.index = uint32_t(i);
                    in_.sample_batch(scene_, &one, 1, vp, stride, local_rays);
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
    tile_done_[ti] = 1;
    tile_samples_[ti] = local_samples;
    rays_ += local_rays;
    nonfinite_ += local_nan;
    const uint64_t s = samples_ += local_samples;
    if (progress_) {
        Progress p;
        p.samples = s;
        p.seconds = seconds();
        p.fraction = timed_ ? std::min(1.0, p.seconds / st_.time_budget) : double(s) / double(total_samples_);
        progress_(p);
    }
}

bool TiledIntegrator::RenderRun::run_pass(long long first, long long count, bool abandonable) {
    std::atomic<bool> skipped{false};
    std::fill(tile_done_.begin(), tile_done_.end(), uint8_t(0));
    const bool keep = abandonable && !first_pass_;
    arena_.execute([&] {
        tbb::parallel_for(size_t(0), tiles_.size(), [&](size_t ti) {
            if (abandonable && (skipped.load(std::memory_order_relaxed) || cancelled() || aborted())) {
                skipped = true;
                return;
            }
            sample_tile(ti, first, count, keep);
        });
    });
    if (skipped) {
        undo_pass(keep);
        return false;
    }
    first_pass_ = false;
    add_splats();
    return true;
}

void TiledIntegrator::RenderRun::add_splats() {
    uint64_t bad = 0;
    for (size_t ti = 0; ti < tile_splats_.size(); ++ti)
        for (const SplatList::Splat& sp : tile_splats_[ti].splats_) {
            if (!(std::isfinite(sp.v[0]) && std::isfinite(sp.v[1]) && std::isfinite(sp.v[2]))) {
                ++bad;
                if (stats_.nonfinite_pixels.size() < 8)
                    stats_.nonfinite_pixels.emplace_back(int(sp.pixel % uint32_t(W_)), int(sp.pixel / uint32_t(W_)));
                continue;
            }
            const size_t at = (size_t(sp.pixel) * splat_layers_ + sp.layer) * 3;
            for (int c = 0; c < 3; ++c) {
                splat_sum_[at + c] += sp.v[c];
                splat_sum2_[at + c] += double(sp.v[c]) * double(sp.v[c]);
            }
        }
    nonfinite_ += bad;
}

void TiledIntegrator::RenderRun::undo_pass(bool keep) {
    for (size_t ti = 0; ti < tiles_.size(); ++ti) {
        if (!tile_done_[ti]) continue;
        samples_ -= tile_samples_[ti];
        if (keep)
            tile_rows(tiles_[ti], [&](size_t s0, size_t s1, size_t q0, size_t q1) {
                std::copy(backup_mean_->data + s0, backup_mean_->data + s1, mean_->data + s0);
                std::copy(backup_m2_->data + q0, backup_m2_->data + q1, m2_->data + q0);
            });
    }
}

bool TiledIntegrator::RenderRun::ensure_backup() {
    if (backup_mean_) return true;
    const double backup_bytes = double(npix_) * double(stride_ + var_stride_) * sizeof(float);
    if (have_ > 0.0 && need_ + backup_bytes > have_) return false;
    try {
        backup_mean_ = std::make_unique<HugeFloats>(npix_ * stride_);
        backup_m2_ = std::make_unique<HugeFloats>(npix_ * var_stride_);
    } catch (const std::bad_alloc&) {
        backup_mean_.reset();
        return false;
    }
    return true;
}

void TiledIntegrator::RenderRun::sample_passes() {
    // Passes are sized to last about st.stop_latency, measured as the render
    // goes (at most 16 samples per pixel): a cancel then waits at most about
    // that long. A pass predicted to last over 1.5 times as long (one sample
    // per pixel of a large or slow image) can be abandoned part-way and
    // undone from a copy of the sums, when memory allows one. The division
    // into passes does not change the image: every pixel still adds its
    // samples in order. Shorter passes cost throughput: passes of half a
    // second made a 32-spp Cornell box render 1.6% slower on one thread
    // than passes of 16 spp (benchmarks/ab.sh, 5 rounds).
    const double pass_seconds = std::max(0.0, st_.stop_latency), wait_seconds = 1.5 * pass_seconds;
    double seconds_per_spp = 0.0;  // of the last pass; 0 before the first
    const auto long_pass = [&](long long n) { return seconds_per_spp * double(n) >= wait_seconds; };
    // An abandoned first pass leaves nothing to undo, and no image: a render
    // needs a sample in every pixel, so render() then throws Interrupted.
    const auto pass = [&](long long first, long long n) {
        const auto t = seconds();
        const bool ok = run_pass(first, n, first_pass_ || (long_pass(n) && ensure_backup()));
        if (ok) seconds_per_spp = (seconds() - t) / double(n);
        return ok;
    };
    const auto next_count = [&](long long left) {
        if (!(seconds_per_spp > 0.0)) return std::min(left, 16LL);
        return std::clamp((long long)(pass_seconds / seconds_per_spp), 1LL, std::min(left, 16LL));
    };
    if (timed_) {
        // Whole passes of one sample per pixel until the budget is spent: an
        // equal-time comparison then compares complete images, not partial ones.
        do {
            if (!pass(st_.first_sample + done_, 1)) break;
            ++done_;
        } while (seconds() < st_.time_budget && !cancelled() && !aborted());
    } else {
        // The first pass takes one sample per pixel, to measure the rate.
        long long n = 1;
        while (done_ < st_.spp && !(done_ > 0 && (cancelled() || aborted()))) {
            if (!pass(st_.first_sample + done_, n)) break;
            done_ += n;
            n = next_count(st_.spp - done_);
        }
    }
    if (done_ == 0) throw Interrupted("the render was stopped before its first pass finished: there is no image to keep");
}

RenderStats TiledIntegrator::RenderRun::finish(FrameBuffer& out) {
    // Means and variances are read from the accumulators by finalize()
    // itself: a slot that only feeds a combined layer (G-PT's splats and
    // one-sided gradients) then costs no image of its own.
    Accumulated acc;
    acc.specs = specs_;
    acc.spp = done_;
    acc.derived = !aborted();
    acc.width = W_, acc.height = H_;
    acc.mean_ = mean_->data, acc.m2_ = m2_->data;
    std::vector<uint32_t> counts;
    if (density_) {
        counts.resize(npix_);
        for (int y = 0; y < H_; ++y)
            for (int x = 0; x < W_; ++x)
                counts[size_t(y) * W_ + x] =
                    uint32_t(count_at(x, y, st_.first_sample + done_) - count_at(x, y, st_.first_sample));
        acc.counts_ = counts.data();
    }
    acc.stride_ = stride_, acc.var_stride_ = var_stride_;
    acc.offset_ = layout_.offset, acc.var_offset_ = layout_.var_offset;
    acc.splat_sum_ = splat_sum_, acc.splat_sum2_ = splat_sum2_, acc.splat_layers_ = splat_layers_;
    out = FrameBuffer(W_, H_);
    // The mask fixed which pixels have gradients: a resumed or merged render
    // needs the same, and finalize()'s reconstructions read it.
    if (mask_) out.set("gradient_mask", *mask_);
    arena_.execute([&] { in_.finalize(acc, out); });
    if (density_) {
        // Each pixel's own count, and the density that fixed it (a resumed or
        // merged render needs it to continue each pixel's sample numbers).
        out.set("spp", acc.count_image());
        out.set("sample_density", *density_);
    } else {
        out.add("spp", 1);
        std::fill(out.get("spp").values().begin(), out.get("spp").values().end(), float(done_));
    }
    out.metadata()["spp"] = std::to_string(done_);
    out.metadata()["seed"] = std::to_string(st_.seed);
    out.metadata()["first_sample"] = std::to_string(st_.first_sample);
    out.metadata()["integrator_params"] = in_.describe();
    // The layers derived from the means (reconstructions) last, after large
    // accumulators are freed: their solvers' memory then reuses the
    // accumulators' instead of adding to it.
    backup_mean_.reset(), backup_m2_.reset();
    if (in_.buffers_->bytes() > kKeptBufferBytes) in_.release_buffers();
    if (acc.derived) arena_.execute([&] { in_.update_merged(out); });

    stats_.seconds = seconds();
    stats_.samples = samples_;
    stats_.rays = rays_;
    stats_.nonfinite = nonfinite_;
    stats_.spp = done_;
    return stats_;
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
    check_settings(st, scene.camera().width(), scene.camera().height());
    density_ = st.sample_density;
    mask_ = st.gradient_mask;
    prepare(scene);
    begin_render(scene, st);
    RenderRun run(*this, scene, st, progress);
    run.allocate();
    run.sample_passes();
    return run.finish(out);
}
}  // namespace gdr
