// Screened Poisson reconstruction core (docs/algorithms.md, "Screened Poisson reconstruction"), usable on
// its own from any renderer: plain interleaved float buffers in, same out.
//
//   I = argmin_x  sum_p rho(alpha (x_p - c_p)) + sum rho(Dx x - gx) + sum rho(Dy x - gy)
//
// c: primal colour, gx / gy: forward-difference gradients (dx(x,y) =
// I(x+1,y) - I(x,y) stored at the left pixel, dy likewise with y pointing
// down). The last column of dx and the last row of dy are ignored (those rows
// of the system are dropped: Neumann boundary). rho is the squared norm for
// L2 and the Euclidean norm of the channel vector of a row for L1 (all
// channels of one residual row are weighted jointly, as the reference does).
//
// L2 is solved exactly: with this boundary the normal operator
// a I + b (Dx^T Dx + Dy^T Dy) is diagonalised by the 2-D DCT-II (Bhat et al.
// 2008), so one forward and one inverse transform solve it in O(N log N).
// The DCT is computed through real FFTs (FFTW single precision) because
// FFTW's own r2r DCTs are about twice as slow.
//
// L1 is IRLS with the weights and eps schedule of the authors' public
// Mitsuba implementation of Kettunen et al., "Gradient-Domain Path Tracing" (2015) ("the reference" below),
// warm-started from
// the exact L2 solution. Each reweighted least-squares step is solved by a
// few conjugate-gradient iterations preconditioned with an aggregation
// multigrid V-cycle rather than with the DCT solve: the IRLS weights vary by
// orders of magnitude between neighbouring rows, which a constant-weight
// (DCT) preconditioner cannot follow. Measured on the reference's cbox
// buffers, 20 IRLS steps of 2 CG iterations leave an L1 energy gap of 1.06%
// with the DCT preconditioner (more than the budget) and 0.19% with multigrid,
// whose iterations are also cheaper. The DCT preconditioner stays available
// (Preconditioner::dct) and is exact for unit weights.
//
// Outliers and float range. The L1 reconstruction of Lehtinen et al.,
// "Gradient-Domain Metropolis Light Transport" (2013), and Kettunen et al.,
// "Gradient-Domain Path Tracing" (2015), solved by IRLS: a residual row e
// gets weight 1 / (|e| + eps), so its pull |e| / (|e| + eps) on the solution
// stays below 1 however large e is, and the L1 minimiser ignores a single
// huge gradient. Two things undo that in
// practice, and are handled here: a starting point displaced by the outlier
// (the exact L2 solution follows it), from which 20 IRLS steps do not come
// back, so the start shortens gradients far beyond their pixels' colours;
// and float overflow (a gradient of 1e30 squared), so the L1 solve works in
// units of a robust scale of the data and bounds what it sees (see
// poisson_l1). No solver returns NaN or Inf: each checks its result and
// throws RuntimeFailure naming the pixel instead.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace gdr {

/// A read-only view of an interleaved float image: row-major, row 0 at the
/// top, `channels` values per pixel (radiance, in the caller's units).
struct ImageView {
    const float* data = nullptr;  ///< width * height * channels floats.
    int width = 0;                ///< Columns.
    int height = 0;               ///< Rows.
    int channels = 0;             ///< Values per pixel (1..4).
};

/// The inputs of one screened Poisson problem; all three views share one shape.
struct PoissonProblem {
    ImageView primal;    ///< c: the noisy colour estimate (radiance).
    ImageView dx;        ///< gx: I(x+1,y) - I(x,y) at (x,y) (radiance); last column unused.
    ImageView dy;        ///< gy: I(x,y+1) - I(x,y) at (x,y), y down (radiance); last row unused.
    double alpha = 0.2;  ///< Weight multiplying the colour residual (unitless, > 0); 0.2 = reference default.
};

/// Throws ParameterError unless the views are non-null, equally shaped, 1..4
/// channels, and alpha is finite and positive. (Finiteness of the values is
/// checked by the Reconstructor front end, which names layer and pixel.)
void check_problem(const PoissonProblem& problem);

/// Throws RuntimeFailure, message starting with `what`, naming the first
/// pixel (x, y) and channel of `image` (any values, e.g. radiance) that holds
/// NaN or Inf; returns if all values are finite. Every solver below and
/// Reconstructor::reconstruct() end with it.
void check_finite_result(const ImageView& image, const std::string& what);

