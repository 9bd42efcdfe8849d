// Training of the neural reconstructor: a data set rendered by gdr itself
// (random camera views of scenes at several sample counts, with a high-count
// target), minibatch training with Adam, checkpoints that resume exactly, and
// validation against the screened Poisson L1 solve.
//
// Loss (per minibatch, on the central crop, the padding excluded):
//   L1(T(p), T(t)) + relmse_weight * mean((p - t)^2 / (t^2 + 0.01))
// with p the network's radiance, t the target's and T(v) = v / (1 + v) per
// channel (Reinhard's tone map), so the L1 term weighs dark and bright
// regions alike and the relMSE term (docs/algorithms.md, "Error metrics", thesis errata
// form) is the figure reported. The publication's E-LPIPS term needs
// pretrained VGG weights that cannot be obtained on this machine; it is left
// out. Gradients are clipped to norm 1: a firefly's relMSE gradient is
// otherwise orders of magnitude above the rest.
//
// Exact resume: the minibatch of step k is drawn from a generator seeded by
// (seed, k) alone, so a resumed run draws the same batches; the checkpoint
// holds the weights, Adam's moments and step counts and the loss history.
#pragma once

#include <torch/torch.h>

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "gdr/neural/unet.h"

namespace gdr::neural {

/// One training example: a noisy frame's network input and its clean target.
struct Sample {
    torch::Tensor input;   ///< make_input() of the noisy frame without the batch axis: [C, H', W'] (encoded).
    torch::Tensor target;  ///< Clean primal [3, H, W] (radiance), H' = padded_size(H), likewise W'.
    int spp = 0;           ///< Samples per pixel of the noisy frame (0 if synthetic).
};

/// What to render for a data set.
struct DatasetOptions {
    std::vector<std::string> scenes;  ///< Scene files; crop i uses scenes[i % size].
    int crops = 16;                   ///< Number of random views.
    int size = 64;                    ///< Width and height of a view (pixels).
    std::vector<int> spp{4, 16, 64};  ///< Sample counts of the noisy frames of each view.
    int target_spp = 1024;            ///< Sample count of each view's target.
    /// Integrator of the targets: "gpt" (its primal) or "bdpt" (its colour
    /// without the directly visible emitters, which gpt's primal leaves out
    /// too). bdpt's light tracing finds the caustics that leave fireflies in
    /// gpt's targets, at about half of gpt's cost per sample.
    std::string target_integrator = "gpt";
    uint64_t seed = 1;                ///< Seed of the views and of the renders.
    int threads = 0;                  ///< Render threads (0 = all cores).
    /// Procedural variation: every odd-numbered view also recolours the
    /// scene's materials (every reflectance times a random tint, each channel
    /// in [0.45, 1]) and rescales its emitters (a random tint and a factor of
    /// 1/3 to 3), from a stream of its own, so its camera is the unvaried
    /// view's; even-numbered views show the scenes as they are.
    bool vary = false;
    /// OBJ files (e.g. scenes/meshes, or meshes in GDR_SCENES) to place into the scenes:
    /// with any given, views whose index is 2 or 3 mod 4 get one of them
    /// (in turn) with a random material, standing on a surface that faces
    /// up in the view (found by camera rays through random pixels; if 32 find
    /// none, floating in front of the first surface hit), turned about the
    /// up axis and sized to 30-70% of the view's width there. Views 0 and 1
    /// mod 4 are the files a run without meshes writes.
    std::vector<std::string> meshes;
    /// Views from anywhere in the scene's open space instead of near its own
    /// camera: the eye moved up to half the distance the scene's camera sees
    /// (its median over probe rays) in any direction, the view turned up to
    /// 60 degrees about the up axis and 20 degrees up or down. A view is kept
    /// only if the segment from the scene's eye to it is free (it stands in
    /// the same room, not inside a wall), at least half its probe rays hit
    /// something, and its median and first-quartile probe distances are at
    /// least 20% and 5% of the scene camera's median (no walls at 1 cm);
    /// after 100 refused tries it falls back to a view near the camera.
    bool roam = false;
    /// Load Mitsuba scenes as `gdr render --lenient` does (unsupported parts
    /// skipped or replaced; each file records how many warnings it had):
    /// training data needs only a renderable scene, not the authors' exact one.
    bool lenient = false;
};

/// What generate_dataset did.
struct DatasetReport {
    int written = 0;  ///< Views rendered by this call.
    int kept = 0;     ///< Views whose file existed already.
    /// Scene files that did not load, with the loader's message; their views
    /// are left out (a later run, once they load, renders them).
    std::map<std::string, std::string> skipped;
    int skipped_views = 0;  ///< Views left out because their scene did not load.
};

/// Renders the data set into `dir`, one file crop-NNNNN.exr per view (layers
/// target and sSPP_primal, sSPP_dx, ... for each noise level), skipping
/// views whose file exists: a stopped run continues where it was, and the
/// files depend only on the options, not on how often it was restarted.
/// View i shows scenes[i % scenes.size()]; a scene file that does not load
/// leaves its views out and is named in the report, so that the same
/// command, run again once it loads, adds them.
/// `progress` (may be empty) gets (views done, views total) after each view.
DatasetReport generate_dataset(const DatasetOptions& options, const std::string& dir,
                               const std::function<void(int, int)>& progress = {});

/// Every (view, noise level) of a data set directory, and of the directories
/// below it (one per scene family, say), as samples for `config`
/// (gradients or not); InputError naming the file if one is malformed or none exists.
std::vector<Sample> load_dataset(const std::string& dir, const UNetConfig& config);

/// The frame of sample count `spp` of a data-set view (its layers sSPP_*):
/// primal, dx, dy, albedo, normal and depth (InputError naming a missing
/// one), and the variance layers where the view has them.
FrameBuffer view_frame(const FrameBuffer& view, int spp);

/// The sample of one frame given as buffers (needs albedo, normal, depth).
Sample make_sample(const GradientBuffers& noisy, const Image& target, const UNetConfig& config, int spp);

/// A symmetry of a training sample: applied as transpose, then flips, then
/// a permutation of the colour channels. Rendering is per colour channel
/// and mirror symmetric, so each maps a sample to another valid one.
struct Augmentation {
    bool transpose = false;  ///< Swap x and y (square samples only): dx and dy swap too.
    bool flip_x = false;     ///< Mirror left-right: dx is negated and moves one pixel.
    bool flip_y = false;     ///< Mirror top-bottom: dy is negated and moves one pixel.
    int permutation = 0;     ///< Index 0..5 of a permutation of R, G, B (0 = identity).
};

/// `s` under `a`, exactly the sample make_input() builds from the transformed
/// frame (up to the Poisson input's solver tolerance): colours, gradients and
/// albedo permute their channels; normals (world space) and depth only move.
/// ParameterError if `a` transposes a non-square sample or the padding is not
/// the same on both sides of an axis that is flipped.
Sample augment(const Sample& s, const UNetConfig& config, const Augmentation& a);

/// Settings of a training run; all but `steps` and `threads` must match on resume.
struct TrainOptions {
    UNetConfig config;              ///< Network shape.
    int batch = 8;                  ///< Samples per minibatch.
    double learning_rate = 5e-4;    ///< Adam's step size after the warm-up.
    int warmup = 100;               ///< Steps of linear learning-rate warm-up.
    double relmse_weight = 0.01;    ///< Weight of the relMSE term of the loss (see the file comment).
    uint64_t seed = 1;              ///< Seed of the initial weights and of the minibatch draws.
    /// Each drawn sample under a random one of its symmetries (Augmentation:
    /// 8 mirror images and transposes of a square sample times 6 colour
    /// permutations), drawn with the minibatch.
    bool augment = false;
};

/// The loss of the file comment for predictions and targets [N, 3, H, W] (radiance).
torch::Tensor training_loss(const torch::Tensor& prediction, const torch::Tensor& target, double relmse_weight);

/// Mean relMSE (eps 0.01, averaged over channels and pixels; docs/algorithms.md,
/// "Error metrics") of `x` against reference `r`, both radiance of one shape.
double rel_mse(const torch::Tensor& x, const torch::Tensor& r);

/// A training run: network, optimiser, step count and loss history.
class Trainer {
public:
    /// A fresh run; the weights are drawn from `options.seed`.
    Trainer(const TrainOptions& options, std::vector<Sample> samples);
    /// Runs one minibatch step and returns its loss.
    double step();
    /// Steps taken so far.
    long long steps() const { return step_; }
    /// Loss of every step taken (including those before a resume).
    const std::vector<double>& losses() const { return losses_; }
    /// The network being trained.
    UNet& net() { return net_; }
    /// Writes weights, optimiser state, step count, losses and options to `path`.
    void save_checkpoint(const std::string& path);
    /// Starts from the weights of a trained network of the same shape instead
    /// of random ones (fine-tuning; call before the first step); ParameterError
    /// saying which if the shapes differ. The optimiser starts afresh, warm-up included.
    void start_from(UNet& trained);
    /// Continues from `path`; InputError naming the file if it is unreadable
    /// or ParameterError naming the option if it was made with other options.
    void load_checkpoint(const std::string& path);
    /// Mean loss of the network on `samples` (no training), in batches of `batch`.
    double evaluate(const std::vector<Sample>& samples);

private:
    TrainOptions options_;
    std::vector<Sample> samples_;
    UNet net_{nullptr};
    std::unique_ptr<torch::optim::Adam> optimizer_;
    long long step_ = 0;
    std::vector<double> losses_;
};

/// The network's prediction of one sample (radiance [3, H, W], cropped).
torch::Tensor predict(UNet& net, const Sample& s);

}  // namespace gdr::neural
