// Spatio-temporal screened Poisson reconstruction of temporal gradient-domain
// path tracing: Manzi, Kettunen, Durand, Zwicker and Lehtinen, "Temporal
// Gradient-Domain Path Tracing" (ACM TOG 35(6), 2016); docs/algorithms.md,
// "Screened Poisson reconstruction" and "Temporal".
//
// A window of F frames is solved jointly:
//
//   x = argmin  sum_f  rho(alpha (x_f - P_f))
//                    + rho(w_s (d_x x_f - Dx_f)) + rho(w_s (d_y x_f - Dy_f))
//                    + rho(w_t (x_{f+1}(p + m_f(p)) - x_f(p) - Dt_f(p)))
//
// summed over pixels p. P_f: primal colour; Dx_f, Dy_f: forward differences
// in gdr's convention (dx(x,y) = I(x+1,y) - I(x,y) at the left pixel, last
// column unused; dy likewise with y down, last row unused); Dt_f: the
// temporal difference from frame f to frame f+1 along the forward motion
// m_f (pixels, x right, y down), rounded to the nearest whole pixel (half
// away from zero) as the authors' implementation rounds its motion maps.
// A temporal row is dropped where the motion leaves the image or the
// validity mask is 0, and for the window's last frame. rho is the squared
// norm (L2) or the Euclidean norm of a row's channel vector (L1).
// Defaults alpha 0.2, w_s = w_t = 1, L1, as the authors' solver.
//
// Solvers. L2 without motion (every m = 0, every row kept) has the normal
// operator alpha^2 I + w_s^2 (Dx^T Dx + Dy^T Dy) + w_t^2 Dt^T Dt with
// Neumann boundaries in x, y and time, which the 3-D DCT-II diagonalises:
// an orthonormal DCT along time (F is small: a dense F x F transform) turns
// it into F independent 2-D problems (alpha^2 + w_t^2 (2 - 2 cos(pi k / F))) I
// + w_s^2 L, each solved exactly by gdr's 2-D DCT solver (FFTW). With motion
// or masks the system is solved by preconditioned conjugate gradients
// (per-channel scalars), preconditioned by that 3-D DCT solve with the mean
// weights or by a per-frame multigrid V-cycle of each frame's own block
// (block Jacobi). L1 is IRLS exactly as the 2-D poisson-l1: every residual
// row (channels jointly) is reweighted by 1 / (||e_r|| + eps_k), the weights
// normalised to mean 1, eps_k = eps_initial * eps_factor^(k-1), starting from
// the L2 solution; each reweighted step is a few PCG iterations.
//
// Windows. A video is solved in windows of W frames (default 10) every S
// frames (default 5); window k covers frames [kS, kS + W). A frame's output
// is the blend of the windows covering it with Hann weights
// 1/2 (1 + cos(2 pi (f - c) / L)), c the centre and L the length of the
// window, normalised to sum to one at every frame, so there are no seams.
// Edges: the first S frames are covered by the first window only, whose
// solution they take; at the end, frames not covered by a full window are
// solved in one final shorter window [kS, N) (between W - S + 1 and W - 1
// frames) blended with the windows before it; a video of N <= W frames is
// one window. The directly visible emitters ("direct") are added after the
// blend, as the 2-D reconstructors add them after the solve.
#pragma once

#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "gdr/core/image.h"
#include "gdr/core/params.h"
#include "gdr/reconstruct/poisson.h"

