// A base for integrators that estimate per-pixel quantities sample by sample.
// It owns the parallel tile loop, time budgets, progress, NaN accounting and
// mean/variance accumulation; subclasses only say what one sample computes.
// Each sample writes its own pixel's slots, and splats to other pixels are
// added in a fixed order, so results are bit-identical for any thread count
// (G-PT's neighbour gradients are gathered in finalize()).
#pragma once

#include <algorithm>
#include <atomic>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "gdr/core/sampler.h"
#include "gdr/integrators/integrator.h"

namespace gdr {

/// One accumulated per-pixel quantity.
struct SlotSpec {
    std::string name;       ///< Layer name (and prefix of its "<name>_variance" layer).
    int channels = 3;       ///< 1..4 channels.
    bool variance = false;  ///< Also track the per-sample variance.
};

/// Contributions of samples to pixels other than their own: light
/// tracing's t = 1 connections land wherever the light subpath is seen from.
/// They are gathered per tile and added to the film after each pass in tile
/// order, so that images stay bit-identical for any thread count and batch
/// size. Each is one sample's estimate for the pixel it lands in, in the
/// units of the integrator's colour slot; the film divides their sum by the
/// samples per pixel, as it divides a slot's.
class SplatList {
public:
    /// Adds `value` at film point `film` (pixel units) to splat layer
    /// `layer` (0 .. splat_layers() - 1); a point outside the film is dropped.
    void add(const Vec2& film, const Color& value, int layer = 0) {
        if (!(film.x >= 0.f && film.y >= 0.f && film.x < float(width_) && film.y < float(height_))) return;
        const uint32_t px = std::min(uint32_t(film.x), uint32_t(width_ - 1));
        const uint32_t py = std::min(uint32_t(film.y), uint32_t(height_ - 1));
        splats_.push_back({py * uint32_t(width_) + px, uint32_t(layer), {value.r, value.g, value.b}});
    }

private:
    friend class TiledIntegrator;
    struct Splat {
        uint32_t pixel, layer;
        float v[3];
    };
    std::vector<Splat> splats_;
    int width_ = 0, height_ = 0;
};

/// The per-pixel running means and squared deviations of a finished render,
/// read as means and per-sample variances of its slots. It reads the
/// render's accumulators in place: finalize() takes what it needs straight
/// from them, so a slot that only feeds a combined layer never becomes an
/// image of its own. Valid only during finalize().
class Accumulated {
public:
    std::vector<SlotSpec> specs;  ///< As declared by the integrator.
    /// Samples per pixel; under adaptive sampling, the passes taken (each
    /// pixel's own number is count()).
    long long spp = 0;
    int width = 0;                ///< Columns.
    int height = 0;               ///< Rows.
    /// Whether layers derived from the means (reconstructions) are wanted:
    /// false when the render was aborted, so that it stops at once; they
    /// can be recomputed later (Integrator::update_merged).
    bool derived = true;

