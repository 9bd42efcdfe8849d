// Adaptive sampling by gradient variance: where to put a render's samples,
// from a pilot render, after Manzi, Kettunen, Durand, Zwicker and Lehtinen,
// "Temporal Gradient-Domain Path Tracing" (2016), whose finding is that a
// screened Poisson reconstruction's error follows the variance of the
// gradients, not of the colours (docs/algorithms.md, "Temporal").
#pragma once

#include <string>

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

/// Options of select_gradient_pixels().
struct GradientSelectOptions {
    /// How a tile's variance with gradients is found: measured, as the spread
    /// between the reconstructions of two independent pilots (whatever the
    /// reconstruction does: L1, outlier rejection), or modelled from the
    /// variance layers as the weighted L2 solve's (see select_gradient_pixels()).
    enum class Criterion { Measured, Model };
    Criterion criterion = Criterion::Model;
    int tile = 16;             ///< Side of the square blocks decided together (pixels, >= 1).
    double max_density = 8.0;  ///< Most samples a primal-only pixel takes per gradient pixel's (>= 1).
    /// Criterion::Measured: the reconstructor whose variance is measured (any
    /// registered name, with its defaults; a pilot's own layer of it,
    /// reconstruction_layer(method), is reused where the pilot has one).
    std::string method = "poisson-weighted";
};

/// Two independent pilots of each kind for Criterion::Measured: renders of
/// one scene with different seeds, the two of a kind with equal passes.
struct SelectionPilots {
    const FrameBuffer* gradient[2] = {nullptr, nullptr};  ///< gpt renders with gradients everywhere.
    const FrameBuffer* primal[2] = {nullptr, nullptr};    ///< gpt renders with an all-zero mask.
    long long gradient_passes = 0, primal_passes = 0;     ///< Passes of each render of a kind.
    double gradient_seconds_per_pass = 0.0;               ///< Wall time of one gradient pass (s).
    double primal_seconds_per_pass = 0.0;                 ///< Wall time of one primal-only pass (s).
};

/// Where gradients pay, and the densities that give every pixel the same time.
struct GradientSelection {
    Image mask;            ///< RenderSettings::gradient_mask: 1 where gradients pay, 0 elsewhere.
    Image density;         ///< RenderSettings::sample_density (mean 1): primal-only pixels take cost_ratio times as many.
    double cost_ratio = 1.0;      ///< Seconds per gradient sample over seconds per primal-only sample (unitless).
    double gradient_share = 1.0;  ///< Fraction of the pixels that take gradients (0..1).
};

/// Colour-gradient selection (Kettunen's thesis "Gradient-Domain Methods for
/// Realistic Image Synthesis", 2020, section 4.3.2): per tile, whether the
/// gradients' variance reduction per second beats the primal's. From a pilot
/// of gradient samples (gpt: primal_variance vp, dx_variance, dy_variance vg,
/// per sample) and one of primal-only samples (gpt with an all-zero mask:
/// primal_variance vpt), with their seconds per pass tg and tpt: a tile keeps
/// its gradients iff tg * vp * F(vg / vp) < tpt * vpt, where vp F(r) is the
/// per-pixel variance of the generalised least-squares (inverse-variance
/// weighted, L2) screened Poisson solution for white noise of per-sample
/// variances vp and vg, F(r) = mean over the image's cosine frequencies of
/// r / (r + lambda), lambda the eigenvalues of the discrete Laplacian.
/// Correlations between the primal and the gradients and the L1 form are
/// not modelled. Throws ParameterError naming a missing layer or a mismatch.
GradientSelection select_gradient_pixels(const FrameBuffer& gradient_pilot, double gradient_seconds_per_pass,
                                         const FrameBuffer& primal_pilot, double primal_seconds_per_pass,
                                         const GradientSelectOptions& options = {});

/// Criterion::Measured: a tile keeps its gradients iff
/// tg ng V(R) < tp np V(P), where V is the tile's relative variance of a
/// render (the mean over its pixels and channels of (a - b)^2 / 2 /
/// (m^2 + 0.01), a and b the two pilots' values, m the mean of all four
/// pilots' colour: relMSE's units), R the reconstruction (options.method) and
/// P the primal-only colour, ng and np the passes behind each and tg, tp
/// the seconds per pass: per-sample variance times the time per sample.
/// Throws ParameterError naming a missing pilot, layer or bad option.
GradientSelection select_gradient_pixels(const SelectionPilots& pilots, const GradientSelectOptions& options = {});

/// F(r) of select_gradient_pixels(): the variance of a pixel of the weighted
/// L2 solution over the primal's per-sample variance, for gradient over
/// primal variance ratio r >= 0 (unitless, between 0 and 1, increasing).
double gls_variance_factor(double r);

/// How render_adaptive() spends its budget.
struct AdaptiveRender {
    /// What the pilot decides: each pixel's sample density by its variance
    /// (adaptive_sample_density()), or which pixels take gradients and how
    /// many primal-only samples the others take (select_gradient_pixels()).
    enum class Mode { Density, SelectGradients };
    Mode mode = Mode::Density;
    double pilot = 0.125;     ///< Share of the budget (samples or seconds) given to the pilot render (0..0.5).
    AdaptiveOptions density;  ///< How the pilot becomes a density (Mode::Density).
    GradientSelectOptions select;  ///< How the pilots choose gradient pixels (Mode::SelectGradients).
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
///
/// Mode::SelectGradients (gpt only) renders pilots first: primal-only
/// samples (an all-zero gradient mask; 4 passes, or the pilot's spp) and
/// gradient samples (the rest of the pilot's share, at least 4 passes), each
/// as two renders of independent seeds for Criterion::Measured; the
/// render itself then has select_gradient_pixels()' mask and density
/// (layers "gradient_mask" and "sample_density", metadata
/// "gradient_share" and "gradient_cost_ratio"). With an spp budget the
/// primal-only pilot's passes are extra. keep_pilot keeps the gradient
/// pilot's samples (the primal-only pilot's are not kept).
RenderStats render_adaptive(Integrator& integrator, const Scene& scene, const RenderSettings& settings,
                            FrameBuffer& out, const AdaptiveRender& adaptive = {}, const ProgressFn& progress = {});

/// The seed of render_adaptive()'s pilot for a render of seed `seed`: a
/// stream of its own, so the pilot never repeats the render's samples.
uint64_t pilot_seed(uint64_t seed);

}  // namespace gdr
