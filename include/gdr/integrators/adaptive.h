// Adaptive sampling by gradient variance: where to put a render's samples,
// from a pilot render, after Manzi, Kettunen, Durand, Zwicker and Lehtinen,
// "Temporal Gradient-Domain Path Tracing" (2016), whose finding is that a
// screened Poisson reconstruction's error follows the variance of the
// gradients, not of the colours (ALGORITHMS.md section 6).
#pragma once

#include "gdr/core/image.h"
#include "gdr/integrators/integrator.h"

namespace gdr {

/// Options of adaptive_sample_density().
struct AdaptiveOptions {
    /// What the error is read from: the gradients' variances (dx_variance,
    /// dy_variance: the publication's rule), the primal's (primal_variance,
    /// or pt's variance: ordinary colour-based adaptive sampling), or Auto:
    /// the gradients where the pilot has them, else the primal.
    enum class Source { Auto, Gradients, Primal };
    Source source = Source::Auto;
    double uniform = 0.25;      ///< Share of the samples spread evenly (a density floor; 0..1).
    double max_density = 8.0;   ///< Most a pixel may take, as a multiple of the mean (the publication's cap).
    double epsilon = 1e-3;      ///< Added to the squared local brightness (radiance^2): dark pixels do not take everything.
    int median_radius = 2;      ///< Half-width of the median filter of the raw densities (2: 5x5).
};

/// A relative sample density per pixel (1 channel, mean 1, between the
/// uniform floor and max_density) for RenderSettings::sample_density, from
/// the layers of a pilot render. The error of pixel p is the sum over RGB of
/// the per-sample variances of the gradients on its four edges (or of its
/// primal), relative to the squared brightness L^2 + epsilon of its 5x5
/// neighbourhood; its density is proportional to the square root of that
/// error, the allocation that minimises the sum of the pixels' relative
/// variances for a fixed number of samples, then median-filtered and
/// smoothed with [.1 .2 .4 .2 .1] (as the publication does) so that one noisy
/// pilot pixel does not decide alone. Throws ParameterError naming a missing
/// layer or a bad option.
Image adaptive_sample_density(const FrameBuffer& pilot, const AdaptiveOptions& options = {});

/// How render_adaptive() spends its budget.
struct AdaptiveRender {
    double pilot = 0.125;     ///< Share of the budget (samples or seconds) given to the pilot render (0..0.5).
    AdaptiveOptions density;  ///< How the pilot becomes a density.
    /// Also keep the pilot's samples, merged pixel by pixel into the result
    /// (as the publication does). Consistent but not unbiased: a pixel whose
    /// pilot was unlucky gets a density that depends on it. The result is
    /// then of mixed density ("sample_density" metadata "mixed") and cannot
    /// be resumed.
    bool keep_pilot = false;
};

/// Renders with adaptive sampling in two steps: a pilot render of uniform
/// samples with a seed of its own (a share of the samples, or of the time
/// budget but at least 4 passes), whose layers give the sample density (adaptive_sample_density()),
/// then the render itself with that density and the rest of the budget. The
/// pilot's samples are not kept: the density is then independent of the
/// samples it distributes, so each pixel's estimate is exactly unbiased
/// (keeping them would bias the pixels whose pilot was unlucky). `out` is the
/// second render, with its "sample_density" layer and metadata entries
/// "adaptive_pilot_spp" and "adaptive_pilot_seconds"; the statistics count
/// both renders. A resumed render passes the stored density directly
/// (RenderSettings::sample_density) instead.
RenderStats render_adaptive(Integrator& integrator, const Scene& scene, const RenderSettings& settings,
                            FrameBuffer& out, const AdaptiveRender& adaptive = {}, const ProgressFn& progress = {});

/// The seed of render_adaptive()'s pilot for a render of seed `seed`: a
/// stream of its own, so the pilot never repeats the render's samples.
uint64_t pilot_seed(uint64_t seed);

}  // namespace gdr
