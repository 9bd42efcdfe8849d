// Variance-weighted, outlier-robust screened Poisson reconstruction, usable
// on its own like gdr/reconstruct/poisson.h (plain interleaved float buffers).
//
//   I = argmin_x  sum_p w_p rho(x_p - c_p) + sum w_x rho(Dx x - gx) + sum w_y rho(Dy x - gy)
//
// with every constraint weighted by the inverse of the variance of its own
// estimate (the variance of the pixel mean: the per-sample variance layer
// over the pixel's sample count). For rho = squared norm this is the
// generalised least-squares estimate of the image from the colour and
// gradient estimates, the weighting of Rousselle, Jarosz and Novak, "Image-
// space Control Variates for Rendering" (2016): with the true variances and
// independent estimates it is unbiased and of least variance among linear
// unbiased combinations. The constant weight alpha of poisson-l2 is the
// special case of equal variances everywhere.
//
// Estimated variances are themselves noisy and correlated with the values
// (a sample that found a bright path also raises its pixel's variance
// estimate), and at low sample counts many are zero. Three guards keep the
// weights from following that noise:
//  - each variance is replaced by the larger of itself and its (2r+1)^2
//    neighbourhood mean, so that a constraint whose few samples happened to
//    agree does not get an unbounded weight;
//  - every variance has a floor, a fraction of the image's mean variance;
//  - the weights of one residual row are shared by its channels (the mean of
//    the channel variances), as the unweighted solvers share theirs;
//  - a pixel of one sample has no variance estimate: it takes the image's
//    mean variances, or, if no pixel has two samples, the weights of
//    poisson-l2 (alpha 0.2), and its rows are not tested for outliers.
//
// Outliers: a gradient row is tested against the difference of the two
// primal pixels it joins, both being estimates of the same difference:
// z^2 = |g - (c_q - c_p)|^2 / (C (v_g + v_p + v_q)) with the guarded
// variances. Rows with z above a threshold tau are dropped (weight 0) or
// down-weighted to the influence of a tau-sigma residual. This follows the
// idea of Ha, Oh, Back, Yoon and Moon, "Gradient Outlier Removal for
// Gradient-Domain Path Tracing" (2019), of judging a gradient by statistics
// of its own estimate and its neighbourhood rather than by magnitude; the
// test itself is this simpler two-estimator z-test. A noiseless input has
// g = c_q - c_p exactly and is never touched. Independently of the mode
// and of the variances, a row with |g - (c_q - c_p)| above 1000 times the
// local radiance and noise scale (|c_p| + |c_q| + the 5x5 mean |c| around
// both + the standard deviation) is dropped: a pixel of one sample has no
// variance to test with, and a gradient of 1e10 with an ordinary variance
// would otherwise pull the whole solve. The start point of the solve uses
// the primal's difference in place of every outlier row's gradient.
//
// L1 form: IRLS on residuals normalised by their standard deviation,
// weight w / (|e| / sigma + eps), so with eps in units of sigma the energy
// is quadratic (inverse-variance weighted) for residuals within the noise
// and grows linearly beyond it: outliers lose their pull without the
// low-frequency darkening of an eps annealed towards 0.
//
// Energy: any robust estimator of a skewed (Monte Carlo) distribution is
// biased low. The primal is unbiased, so the low frequencies of the result
// can be taken from it: "mean" scales each channel so that the image mean
// equals the primal's, "lowpass" adds a (2R+1)^2 box-filtered (primal -
// result), which restores every region's mean at the price of the primal's
// noise averaged over the box.
//
// Fallback: per tile, if the gradients are noisier than the primal's own
// differences (mean gradient variance > kappa * 2 * mean primal variance),
// the tile's gradient rows are dropped and it keeps the primal; a caller
// may also disable gradients per pixel (gradient_enabled). With every
// gradient dropped the result is the primal exactly.
#pragma once

#include <vector>

#include "gdr/reconstruct/poisson.h"