/// Exact solver of (a I + b L) x = rhs per channel, L = Dx^T Dx + Dy^T Dy with
/// the dropped border rows, through a 2-D DCT-II built on real FFTs.
/// FFTW plans are cached per image size for the life of the process (created
/// under a mutex, so any number of solvers may be constructed concurrently);
/// one solver object owns scratch memory and runs one solve at a time.
/// Work is split over rows / columns with TBB in the caller's task arena.
class DctSolver {
public:
    /// A solver for images of width x height pixels (both >= 1).
    DctSolver(int width, int height);
    ~DctSolver();
    DctSolver(const DctSolver&) = delete;
    DctSolver& operator=(const DctSolver&) = delete;

    /// x = (a I + b L)^-1 rhs for `channels` images, planar (plane stride
    /// width * height) or, if `interleaved`, with channels interleaved per
    /// pixel like Image. a > 0, b >= 0; rhs and x may alias. If a == 0 the
    /// constant component is left out (the minimum-norm Poisson solution).
    /// If `all_finite` is given it receives whether every value of x is
    /// finite (tested while x is written, so without another pass).
    void solve(const float* rhs, float* x, int channels, double a, double b, bool interleaved = false,
               bool* all_finite = nullptr);

    int width() const;   ///< Columns this solver was made for.
    int height() const;  ///< Rows this solver was made for.

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Per-row weights of a weighted least-squares step, one value per pixel,
/// shared by all channels of that residual row (unitless). Entries for the
/// dropped rows (last column of dx, last row of dy) are ignored.
struct RowWeights {
    std::vector<float> primal;  ///< Weight of alpha (x - c) at each pixel.
    std::vector<float> dx;      ///< Weight of (Dx x - gx) at each pixel.
    std::vector<float> dy;      ///< Weight of (Dy x - gy) at each pixel.
};

/// The exact L2 solution (unbiased) into `out` (width * height * channels
/// floats, interleaved like the inputs): one DCT solve of
/// (alpha^2 I + L) x = alpha^2 c + Dx^T gx + Dy^T gy, built in `out` and
/// solved in place. Keeps the DctSolver of the last image size it solved
/// (scratch of about 2 floats per value) per calling thread, so that a
/// renderer reconstructing frame after frame does not pay for fresh memory.
/// If that overflows (inputs near the float range), it is solved again on a
/// copy scaled by a power of two; throws RuntimeFailure naming the pixel if
/// the solution itself is beyond the float range (`out` then unspecified).
void poisson_l2(const PoissonProblem& problem, float* out);

/// Preconditioner of a CG solve.
enum class Preconditioner {
    none,       ///< Plain CG, as the reference implementation runs it.
    dct,        ///< The DCT solve of the constant-weight operator with the mean weights (exact for unit weights).
    multigrid,  ///< Aggregation multigrid V-cycle that follows the weights (best for IRLS steps).
};

/// Settings of a conjugate-gradient solve of a weighted normal system.
struct CgOptions {
    int max_iterations = 50;  ///< Upper bound on CG iterations.
    /// Stop when ||r|| <= tolerance * ||r0|| (r0: residual of the starting
    /// point, all channels together); 0 = always run max_iterations.
    double tolerance = 0.0;
    Preconditioner preconditioner = Preconditioner::multigrid;  ///< See Preconditioner.
};

/// What a CG solve did.
struct CgReport {
    int iterations = 0;                ///< CG iterations taken.
    double relative_residual = 0.0;    ///< ||r|| / ||r0|| at exit (recursively updated residual; last finite value).
    /// True if CG stopped because a curvature <p, A p> was not positive or a
    /// step, residual or curvature overflowed (e.g. weights near the float
    /// range); x then holds the last iterate, not a solution.
    bool breakdown = false;
};

/// Minimises the weighted L2 energy sum w_r |row residual r|^2 by (P)CG on
/// its normal equations, starting from and overwriting `x` (interleaved, same
/// shape as the inputs). `weights` == nullptr means all ones. Each channel
/// runs its own CG scalars, as in the reference. With max_iterations = 50,
/// Preconditioner::none and x = primal this is the reference's "L2D" preset.
/// A channel whose curvature <p, A p> is not positive or whose step is not
/// finite stops there (CgReport::breakdown); throws RuntimeFailure naming the
/// pixel if x ends non-finite.
CgReport poisson_weighted(const PoissonProblem& problem, const RowWeights* weights, const CgOptions& options,
                          float* x);

/// The reference's IRLS reweighting at iterate x: every residual row r (the
/// channel vector of alpha (x - c), Dx x - gx or Dy x - gy) gets weight
/// 1 / (||e_r|| + eps), then all weights are scaled to mean 1 over the rows
/// in use. eps in radiance units. Computed in the same scaled units as
/// poisson_l1, so huge residuals get tiny weights rather than NaN.
RowWeights irls_weights(const PoissonProblem& problem, const float* x, double eps);

/// Settings of the L1 (IRLS) solve. The defaults keep the reference's
/// schedule (20 IRLS steps, eps 0.05 halved per step) and spend 2 multigrid-
/// preconditioned CG iterations per step. Measured (benchmarks/
/// bench_reconstruct.cpp): L1 energy within 0.2% of a converged (40-step,
/// up to 30 CG per step) solve on the reference cbox buffers and on them tiled
/// to 1280x720, against a budget of 1%; one CG iteration per step gives 0.35%
/// at about 60% of the time; the output is within relMSE ~1e-6 of the
/// reference's own 20 x 50-plain-CG algorithm (which is itself not converged:
/// its result moves by 4e-7 with 100 CG iterations per step).
struct L1Options {
    /// IRLS iterations including the first, unweighted one (reference: 20).
    int iterations = 20;
    /// Upper bound on CG iterations per reweighted step.
    int cg_iterations = 2;
    /// Relative residual (to the step's initial one) at which a step's CG stops early.
    double tolerance = 1e-3;
    /// eps of the first reweighted step (radiance); reference 0.05.
    double eps_initial = 0.05;
    /// eps is multiplied by this after every reweighted step; reference 0.5.
    double eps_factor = 0.5;
    /// Start from the exact L2 solution (true) or, like the reference, from
    /// the primal followed by an unweighted CG step of cg_iterations.
    bool exact_l2_start = true;
    /// Preconditioner of every reweighted step's CG.
    Preconditioner preconditioner = Preconditioner::multigrid;
};

/// What an L1 solve did.
struct L1Report {
    int irls_iterations = 0;      ///< IRLS iterations run (including the first).
    int cg_iterations = 0;        ///< CG iterations summed over all steps.
    double energy = 0.0;          ///< poisson_energy_l1 of the result.
};

/// The L1 (robust, consistent but biased) reconstruction into `out`
/// (interleaved, same shape as the inputs) by IRLS with the reference's
/// weights and eps schedule eps_k = eps_initial * eps_factor^(k-1). A step's
/// weights are the reference's 1 / (|e_r| + eps) up to a common factor, which
/// does not change the solution; eps is never taken below 1e-9 times the
/// largest row residual of the previous iterate, where float arithmetic would
/// lose the small weights (the default schedule stays well above), counting
/// residuals beyond 1024 times the robust scale below as that much (they are
/// outliers, whose weight is meant to vanish).
/// Robustness (see the file comment): the solve runs on the data divided by
/// a power of two near their 99th percentile magnitude (exact, so ordinary
/// results are unchanged), with pixel vectors beyond 2^40 of that scale
/// shortened to it and eps not below 2^-40 of it; the starting point (either
/// kind) uses gradient rows shortened to 16 times the sum of their two
/// pixels' colours plus that scale. Throws RuntimeFailure naming the pixel if
/// the result is not finite.
L1Report poisson_l1(const PoissonProblem& problem, const L1Options& options, float* out);

/// The L1 energy of x (radiance): sum over rows of the Euclidean norm of the
/// row's channel vector, colour rows scaled by alpha; what IRLS minimises.
double poisson_energy_l1(const PoissonProblem& problem, const float* x);

/// The L2 energy of x (radiance^2): sum of squared row residuals, colour rows
/// scaled by alpha; what poisson_l2 minimises exactly.
double poisson_energy_l2(const PoissonProblem& problem, const float* x);

}  // namespace gdr
