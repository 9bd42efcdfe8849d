// The header a stored render carries (the EXR's string attributes): what
// gdr render writes and what gdr info, gdr render --resume and gdr merge
// read back, shared by the gdr tool and the Python module so that a render
// stored by either is accepted by the other.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gdr/core/image.h"

namespace gdr {

/// The "seed" (and "first_sample") metadata of a render merged from several
/// seeds: it has no single sample sequence, so --resume refuses it; its
/// "sample_ranges" entry says which samples it holds.
inline const std::string kMixedSeeds = "mixed";

/// A run of consecutive sample numbers of one seed, taken in every pixel.
struct SampleRange {
    uint64_t seed = 0;   ///< Sampler seed.
    uint64_t first = 0;  ///< Number of the first sample in each pixel.
    uint64_t count = 0;  ///< Samples per pixel in the run.
};

/// `ranges` as the "sample_ranges" header entry: "seed:first:count", comma-separated.
std::string format_sample_ranges(const std::vector<SampleRange>& ranges);
/// `ranges` sorted by seed and first sample, with adjacent runs of one seed joined.
std::vector<SampleRange> normalized_ranges(std::vector<SampleRange> ranges);

/// What a fresh render records beside the settings its integrator writes
/// ("spp", "seed", "first_sample", "integrator_params").
struct RenderRecord {
    std::string integrator;   ///< Registered integrator name.
    std::string scene;        ///< The scene's file (absolute path) or another name of its source.
    std::string scene_hash;   ///< SceneFile::content_hash ("" if unknown: merges then compare `scene`).
    double seconds = 0.0;     ///< Wall time of the render (s).
    double time_budget = 0.0; ///< The time asked for (s), 0 for a render of a sample count.
    uint64_t target_spp = 0;  ///< One past the last sample number asked for, 0 for a time budget.
    SampleRange samples;      ///< The samples taken in every pixel.
    bool interrupted = false; ///< Stopped before its target.
    std::string version;      ///< gdr's version that rendered it.
};

/// Adds `r` to `fb`'s metadata as the keys gdr render writes ("integrator",
/// "scene", "scene_hash", "render_seconds", "time_budget", "target_spp",
/// "sample_ranges", "gdr_version", "interrupted").
void write_render_record(FrameBuffer& fb, const RenderRecord& r);

/// The layer a render's preview shows: the reconstruction of a
/// gradient-domain render (neural if it has one, else variance-weighted, else
/// L1), else its colour.
std::string preview_layer(const FrameBuffer& fb);

}  // namespace gdr