namespace gdr {

/// One weighted Poisson problem: estimates, their per-sample variances and sample counts.
struct VarianceProblem {
    ImageView primal;           ///< c: the colour estimate (radiance).
    ImageView dx;               ///< gx, as in PoissonProblem (radiance).
    ImageView dy;               ///< gy, as in PoissonProblem (radiance).
    ImageView primal_variance;  ///< Per-sample variance of c (radiance^2), same shape.
    ImageView dx_variance;      ///< Per-sample variance of gx (radiance^2), same shape.
    ImageView dy_variance;      ///< Per-sample variance of gy (radiance^2), same shape.
    /// Samples per pixel behind each mean (width * height values, >= 1), or
    /// null if the variances above are already variances of the means.
    const float* spp = nullptr;
    /// Per pixel: 0 disables the pixel's dx and dy rows (pixels without
    /// gradient samples); null enables all.
    const unsigned char* gradient_enabled = nullptr;
};

/// How a residual row's deviation is penalised.
enum class WeightedNorm {
    l2,  ///< Squared (generalised least squares: unbiased with true variances).
    l1,  ///< Normalised L1 by IRLS, quadratic within eps standard deviations.
};

/// What happens to gradient rows that fail the outlier test.
enum class OutlierMode {
    none,        ///< No test.
    drop,        ///< Weight 0.
    downweight,  ///< Weight times tau^2 / z^2: the pull of a residual of tau standard deviations.
};

/// How the low frequencies of the result are tied to the primal's.
enum class EnergyMode {
    none,     ///< Result as solved.
    mean,     ///< Each channel scaled so that its image mean equals the primal's.
    lowpass,  ///< Plus the box-filtered (primal - result) of radius energy_radius.
};

/// The neighbourhood statistic that bounds each variance from below.
enum class VarianceGuard {
    mean,    ///< Box mean: also raises the neighbours of a firefly.
    median,  ///< Box median: a single firefly's variance stays its own.
};

/// Settings of poisson_variance_weighted; defaults as registered for
/// "poisson-weighted", chosen by bench_equal_time on the bundled scenes
/// (docs/results.md, "Variance-weighted reconstruction"): among the variants measured,
/// L1 with r = 2 and a lowpass tie of R = 24 had the lowest relMSE on
/// average; R = 8 spread fireflies of veach-mis's primal visibly, the global
/// mean tie lost at 2 spp on the Cornell box, r = 0 and r = 3 were worse.
struct WeightedOptions {
    WeightedNorm norm = WeightedNorm::l1;        ///< Penalty of the rows.
    double primal_scale = 1.0;                   ///< Extra factor on every colour weight (unitless, > 0).
    int variance_radius = 2;                     ///< r of the neighbourhood guard on variances (pixels, >= 0).
    VarianceGuard guard = VarianceGuard::mean;   ///< Statistic of the neighbourhood guard.
    double variance_floor = 1e-3;                ///< Variance floor as a fraction of the mean variance (> 0).
    OutlierMode outliers = OutlierMode::drop;    ///< Treatment of outlier gradient rows.
    double tau = 4.0;                            ///< Outlier threshold on z (standard deviations, > 0).
    bool tile_fallback = false;                  ///< Drop the gradients of tiles where they do not pay.
    int tile = 16;                               ///< Fallback tile size (pixels, >= 1).
    double kappa = 1.0;                          ///< Fallback ratio (unitless, > 0), see the file comment.
    EnergyMode energy = EnergyMode::lowpass;     ///< Low-frequency tie to the primal.
    int energy_radius = 24;                      ///< R of EnergyMode::lowpass (pixels, >= 1).
    /// Bound on each pixel's (primal - result) before the lowpass filter, in
    /// neighbourhood standard deviations of the primal mean; 0 = none.
    double energy_clip = 0.0;
    int irls_iterations = 5;                     ///< IRLS steps of the L1 form after the L2 solve.
    double eps = 1.0;                            ///< L1 knee, in standard deviations of each row (> 0).
    int cg_iterations = 100;                     ///< Most CG iterations of the L2 solve (each IRLS step: a tenth, >= 2).
    double tolerance = 1e-4;                     ///< Relative residual at which CG stops.
};

/// What a weighted solve did.
struct WeightedReport {
    long long outlier_rows = 0;   ///< Gradient rows dropped or down-weighted as outliers.
    long long fallback_rows = 0;  ///< Gradient rows dropped by the tile fallback or gradient_enabled.
    int cg_iterations = 0;        ///< CG iterations over all steps.
};

/// Throws ParameterError unless all views are non-null and of one shape and
/// the options are in range; InputError naming the layer and pixel if a
/// variance is negative or a sample count below 1.
void check_variance_problem(const VarianceProblem& problem, const WeightedOptions& options);

/// The guarded per-row weights (inverse variances of the means, scaled to
/// mean 1; unitless) after the outlier test and fallback; what the L2 form
/// minimises with. `report` (may be null) receives the row counts.
RowWeights inverse_variance_weights(const VarianceProblem& problem, const WeightedOptions& options,
                                    WeightedReport* report = nullptr);

/// The weighted reconstruction into `out` (interleaved, radiance, shape of
/// the inputs): weights as inverse_variance_weights, solved by multigrid-
/// preconditioned CG from the exact unweighted (alpha 0.2) L2 solution,
/// then IRLS for the L1 form and the energy tie. With one sample in every
/// pixel (no variance estimate anywhere) and neither mask nor fallback, it
/// is poisson_l1 (alpha 0.2, default L1Options) plus the energy tie. Throws RuntimeFailure
/// naming the pixel if the result is not finite.
WeightedReport poisson_variance_weighted(const VarianceProblem& problem, const WeightedOptions& options, float* out);

/// One set of gradient estimates of a frame with their per-sample variances
/// (e.g. from one shift mapping), all of one shape (radiance, radiance^2).
struct GradientSet {
    ImageView dx, dy;                    ///< Forward differences, as in PoissonProblem.
    ImageView dx_variance, dy_variance;  ///< Their per-sample variances.
};

/// The inverse-variance combination of several gradient sets estimated with
/// the same sample counts: per pixel and channel g = sum(g_i / v_i) /
/// sum(1 / v_i), variance 1 / sum(1 / v_i); where some sets have variance
/// zero (exact estimates) the mean of those alone, variance 0. Outputs (interleaved,
/// same shape) are resized. Throws ParameterError on an empty list or
/// unequal shapes.
void combine_gradient_sets(const std::vector<GradientSet>& sets, std::vector<float>& dx, std::vector<float>& dy,
                           std::vector<float>& dx_variance, std::vector<float>& dy_variance);

}  // namespace gdr