namespace gdr {

/// Penalty of the residual rows of the spatio-temporal energy.
enum class TemporalNorm {
    l2,  ///< Squared norm: linear, unbiased on unbiased inputs.
    l1,  ///< Euclidean norm of each row's channel vector, by IRLS (robust, biased).
};

/// How the L2 system (and each IRLS step) of a window is solved.
enum class TemporalSolver {
    automatic,  ///< The 3-D DCT where it is exact (L2, no motion, no dropped row), else PCG.
    dct,        ///< The exact 3-D DCT solve; ParameterError if the window has motion or dropped rows.
    cg,         ///< Preconditioned conjugate gradients always.
};

/// Preconditioner of the window's CG solves.
enum class TemporalPreconditioner {
    none,             ///< Plain CG.
    dct,              ///< 3-D DCT solve of the motion-free operator with the mean weights.
    frame_multigrid,  ///< Per frame, a multigrid V-cycle of the frame's own block (follows IRLS weights).
};

/// Settings of the spatio-temporal reconstruction; defaults as the authors' solver where it has one.
struct TemporalOptions {
    double alpha = 0.2;  ///< Weight of the colour rows (unitless, > 0).
    double w_s = 1.0;    ///< Weight of the spatial gradient rows (unitless, >= 0).
    double w_t = 1.0;    ///< Weight of the temporal rows (unitless, >= 0).
    TemporalNorm norm = TemporalNorm::l1;  ///< Penalty of the rows.
    TemporalSolver solver = TemporalSolver::automatic;  ///< Solver of the L2 system.
    /// Preconditioner of the L2 PCG (motion: the motion-free operator is close to it).
    TemporalPreconditioner l2_preconditioner = TemporalPreconditioner::dct;
    int cg_iterations = 300;  ///< Most PCG iterations of the L2 solve.
    double tolerance = 1e-6;  ///< Relative residual (all channels) at which the L2 PCG stops.
    /// IRLS iterations including the first, unweighted (L2) one (reference: 20).
    int irls_iterations = 20;
    /// Most PCG iterations per reweighted step. Measured (benchmarks/
    /// bench_temporal.cpp, 10 frames of 160x90, with and without motion):
    /// the L1 energy is within 0.04% of a converged IRLS (100 iterations per
    /// step) with 1 multigrid-preconditioned iteration per step, 0.012% with
    /// 2, 0.003% with 4; the DCT preconditioner needs 8 for 0.03%.
    int irls_cg_iterations = 2;
    double irls_tolerance = 1e-3; ///< Relative residual at which a reweighted step's PCG stops.
    /// Preconditioner of the reweighted steps (their weights vary by orders of magnitude).
    TemporalPreconditioner irls_preconditioner = TemporalPreconditioner::frame_multigrid;
    double eps_initial = 0.05;  ///< eps of the first reweighted step (radiance); reference 0.05.
    double eps_factor = 0.5;    ///< eps is multiplied by this after every reweighted step.
    int window = 10;  ///< Frames per window W (>= 1).
    int step = 5;     ///< Frames between window starts S (1..W).
    /// A frame followed by another must hold "dt" (else InputError); false:
    /// a frame without dt has no temporal rows to the next (a cut).
    bool require_dt = true;
};

/// Throws ParameterError naming the field unless the options are in range.
void check_temporal_options(const TemporalOptions& options);

/// Options from parameters ("key=value", e.g. gdr reconstruct --set): alpha,
/// w_s, w_t, norm (l1 | l2), solver (auto | dct | cg), preconditioner and
/// irls_preconditioner (dct | multigrid | none: of the L2 solve and of the
/// IRLS steps), cg_iterations, tolerance, iterations (IRLS),
/// irls_cg_iterations, irls_tolerance, eps_initial, eps_factor, window,
/// step, require_dt. Unknown keys are errors (ParameterError naming the key).
TemporalOptions temporal_options(const Params& params);

/// The options as sorted "key=value" lines (for file headers), in the keys of temporal_options().
std::string describe(const TemporalOptions& options);

/// Non-owning views of one frame's buffers for the window solver (radiance,
/// interleaved like ImageView); all of primal's width and height.
struct TemporalFrameView {
    ImageView primal;  ///< P_f: colour estimate without directly visible emitters.
    ImageView dx;      ///< Dx_f, shape of primal.
    ImageView dy;      ///< Dy_f, shape of primal.
    /// Dt_f (shape of primal): x_{f+1}(p + m_f(p)) - x_f(p) at p; data null =
    /// no temporal rows from this frame (also what the window's last frame's dt is: unused).
    ImageView dt;
    /// m_f: 2 floats per pixel (pixels, x right, y down) to frame f+1; null = 0.
    const float* motion = nullptr;
    /// 1 float per pixel: the temporal row of p is used where >= 0.5; null = all.
    const float* valid = nullptr;
};

/// What a window solve did.
struct TemporalReport {
    bool direct_solve = false;    ///< The L2 system was solved by the exact 3-D DCT.
    int cg_iterations = 0;        ///< PCG iterations of the L2 solve (0 if direct).
    double relative_residual = 0; ///< ||r|| / ||r0|| of the L2 PCG at exit (0 if direct).
    int irls_iterations = 0;      ///< IRLS iterations run, including the L2 one (L1 only).
    int irls_cg_iterations = 0;   ///< PCG iterations summed over the reweighted steps.
    long long temporal_rows = 0;  ///< Temporal rows in use (pixels, not channels).
    double energy = 0;            ///< The minimised energy of the result (L2: radiance^2, L1: radiance).
};

/// Throws ParameterError (naming frame index and layer) unless the frames
/// are at least one, equally shaped (1..4 channels), and every view present
/// has the primal's shape; dt-less frames are allowed.
void check_temporal_frames(const std::vector<TemporalFrameView>& frames);

/// Solves one window: out[f] (width * height * channels floats, interleaved)
/// receives x_f, without any direct layer. Throws RuntimeFailure naming the
/// frame and pixel if a result is not finite.
TemporalReport solve_temporal_window(const std::vector<TemporalFrameView>& frames, const TemporalOptions& options,
                                     const std::vector<float*>& out);

/// The spatio-temporal energy of x (L2: sum of squared rows, radiance^2; L1:
/// sum of row norms, radiance), rows weighted by alpha, w_s and w_t.
double temporal_energy(const std::vector<TemporalFrameView>& frames, const TemporalOptions& options,
                       const std::vector<const float*>& x, TemporalNorm norm);

/// Owning storage of one frame of a video; optional layers are empty when absent.
struct TemporalFrame {
    std::string name;  ///< Names the frame in error messages (a file path, "frame 12").
    Image primal;      ///< Colour without directly visible emitters (radiance).
    Image dx;          ///< Horizontal forward differences (radiance).
    Image dy;          ///< Vertical forward differences, y down (radiance).
    Image direct;      ///< Directly visible emitters (radiance), added after the solve; or empty.
    Image dt;          ///< Temporal difference to the next frame (radiance); or empty.
    Image motion;      ///< Forward motion, 2 channels (pixels); or empty (m = 0).
    Image valid;       ///< Temporal row mask, 1 channel (>= 0.5: used); or empty (all).

