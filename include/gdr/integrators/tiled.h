// A base for integrators that estimate per-pixel quantities sample by sample.
// It owns the parallel tile loop, time budgets, progress, NaN accounting and
// mean/variance accumulation; subclasses only say what one sample computes.
// Each sample writes only its own pixel's slots, so results are bit-identical
// for any thread count (neighbour splats are gathered in finalize()).
#pragma once

#include <memory>
#include <string>
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

/// Per-pixel means (and per-sample variances) of every slot after a render.
struct Accumulated {
    std::vector<SlotSpec> specs;     ///< As declared by the integrator.
    std::vector<Image> mean;         ///< Mean per slot.
    std::vector<Image> variance;     ///< Per-sample variance per slot (empty image if not tracked).
    long long spp = 0;               ///< Samples per pixel.
    /// The mean image of a slot by name.
    const Image& mean_of(const std::string& name) const;
    /// The variance image of a slot by name.
    const Image& variance_of(const std::string& name) const;
};

/// Integrator skeleton: subclasses declare slots and implement sample().
/// The accumulation buffers (per-pixel sums and squared sums, in double) are
/// kept from one render to the next while their size fits: a frame sequence,
/// an equal-time series or progressive passes then reuse warm pages instead of
/// faulting in fresh ones, which on a virtual machine can cost as much as a
/// few samples per pixel. release_buffers() returns the memory. Because of
/// them, one object renders one image at a time: concurrent renders need one
/// integrator each.
class TiledIntegrator : public Integrator {
public:
    TiledIntegrator();
    ~TiledIntegrator() override;
    RenderStats render(const Scene& scene, const RenderSettings& settings, FrameBuffer& out,
                       const ProgressFn& progress) final;
    /// Frees the accumulation buffers kept from the last render (bytes freed).
    size_t release_buffers();

protected:
    /// The slots each sample writes, in order.
    virtual std::vector<SlotSpec> slots() const = 0;
    /// Computes one sample of pixel (x, y) with `sampler` (already keyed to the
    /// pixel and sample index) and writes all slots consecutively to `out`
    /// (zero-initialised); adds the rays it cast to `rays`.
    virtual void sample(const Scene& scene, int x, int y, Sampler& sampler, float* out, uint64_t& rays) const = 0;
    /// Turns accumulated slots into output layers; the default writes each slot
    /// as a layer of its name and its variance as "<name>_variance".
    virtual void finalize(const Accumulated& acc, FrameBuffer& out) const;
    /// Called once before the first sample (e.g. to precompute per-scene data).
    virtual void prepare(const Scene& scene) {}

private:
    struct Buffers;
    std::unique_ptr<Buffers> buffers_;
};

}  // namespace gdr
