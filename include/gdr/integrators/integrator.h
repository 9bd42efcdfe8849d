// Integrator interface, render settings and statistics, the integrator
// registry, and merging of partial renders.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "gdr/core/image.h"
#include "gdr/core/params.h"
#include "gdr/registry.h"
#include "gdr/scene/scene.h"

namespace gdr {

/// How an integrator that shares random numbers between consecutive frames of
/// an animation (tgpt) keys its samplers in one frame: temporal seed sharing
/// of Manzi, Kettunen, Durand, Zwicker and Lehtinen, "Temporal
/// Gradient-Domain Path Tracing" (2016), docs/algorithms.md, "Temporal".
struct FrameSampling {
    uint64_t next_seed = 0;  ///< The next frame's own sampler seed (its RenderSettings::seed).
    /// 2 channels per pixel, or empty: the pixel (column, row) of the previous
    /// frame whose random numbers this frame's first half replays at that
    /// pixel, (-1, -1) where the pixel has no correspondence and uses its own.
    Image replay;
};

/// How much to render and how.
struct RenderSettings {
    long long spp = 16;            ///< Samples per pixel to take (ignored when time_budget > 0).
    double time_budget = 0.0;      ///< Wall-clock seconds; > 0 renders whole passes until it is spent.
    int threads = 0;               ///< Worker threads; 0 = all cores.
    uint64_t seed = 0;             ///< Sampler seed.
    long long first_sample = 0;    ///< Index of the first sample per pixel (resuming continues the sequence).
    /// If set and true, the render stops within about a second and returns
    /// what it has (an interrupted render is still a valid, resumable image):
    /// after the pass under way, or, for a long pass, by abandoning it.
    const std::atomic<bool>* cancel = nullptr;
    /// If set and true, the render stops at once: the pass under way is
    /// abandoned where it can be undone, and if no pass has finished,
    /// render() throws Interrupted.
    const std::atomic<bool>* abort = nullptr;
    /// About how long (s) a cancel waits for the pass under way: passes are
    /// sized to it, and a pass predicted to take over 1.5 times as long (one
    /// sample per pixel of a large image) is abandoned and undone instead,
    /// from a copy of the sums taken only for such passes. Does not change
    /// the image.
    double stop_latency = 1.0;
    /// Seed sharing with the neighbouring frames, for integrators whose
    /// shares_frame_samples() is true; nullptr: a still (the next seed is
    /// then derived from `seed`, and no pixel replays another's numbers).
    const FrameSampling* frame_sampling = nullptr;
    /// Relative sample density per pixel for adaptive sampling (1 channel, the
    /// camera's size, finite, 0 to kMaxSampleDensity; mean 1 keeps `spp` the
    /// average count), or nullptr for uniform sampling. A render of J passes
    /// (J = spp, or as many as the time budget allows) from first_sample on
    /// gives pixel p the sample numbers sample_count(first_sample, d(p)) to
    /// sample_count(first_sample + J, d(p)) - 1; each pixel's estimate divides
    /// by its own count, so it stays unbiased for any density fixed before the
    /// render (adaptive_sample_density() makes one from a pilot render).
    const Image* sample_density = nullptr;
    /// Where an integrator with gradients (gpt) takes them (1 channel, the
    /// camera's size, each value 0 or 1), or nullptr for everywhere: a pixel
    /// of value 0 takes primal-only samples (no shifted paths, a path
    /// tracer's cost), and the pair of neighbours across each of its edges is
    /// treated like the image border (its gradient is not estimated, the base
    /// path estimates its own pixel alone), so every pixel stays unbiased.
    /// Integrators without gradients refuse it. Thesis section 4.3.2;
    /// select_gradient_pixels() makes one from pilot renders.
    const Image* gradient_mask = nullptr;
};

/// Largest relative sample density a pixel may ask for (RenderSettings::sample_density).
constexpr float kMaxSampleDensity = 256.f;

/// Samples a pixel of relative density `density` holds after `passes` passes
/// of adaptive sampling: 0 before the first pass, then max(1, round(passes *
/// density)), which never decreases as passes are added, so a render resumed
/// from a pass count continues the pixel's sample numbers without a gap.
inline long long sample_count(long long passes, float density) {
    if (passes <= 0) return 0;
    const long long n = (long long)(double(passes) * double(density) + 0.5);
    return n < 1 ? 1 : n;
}

/// Progress of a running render, reported from worker threads.
struct Progress {
    double fraction = 0.0;        ///< Done fraction in [0,1] (of spp, or of the time budget).
    uint64_t samples = 0;         ///< Pixel samples finished so far.
    double seconds = 0.0;         ///< Wall time since the start.
};

/// Callback receiving progress; must be thread-safe and cheap.
using ProgressFn = std::function<void(const Progress&)>;

/// What a render did.
struct RenderStats {
    double seconds = 0.0;          ///< Wall time of the render.
    uint64_t samples = 0;          ///< Pixel samples taken (all pixels).
    uint64_t rays = 0;             ///< Rays cast (intersection + shadow).
    uint64_t nonfinite = 0;        ///< Samples that were NaN or Inf (dropped as zero).
    std::vector<std::pair<int, int>> nonfinite_pixels;  ///< First few pixels (x, y) where that happened.
    long long spp = 0;             ///< Samples per pixel taken in this render.
};

/// An image-synthesis algorithm. Writes named layers into a FrameBuffer sized
/// like the camera; colour layers hold radiance (W/(m^2 sr)) per pixel.
class Integrator {
public:
    virtual ~Integrator() = default;
    /// Renders with the given settings; the buffer is cleared first. Layers are
    /// means over the samples taken, plus an "spp" metadata entry.
    virtual RenderStats render(const Scene& scene, const RenderSettings& settings, FrameBuffer& out,
                               const ProgressFn& progress = {}) = 0;
    /// The integrator's parameters as "key=value" lines (written to file headers).
    virtual std::string describe() const = 0;
    /// Computes, in `merged`, the layers that are not means of samples
    /// (reconstructions: an L1 reconstruction is not the average of two) from
    /// its means: called at the end of every render (after its spp layer is
    /// set) and after merge_renders() pooled two renders of this integrator.
    virtual void update_merged(FrameBuffer& merged) const { (void)merged; }
    /// True if a frame of an animation should be rendered with its
    /// RenderSettings::frame_sampling filled in (see FrameSampling).
    virtual bool shares_frame_samples() const { return false; }
};

/// The process-wide integrator registry, with the built-ins registered on first use.
Registry<Integrator>& integrator_registry();
/// Adds gdr's built-in integrators (pt, gpt, ...) to a registry.
void register_builtin_integrators(Registry<Integrator>& r);

/// Combines two renders of the same scene and integrator made with
/// independent samples: mean layers are averaged weighted by sample counts,
/// layers whose name ends in "variance" are pooled (per-sample variances).
/// Adaptive renders (with a "sample_density" layer, equal in both) are
/// weighted pixel by pixel by their "spp" layers. Both need "spp" metadata;
/// throws ParameterError if they do not match.
/// Layers that are not means (reconstructions) are then stale: call the
/// integrator's update_merged() on the result.
void merge_renders(FrameBuffer& into, const FrameBuffer& other);

}  // namespace gdr