    /// Views of the members for solve_temporal_window (valid while *this lives).
    TemporalFrameView view() const;
};

/// Layer names of a temporal frame in a gdr FrameBuffer / EXR.
namespace temporal_layers {
inline constexpr const char* primal = "primal";      ///< Required.
inline constexpr const char* dx = "dx";              ///< Required.
inline constexpr const char* dy = "dy";              ///< Required.
inline constexpr const char* direct = "direct";      ///< Optional, shape of primal.
inline constexpr const char* dt = "dt";              ///< Required on every frame but the video's last (require_dt).
inline constexpr const char* motion = "motion_fwd";  ///< Optional, 2 channels (pixels to frame k+1).
inline constexpr const char* valid = "dt_valid";     ///< Optional, 1 channel (0: temporal row dropped).
/// tgpt's first half (radiance): the frame with its own seed, replaying the
/// previous frame's second half along the motion.
inline constexpr const char* primal_a = "primal_a";
/// tgpt's second half (radiance): the frame with the next frame's seed.
inline constexpr const char* primal_b = "primal_b";
/// tgpt, 2 channels: the previous frame's pixel whose random numbers the
/// first half used at each pixel, (-1, -1) where it used its own.
inline constexpr const char* replay = "replay_pixel";
}  // namespace temporal_layers

/// True if `frame` and `next` hold the halves add_temporal_difference() reads.
bool has_temporal_halves(const FrameBuffer& frame, const FrameBuffer& next);

/// Forms frame k's temporal difference from two consecutive tgpt frames, as
/// Manzi et al. (2016) do: dt(p) = A_{k+1}(p + m(p)) - B_k(p), with B_k =
/// frame's primal_b, A_{k+1} = next's primal_a, m = frame's motion_fwd
/// rounded to whole pixels (0 without the layer), and sets "dt" and
/// "dt_valid" in `frame`. A row is valid (1) where p + m(p) is in the image
/// and next's first half replayed p's random numbers there (its replay layer
/// holds p), so that both terms used the same random numbers; elsewhere dt is
/// 0 and the row is dropped. InputError naming the frame (`name`, `next_name`)
/// and the layer if one is missing or mis-shaped.
void add_temporal_difference(FrameBuffer& frame, const FrameBuffer& next, const std::string& name,
                             const std::string& next_name);

/// The layers of `fb` (see temporal_layers) copied into a TemporalFrame
/// called `name`. InputError naming `name` and the layer if primal, dx or dy
/// is missing, a layer is mis-shaped, or a value is NaN or Inf (with the
/// pixel). A missing dt is checked when the next frame arrives.
TemporalFrame temporal_frame(const FrameBuffer& fb, const std::string& name);

/// Throws InputError naming the frame, the layer and (for NaN / Inf) the
/// pixel unless `frame` is complete, consistently shaped and finite.
void check_temporal_frame(const TemporalFrame& frame);

/// Streaming reconstruction of a video: frames go in one at a time with
/// push(), finished frames come out in order with pop(). Holds at most W
/// input frames and the running blends of at most W frames (plus the
/// finished frames not yet popped); a window's solve needs about 12 floats
/// per value of its W frames besides.
class TemporalReconstructor {
public:
    /// A reconstructor with checked options (ParameterError if out of range).
    explicit TemporalReconstructor(const TemporalOptions& options = {});

