// The base of the tiled integrators (gdr/integrators/tiled.h): parameters,
// settings checks, the kept accumulation buffers, the accumulated means'
// reader and the default finalize(). One render's pass loop is tiled_run.cpp.
#include "gdr/integrators/tiled.h"

#include <algorithm>
#include <memory>

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include "tiled_storage.h"

namespace gdr {

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
