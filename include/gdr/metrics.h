// Image error metrics for comparing a render against a reference. Every
// function takes (image, reference), throws ParameterError if their shapes
// differ or they are empty, and InputError naming the pixel if either holds
// NaN or Inf. Results are averages over all pixels and all channels.
#pragma once

#include <string>
#include <vector>

#include "gdr/core/image.h"

namespace gdr {

/// Mean squared error: mean over pixels and channels of (x - r)^2 (radiance^2).
double mse(const Image& img, const Image& ref);

/// Mean absolute error: mean over pixels and channels of |x - r| (radiance).
double mae(const Image& img, const Image& ref);

/// Which relative MSE convention to use; always state it next to a number.
struct RelMseOptions {
    float eps = 0.01f;              ///< Added to the denominator (radiance^2) so black pixels do not dominate.
    bool grey_denominator = false;  ///< Denominator (mean of r's channels)^2 + eps instead of r_c^2 + eps.

    /// The thesis errata convention: per-channel denominator, eps = 0.01.
    static RelMseOptions thesis() { return {0.01f, false}; }
    /// The later neural-reconstruction convention: grey denominator, eps = 0.001.
    static RelMseOptions neural() { return {0.001f, true}; }
};

/// Relative MSE (unitless): mean over pixels and channels of (x - r)^2 / (d + eps),
/// d = r_c^2, or (mean_c r_c)^2 with grey_denominator (docs/algorithms.md, "Error metrics").
double relmse(const Image& img, const Image& ref, const RelMseOptions& opt = {});

/// Temporal (flicker) error of an image sequence against a reference sequence
/// (unitless): the relMSE of the frame-to-frame differences, mean over the
/// n - 1 consecutive pairs k, the pixels and the channels of
///   ((x[k+1] - x[k]) - (r[k+1] - r[k]))^2 / (((r[k+1] + r[k]) / 2)^2 + eps).
/// The denominator is the reference's radiance at the pair, not its
/// difference, which is zero wherever nothing changes. Needs at least two
/// frames, all of one shape, as many images as references.
double temporal_relmse(const std::vector<Image>& imgs, const std::vector<Image>& refs, float eps = 0.01f);

/// How SSIM maps HDR radiance to the [0,1] range it needs.
struct SsimOptions {
    bool srgb = false;  ///< Encode the clamped values with the sRGB curve (as a PNG viewer shows them) first.
};

/// Structural similarity (unitless, 1 = identical; Wang et al. 2004) with an
/// 11x11 Gaussian window (sigma 1.5), K1 = 0.01, K2 = 0.03, L = 1, computed per
/// channel on values clamped to [0,1] and averaged over channels and pixels.
/// Near the border the window is truncated and renormalised, so every pixel
/// counts and images smaller than the window are fine.
double ssim(const Image& img, const Image& ref, const SsimOptions& opt = {});

/// Human-readable lines (newline-terminated) with every metric above, each
/// labelled with its convention, and the per-channel means of both images
/// with their ratio image / reference ("n/a" where the reference's mean is 0);
/// what the CLI `gdr compare` prints.
std::string compare_report(const Image& img, const Image& ref);

/// Shrinks `img` by the integer `factor` in both dimensions, each output pixel
/// the mean of a factor x factor block (a box filter, same units as the input),
/// so that a render can be compared with a reference of a lower resolution
/// without changing its mean. Throws ParameterError naming the size and factor
/// unless factor >= 1 divides both the width and the height.
Image box_downsample(const Image& img, int factor);

}  // namespace gdr
