// The network of gdr's neural reconstruction, after Kettunen, Härkönen and
// Lehtinen, "Deep Convolutional Reconstruction for Gradient-Domain Rendering"
// (SIGGRAPH 2019): a U-Net with skip connections that reads the log-encoded
// primal colour, the signed-log gradients and the auxiliary buffers (albedo,
// normal, depth) and outputs the log-encoded image.
//
// Sized for a CPU, not the publication's GPU (docs/algorithms.md, "Neural reconstruction"): the
// publication's dense blocks (4.4 M parameters) take 55 s per 1280x720 frame
// on two cores here and, at equal parameters, dense concatenations run 5-7x
// slower than plain convolutions on this CPU. So each level is two plain 3x3
// convolutions (leaky ReLU 0.01), the full-resolution level is the narrowest
// (its cost is paid on every pixel), down-sampling is a 2x2 stride-2
// convolution and up-sampling a 1x1 convolution to 4C channels followed by
// pixel_shuffle (exactly a 2x2 stride-2 transposed convolution, and about 4x
// faster than torch's CPU kernel for it). The output is a correction added
// to the log-encoded primal (a residual), so the untrained network already
// returns the input and training only learns the denoising.
//
// Any image size: the input is extended by replicate padding (colour and
// auxiliary buffers repeated from the border, gradients zero there, as the
// repeated colour is constant) by at least kMargin pixels and up to a
// multiple of 2^(levels-1), the network runs on that, and the result is
// cropped back.
#pragma once

#include <torch/torch.h>

#include <string>
#include <vector>

#include "gdr/reconstruct/reconstructor.h"

namespace gdr::neural {

/// The shape of a U-Net; stored in its weights file.
struct UNetConfig {
    /// Channels of each resolution level, full resolution first; the number
    /// of entries is the number of levels (2x down-samplings = size - 1).
    std::vector<int> widths{16, 32, 48, 64};
    /// True: inputs include dx and dy (16 channels); false: the primal-only
    /// network (10 channels) that measures what the gradients add.
    bool gradients = true;
    /// True (needs gradients): the inputs also hold the frame's poisson-l1
    /// reconstruction (19 channels), and the output is a correction to it
    /// instead of to the primal. A network of a few pixels' reach cannot
    /// integrate gradients across the frame; the screened Poisson solve does,
    /// and the network learns what that solve gets wrong.
    bool poisson = false;
    /// True (needs poisson): that input, and the image the output corrects,
    /// is poisson-weighted's reconstruction (the variance-weighted screened
    /// Poisson solve, gdr's default final image) instead of poisson-l1's; the
    /// frame then needs the variance layers gpt writes. The network starts
    /// from the best solve there is, one that keeps improving with samples,
    /// and learns what it still gets wrong.
    bool weighted = false;

    /// Same shape (same widths and inputs).
    bool operator==(const UNetConfig&) const = default;
};

/// Input channels of a network of that configuration (19 with the Poisson
/// input, 16 with gradients only, 10 without); ParameterError for poisson without gradients.
int input_channels(const UNetConfig& config);

/// Pixels of replicate padding added on every side before the network runs.
inline constexpr int kMargin = 4;

/// The U-Net (see the file comment). forward() maps [N, input_channels, H, W]
/// with H and W multiples of 2^(levels-1) to the log-encoded image [N, 3, H, W].
class UNetImpl : public torch::nn::Module {
public:
    /// Builds the layers, initialised from torch's global generator (seed it first).
    explicit UNetImpl(const UNetConfig& config);
    /// The log-encoded reconstruction (log(1 + radiance)), not yet clamped.
    torch::Tensor forward(const torch::Tensor& x);
    /// The configuration it was built with.
    const UNetConfig& config() const { return config_; }
    /// Number of trainable values.
    long long parameter_count() const;

private:
    UNetConfig config_;
    std::vector<torch::nn::Conv2d> enc_a_, enc_b_, down_, up_, dec_a_, dec_b_;
    torch::nn::Conv2d out_{nullptr};
};
/// Shared handle of a UNetImpl (torch's module-holder convention: copies share the weights).
TORCH_MODULE(UNet);

/// log(1 + max(0, x)): the colour encoding (radiance -> unitless).
torch::Tensor encode_colour(const torch::Tensor& radiance);
/// exp(y) - 1 with y clamped to [0, 80]: the inverse of encode_colour, finite
/// for every finite or infinite y (radiance, at most about 5.5e34).
torch::Tensor decode_colour(const torch::Tensor& y);
/// sign(g) log(1 + |g|): the gradient encoding (radiance -> unitless).
torch::Tensor encode_signed(const torch::Tensor& g);
/// sign(y) (exp(|y|) - 1): the inverse of encode_signed (radiance).
torch::Tensor decode_signed(const torch::Tensor& y);

/// The padded size (>= size + 2 kMargin, a multiple of 2^(levels-1)) of one image dimension (pixels).
int padded_size(int size, int levels);

/// Where each kind of input sits among a configuration's channels (first
/// channel index, or -1 if absent); the first three channels are always the
/// encoded colour the output corrects.
struct InputLayout {
    int poisson = -1;  ///< Encoded poisson-l1 (or poisson-weighted) reconstruction (3 channels).
    int primal = 0;    ///< Encoded primal (3).
    int dx = -1;       ///< Signed-log dx (3).
    int dy = -1;       ///< Signed-log dy (3).
    int albedo = 0;    ///< Albedo in [0, 1] (3).
    int normal = 0;    ///< World-space normal (3).
    int depth = 0;     ///< Depth over the frame's largest depth (1).
};
/// The channel layout of `config`'s input.
InputLayout input_layout(const UNetConfig& config);

/// The network input [1, C, H', W'] of one frame, padded as the file comment
/// says, in the order of input_layout(): the encoded poisson-l1 (or, if
/// config.weighted, poisson-weighted) reconstruction of primal, dx and dy
/// (if config.poisson), the encoded
/// primal, dx, dy (if config.gradients; the unused last column of dx and last
/// row of dy are zeroed), albedo (clamped to [0, 1]), normal, and depth
/// divided by the frame's largest depth. Needs the layers "albedo" (3
/// channels), "normal" (3) and "depth" (1) through in.layer().
torch::Tensor make_input(const GradientBuffers& in, const UNetConfig& config);

/// Runs the network on a frame and returns its primal reconstruction (radiance,
/// without `direct`), cropped to the frame's size; no gradients are recorded.
Image infer(UNet& net, const GradientBuffers& in);

/// Writes the configuration and weights to `path` (a torch archive).
void save_weights(UNet& net, const std::string& path);
/// Reads a network written by save_weights; InputError naming `path` if it
/// is absent or does not hold a gdr U-Net of consistent shape.
UNet load_weights(const std::string& path);

}  // namespace gdr::neural