    /// Index of a slot by name; throws ParameterError naming it if absent.
    int slot(const std::string& name) const;
    /// Samples pixel (x, y) holds: spp, or its own count under adaptive sampling.
    long long count(int x, int y) const { return counts_ ? (long long)counts_[pixel(x, y)] : spp; }
    /// True if pixels hold counts of their own (adaptive sampling).
    bool adaptive() const { return counts_ != nullptr; }
    /// Every pixel's count() as a one-channel image (the "spp" layer).
    Image count_image() const;
    /// Mean of channel `c` of slot `s` at pixel (x, y), in the slot's units
    /// (the pixel's sum over its own sample count).
    float mean(int s, int x, int y, int c) const { return mean_[pixel(x, y) * stride_ + offset_[s] + c]; }
    /// Per-sample variance of channel `c` of slot `s` at (x, y), in the slot's
    /// units squared; the slot must track a variance.
    float variance(int s, int x, int y, int c) const {
        const double n = double(count(x, y));
        const double m2 = m2_[pixel(x, y) * var_stride_ + var_offset_[s] + c];
        return n > 1.0 ? float(std::max(0.0, m2 / (n - 1.0))) : 0.f;
    }
    /// Mean of the first three channels of slot `s` at (x, y).
    Color mean_rgb(int s, int x, int y) const { return {mean(s, x, y, 0), mean(s, x, y, 1), mean(s, x, y, 2)}; }
    /// Per-sample variance of the first three channels of slot `s` at (x, y).
    Color variance_rgb(int s, int x, int y) const {
        return {variance(s, x, y, 0), variance(s, x, y, 1), variance(s, x, y, 2)};
    }
    /// Mean of splat layer `layer` at (x, y): the sum of the splats that
    /// landed there over the samples per pixel (the integrator's colour units).
    Color splat_mean(int layer, int x, int y) const {
        const double* a = &splat_sum_[(pixel(x, y) * splat_layers_ + layer) * 3];
        return {float(a[0] / double(spp)), float(a[1] / double(spp)), float(a[2] / double(spp))};
    }
    /// Per-sample variance of splat layer `layer` at (x, y), as the sum of
    /// the squared splats over the samples per pixel: the splats of one
    /// sample index come from independent light subpaths, each with a mean
    /// far below its spread, so their sum's variance is the sum of their
    /// second moments (it omits the squared means, an overestimate below 1/W*H).
    Color splat_variance(int layer, int x, int y) const {
        const double* a = &splat_sum2_[(pixel(x, y) * splat_layers_ + layer) * 3];
        return {float(a[0] / double(spp)), float(a[1] / double(spp)), float(a[2] / double(spp))};
    }
    /// One image images() computes: a slot's mean, or its per-sample variance.
    struct Want {
        std::string slot;       ///< Slot name.
        bool variance = false;  ///< The variance (the slot must track one) instead of the mean.
    };
    /// The wanted images, in order, computed in one parallel pass over the sums;
    /// throws ParameterError naming an unknown slot or one without a variance.
    std::vector<Image> images(const std::vector<Want>& wanted) const;

private:
    friend class TiledIntegrator;
    size_t pixel(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
    const float* mean_ = nullptr;  // per pixel: `stride_` running means, slots in order
    const uint32_t* counts_ = nullptr;  // per pixel: samples taken (adaptive sampling), or nullptr: spp each
    const float* m2_ = nullptr;  // per pixel: `var_stride_` sums of squared deviations from the mean (Welford)
    int stride_ = 0, var_stride_ = 0;
    std::vector<int> offset_, var_offset_;  // per slot: first channel in the sums / the squared sums (-1: none)
    const double* splat_sum_ = nullptr;   // per pixel and splat layer: 3 sums of splats
    const double* splat_sum2_ = nullptr;  // ... and of their squares
    int splat_layers_ = 0;
};

/// Integrator skeleton: subclasses declare slots and implement sample_batch().
/// The accumulation buffers (per-pixel running means and squared deviations,
/// 8 bytes a channel with a variance and 4 without) are kept from one render
/// to the next while their size fits and is below kKeptBufferBytes: a frame
/// sequence, an equal-time series or progressive passes then reuse warm pages
/// instead of faulting in fresh ones, which on a virtual machine can cost as
/// much as a few samples per pixel. Larger ones are freed before the derived
/// layers (reconstructions) are computed, so that the two never coexist.
/// release_buffers() returns the memory. Because of them, one object renders
/// one image at a time: concurrent renders need one integrator each.
class TiledIntegrator : public Integrator {
public:
    TiledIntegrator();
    ~TiledIntegrator() override;
    RenderStats render(const Scene& scene, const RenderSettings& settings, FrameBuffer& out,
                       const ProgressFn& progress) final;
    /// Frees the accumulation buffers kept from the last render (bytes freed).
    size_t release_buffers();
    /// Largest accumulation buffers (bytes) a render keeps for the next one;
    /// larger ones are freed before its derived layers are computed.
    static constexpr size_t kKeptBufferBytes = size_t(512) << 20;

protected:
    /// The slots each sample writes, in order.
    virtual std::vector<SlotSpec> slots() const = 0;
    /// One sample to compute: its pixel and its sampler (keyed to the pixel
    /// and sample index).
    struct SampleJob {
        int x = 0, y = 0;  ///< Pixel column and row.
        Sampler sampler;   ///< The sample's stream, at dimension 0.
        /// Where the sample's splats go (the tile's list) when the
        /// integrator has splat layers; nullptr otherwise.
        SplatList* splats = nullptr;
        /// The sample's number within its pixel.
        uint32_t index = 0;
    };
    /// Computes jobs[0..n) (n <= batch_size(), so one at a time unless the
    /// integrator asks for more), job i writing all its slots consecutively to
    /// out + i * stride (zero-initialised) with its sampler (keyed to the
    /// pixel and sample number); adds the rays cast to `rays`. The one entry
    /// point render() calls. An integrator whose sample runs through more code
    /// than the instruction cache holds takes several jobs and runs the stages
    /// of all in turn; results must not depend on n.
    virtual void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                              uint64_t& rays) const = 0;
    /// Number of splat layers (SplatList) the samples write, each three
    /// channels; 0 for an integrator that writes only its own pixel's slots.
    /// An integrator with splat layers implements sample_batch(), which is
    /// then always called, and reads them in finalize() (Accumulated::splat_mean).
    virtual int splat_layers() const { return 0; }
    /// The most jobs render() passes to sample_batch() at once (at most 16).
    virtual int batch_size() const { return 1; }
    /// True if sample_batch() must be called even for one job at a time (an
    /// integrator that keys further samplers by the job's index); always
    /// so with splat layers.
    virtual bool jobs_only() const { return false; }
    /// An integrator's `batch` parameter (jobs per sample_batch() call),
    /// `max_batch` by default; throws ParameterError naming integrator `who`
    /// outside 1..max_batch.
    static int batch_param(const Params& p, const std::string& who, int max_batch);
    /// Longest path a depth parameter may ask for (segments).
    static constexpr long long kMaxDepth = 1 << 16;
    /// Reads "max_depth" (-1 for unlimited, else 1 to kMaxDepth; default -1)
    /// and "rr_depth" (1 to kMaxDepth; default 5) for integrator `who`, as
    /// {max_depth, rr_depth}; throws a ParameterError naming the key otherwise
    /// (a huge value must not wrap around when narrowed to int).
    static std::pair<int, int> depth_params(const Params& p, const std::string& who);
    /// Turns accumulated slots into output layers; the default writes each slot
    /// as a layer of its name and its variance as "<name>_variance". Runs in
    /// the render's thread arena, so its parallel loops keep to its threads.
    virtual void finalize(const Accumulated& acc, FrameBuffer& out) const;
    /// Called once before the first sample (e.g. to precompute per-scene data).
    virtual void prepare(const Scene& scene) {}
    /// Called once before the first sample, after prepare(), with the render's
    /// settings (e.g. for an integrator that keys samplers of its own by the seeds).
    virtual void begin_render(const Scene& scene, const RenderSettings& settings) {}
    /// The relative sample density of pixel (x, y) in the render under way
    /// (RenderSettings::sample_density; 1 when sampling is uniform), for
    /// estimators whose weights depend on the ratio of neighbours' sample counts.
    float sample_density(int x, int y) const {
        return density_ ? density_->at(x, y, 0) : 1.f;
    }
    /// True while the render under way samples adaptively.
    bool adaptive() const { return density_ != nullptr; }
    /// True if the integrator honours RenderSettings::gradient_mask; render()
    /// refuses a mask otherwise.
    virtual bool takes_gradient_mask() const { return false; }
    /// Whether pixel (x, y) takes gradient samples in the render under way
    /// (RenderSettings::gradient_mask; true everywhere without one).
    bool gradients_at(int x, int y) const { return !mask_ || mask_->at(x, y, 0) != 0.f; }
    /// True while the render under way has a gradient mask.
    bool masked() const { return mask_ != nullptr; }

private:
    // Throws ParameterError naming what is wrong with `st` for a W x H
    // render: sample counts, the sample density's and the gradient mask's
    // size and values, and whether this integrator takes them.
    void check_settings(const RenderSettings& st, int W, int H) const;
    struct Buffers;
    std::unique_ptr<Buffers> buffers_;
    class RenderRun;  // one render(): its accumulators, tiles and passes (tiled.cpp)
    const Image* density_ = nullptr;  // RenderSettings::sample_density of the render under way
    const Image* mask_ = nullptr;     // RenderSettings::gradient_mask of the render under way
    // Set while render() runs: a second, concurrent render() of the same
    // object would share the accumulators, so it is refused instead.
    std::atomic<bool> rendering_{false};
};

}  // namespace gdr
