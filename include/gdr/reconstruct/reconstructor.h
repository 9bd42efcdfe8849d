// Reconstructors: turn a frame's primal and gradient buffers into the final
// image. They are created by name from a registry (like integrators) and work
// on plain float images, so a renderer that knows nothing else of gdr can
// fill three Images and call reconstruct() (examples/embed_reconstruct).
//
// Buffer conventions (docs/algorithms.md, "What is estimated: the gradient
// layout" and "Screened Poisson reconstruction"): row 0 at the top,
// dx(x,y) = I(x+1,y) - I(x,y) stored at the left pixel, dy(x,y) =
// I(x,y+1) - I(x,y) stored at the top pixel; the last column of dx and the
// last row of dy are unused. Directly visible emitters belong in `direct`,
// not in primal / dx / dy: they are added after reconstruction, as the
// authors' public Mitsuba implementation of Kettunen et al., "Gradient-Domain Path Tracing" (2015) does.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gdr/core/image.h"
#include "gdr/core/params.h"
#include "gdr/registry.h"

namespace gdr {

/// Non-owning pointers to one frame's buffers (radiance); all of one shape.
struct GradientBuffers {
    const Image* primal = nullptr;  ///< Colour estimate without directly visible emitters.
    const Image* dx = nullptr;      ///< Horizontal forward differences (see file comment).
    const Image* dy = nullptr;      ///< Vertical forward differences, y down.
    const Image* direct = nullptr;  ///< Optional: directly visible emitters, added after solving.
    // Optional layers for methods that weight by variance (poisson-weighted);
    // all of primal's shape except spp, which has one channel.
    const Image* primal_variance = nullptr;  ///< Per-sample variance of primal (radiance^2).
    const Image* dx_variance = nullptr;      ///< Per-sample variance of dx (radiance^2).
    const Image* dy_variance = nullptr;      ///< Per-sample variance of dy (radiance^2).
    const Image* spp = nullptr;              ///< Samples per pixel behind the means (1 channel, >= 1).

    /// Optional: the frame buffer holding further layers (albedo, normal,
    /// depth, variances...) that a method may ask for by name; nullptr if none.
    const FrameBuffer* layers = nullptr;

    /// The layer called `name`: the fields above for "primal", "dx", "dy" and
    /// "direct" (these win over `layers`), otherwise that layer of `layers`;
    /// nullptr if absent.
    const Image* layer(const std::string& name) const;
};

/// Owning storage of one frame's buffers; `direct` is empty when absent.
struct GradientFrame {
    Image primal;  ///< Colour estimate without directly visible emitters (radiance).
    Image dx;      ///< Horizontal forward differences (radiance).
    Image dy;      ///< Vertical forward differences (radiance).
    Image direct;  ///< Directly visible emitters (radiance), or empty.

    /// Pointers to the members (direct = nullptr if empty); valid while *this lives.
    GradientBuffers buffers() const;
};

/// Throws ParameterError if primal / dx / dy are missing or the buffers
/// present differ in shape (spp: width x height x 1), and InputError naming
/// the layer and the first pixel if any of them holds NaN or Inf.
void check_gradient_buffers(const GradientBuffers& in);

/// A reconstruction method. reconstruct() checks the input, adds `direct` and
/// checks the output around the method's own solve(), so no method can
/// forget any of them.
class Reconstructor {
public:
    virtual ~Reconstructor() = default;

    /// The final image (same shape as the inputs, radiance): check_gradient_buffers,
    /// then solve(), then + direct if present; throws RuntimeFailure naming the
    /// pixel (x, y) and channel if a value of the result is NaN or Inf.
    Image reconstruct(const GradientBuffers& in) const;

    /// The method's parameters as "key=value" lines (for file headers).
    virtual std::string describe() const = 0;

    /// Names of the layers beyond primal / dx / dy that solve() reads through
    /// GradientBuffers::layer(); reconstruct() checks that each is present,
    /// shaped like primal and finite (InputError naming a missing one).
    virtual std::vector<std::string> required_layers() const { return {}; }

protected:
    /// Reconstructs from checked, finite, equally shaped primal / dx / dy;
    /// must not add `direct` nor check the result (the caller does both).
    virtual Image solve(const GradientBuffers& in) const = 0;
};

/// The process-wide reconstructor registry, built-ins registered on first use.
Registry<Reconstructor>& reconstructor_registry();

/// Adds gdr's built-in reconstructors to a registry (poisson-l2, poisson-l1, ...).
void register_builtin_reconstructors(Registry<Reconstructor>& r);

/// Adds "poisson-weighted" (variance-weighted, outlier-robust screened
/// Poisson; needs the variance and spp layers; see gdr/reconstruct/weighted.h
/// and the registry description for its parameters).
void register_weighted_reconstructors(Registry<Reconstructor>& r);

/// Adds "poisson-l2" (exact DCT solve; parameter alpha) and "poisson-l1"
/// (IRLS with multigrid-preconditioned CG; alpha, iterations, cg_iterations,
/// tolerance as in L1Options, and preset = fast (default) | reference, the
/// latter running the slow "L1D" algorithm of the authors' public Mitsuba
/// implementation of Kettunen et al., "Gradient-Domain Path Tracing" (2015)).
void register_poisson_reconstructors(Registry<Reconstructor>& r);

/// One-call convenience: creates `method` from the registry with `params`
/// (unknown keys are errors) and returns its reconstruction including direct.
Image reconstruct(const std::string& method, const Params& params, const GradientBuffers& in);

/// Views of the layers "primal", "dx", "dy" and the optional "direct",
/// "primal_variance", "dx_variance", "dy_variance" and "spp" of a gdr frame
/// buffer, with `layers` = &fb for the rest (valid while `fb` lives);
/// InputError naming a missing layer.
GradientBuffers gradient_buffers(const FrameBuffer& fb);

}  // namespace gdr
