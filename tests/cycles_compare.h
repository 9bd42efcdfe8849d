// Comparison of a render with Blender Cycles' block means: tests/data/
// cycles-*.json hold Cycles' block means of a scene and their standard
// errors (scripts/cycles/reference.py: Lambertian Kd, one-sided Ke, box
// filter, no clamping; 8 runs x 256 spp). A render's block means come with
// variances from its per-pixel variance layer ("variance", per sample) and
// its "spp" layer.
#pragma once

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "gdr/core/image.h"

namespace gdr::test {

/// Threshold |z| for `tests` two-sided tests at family-wise level 1e-3
/// (Bonferroni), from the normal tail; 4.0 at one test, ~5.3 at 1000.
inline double z_threshold(int tests) {
    const double alpha = 1e-3 / tests;
    double z = 3.0;
    while (std::erfc(z / std::sqrt(2.0)) > alpha) z += 0.01;
    return z;
}

/// Cycles' block means of one scene (tests/data/NAME).
struct CyclesReference {
    nlohmann::json data;
    int block = 0, blocks_x = 0, blocks = 0, width = 0, height = 0;
    /// Reads tests/data/`name`; throws if it is missing.
    explicit CyclesReference(const std::string& name) {
        std::ifstream in(std::string(GDR_SOURCE_DIR "/tests/data/") + name);
        if (!in) throw std::runtime_error("missing Cycles reference " + name);
        data = nlohmann::json::parse(in);
        block = data["block"], blocks_x = data["blocks_x"], blocks = int(data["mean"].size());
        width = data["width"], height = data["height"];
    }
};

/// Largest |z| over the blocks and channels, and over the image's channel means.
struct CyclesWorst {
    double block = 0.0, image = 0.0;
};

/// The render's block means, scaled by `gain` (1: as rendered), against Cycles'.
inline CyclesWorst compare_with_cycles(const FrameBuffer& fb, const CyclesReference& ref, double gain) {
    const Image &c = fb.get("color"), &v = fb.get("variance");
    const double spp = fb.get("spp").at(0, 0), n = double(ref.block) * ref.block;
    CyclesWorst worst;
    for (int ch = 0; ch < 3; ++ch) {
        double image_mean = 0.0, image_var = 0.0;
        for (int i = 0; i < ref.blocks; ++i) {
            const int x0 = (i % ref.blocks_x) * ref.block, y0 = (i / ref.blocks_x) * ref.block;
            double m = 0.0, var = 0.0;
            for (int y = y0; y < y0 + ref.block; ++y)
                for (int x = x0; x < x0 + ref.block; ++x) m += c.at(x, y, ch) / n, var += v.at(x, y, ch) / spp / (n * n);
            const double rm = ref.data["mean"][i][ch], rs = ref.data["stderr"][i][ch];
            worst.block = std::max(worst.block, std::abs(gain * m - rm) / std::sqrt(std::max(gain * gain * var + rs * rs, 1e-14)));
            image_mean += m / ref.blocks, image_var += var / (double(ref.blocks) * ref.blocks);
        }
        const double rm = ref.data["image_mean"][ch], rs = ref.data["image_stderr"][ch];
        worst.image = std::max(worst.image, std::abs(gain * image_mean - rm) / std::sqrt(std::max(gain * gain * image_var + rs * rs, 1e-14)));
    }
    return worst;
}

}  // namespace gdr::test