    /// Appends the next frame (checked: InputError naming it and the layer if
    /// incomplete, non-finite or shaped unlike the first frame, or if the
    /// previous frame has no dt and require_dt is set). Solves a window when
    /// W frames are held. Throws ParameterError after finish().
    void push(TemporalFrame frame);

    /// No more frames: solves the remaining ones; after it every frame can be popped.
    void finish();

    /// True if pop() has a frame.
    bool ready() const;

    /// The next finished frame in order (radiance, direct included); ParameterError if none is ready.
    Image pop();

    int frames_pushed() const;   ///< Frames pushed so far.
    int frames_popped() const;   ///< Frames returned by pop() so far.
    int held_frames() const;     ///< Input frames held now (<= W).
    int pending_blends() const;  ///< Frames with a partial blend held now (<= W).
    /// Reports of the windows solved so far, in order, with their first frame.
    const std::vector<std::pair<int, TemporalReport>>& reports() const;

private:
    void solve_window(int first, int count);
    void finalise_until(int end);

    TemporalOptions opt_;
    std::deque<TemporalFrame> inputs_;  // frames [input_base_, input_base_ + inputs_.size())
    int input_base_ = 0;
    struct Blend {
        std::vector<float> sum;  // sum of Hann weight * solution (interleaved)
        double weight = 0;       // sum of Hann weights
        int width = 0, height = 0, channels = 0;
        Image direct;            // the frame's direct layer, or empty
    };
    std::deque<Blend> blends_;  // frames [blend_base_, blend_base_ + blends_.size())
    int blend_base_ = 0;
    std::deque<Image> ready_;
    int pushed_ = 0, popped_ = 0;
    int next_window_ = 0;  // first frame of the next full window
    int covered_ = 0;      // frames [0, covered_) are covered by a solved window
    bool finished_ = false;
    std::vector<std::pair<int, TemporalReport>> reports_;
};

/// The path of frame `frame` from a printf pattern with exactly one integer
/// conversion (%d, %04d, %5d...; %% for a percent sign); ParameterError
/// naming the pattern otherwise.
std::string frame_path(const std::string& pattern, int frame);

}  // namespace gdr
