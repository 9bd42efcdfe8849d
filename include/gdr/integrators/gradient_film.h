// The gradient-domain film: where the samples of a gradient-domain integrator
// go, and how the shares a base path and its four offset paths leave in
// neighbouring pixels become the primal image, its finite differences dx and
// dy, their per-sample variances and the standard layers. gpt, gbdpt and
// tgpt are written on it, and so can an integrator outside the library (see
// examples/gradient_integrator): declare GradientLayout::slots() as the
// integrator's slots, write each sample through a GradientRecord, and in
// finalize() call gather_gradients() and set_gradient_layers(). The
// reconstructions (GradientReconstructions, gdr/integrators/gpt.h) then run
// on the layers, after the render (Integrator::update_merged).
//
// A sample of pixel p writes only p's own record, so that images stay
// bit-identical for any thread count: the share its offset path leaves in
// neighbour q = p + step(d) is stored at p under direction d and gathered
// into q's primal when the render finishes, and the gradient across an edge
// combines the one-sided estimates of the two pixels that share it
// (Kettunen, Manzi, Aittala, Lehtinen, Durand and Zwicker, "Gradient-Domain
// Path Tracing", 2015, section 5; docs/algorithms.md, "Gradient layout").
#pragma once

#include <string>
#include <vector>

#include "gdr/core/image.h"
#include "gdr/core/math.h"
#include "gdr/integrators/tiled.h"

namespace gdr {

/// Neighbours a base path is shifted to, in record order: +x, -x, +y, -y.
constexpr int kNeighbours = 4;
/// Column step (pixels) towards each neighbour.
inline constexpr int kNeighbourDx[kNeighbours] = {1, -1, 0, 0};
/// Row step (pixels, y down) towards each neighbour.
inline constexpr int kNeighbourDy[kNeighbours] = {0, 0, 1, -1};

/// The float offsets of the standard slots in one gradient-domain sample's
/// record (the `out` array TiledIntegrator::sample_batch() fills), derived
/// from the slot list itself so that no offset is written by hand.
/// Integrator-specific slots may follow (slot_offset() finds them).
struct GradientLayout {
    std::string prefix;              ///< Prefix of every slot name ("" for one set of samples; tgpt: "a", "b").
    int self = 0;                    ///< The base path's own share of its pixel (RGB radiance).
    int gradient[kNeighbours] = {};  ///< One-sided gradient towards each neighbour (RGB radiance difference).
    int share[kNeighbours] = {};     ///< The offset path's share of each neighbour's primal (RGB radiance).
    int direct = 0;                  ///< Directly visible emission, kept out of primal and gradients (RGB radiance).
    int albedo = 0;                  ///< Albedo at the first vertex a reconstruction can use (RGB, unitless).
    int normal = 0;                  ///< Its shading normal (unit vector, world space).
    int depth = 0;                   ///< Distance to the first hit (scene units; 0 where the ray left the scene).
    int floats = 0;                  ///< Floats of the standard slots; integrator-specific ones start here.

    /// The layout of the standard slots named with `prefix`.
    static GradientLayout make(const std::string& prefix = "");
    /// Name (without prefix) of the one-sided gradient slot towards neighbour d: "g+x", "g-x", "g+y", "g-y".
    static const char* gradient_name(int d);
    /// Name (without prefix) of the offset-share slot towards neighbour d: "s+x", "s-x", "s+y", "s-y".
    static const char* share_name(int d);
    /// The standard slots (self, the one-sided gradients and shares with
    /// their variances, direct, albedo, normal, depth), in record order.
    std::vector<SlotSpec> slots() const;
};

/// First float of slot `name` in a record of `specs` (the slots in record
/// order); throws ParameterError naming it if absent.
int slot_offset(const std::vector<SlotSpec>& specs, const std::string& name);

/// One sample's record, written through a GradientLayout's named offsets.
/// Values add up: a base path may contribute several terms to one slot.
class GradientRecord {
public:
    /// Writes to `out` (the sample's record, zero-initialised) with `layout`.
    GradientRecord(float* out, const GradientLayout& layout) : out_(out), layout_(layout) {}
    /// Adds to the base path's own share of its pixel (radiance).
    void add_self(const Color& c) { add(layout_.self, c); }
    /// Adds to the one-sided gradient towards neighbour d (radiance difference f(y) - f(x), MIS-weighted).
    void add_gradient(int d, const Color& c) { add(layout_.gradient[d], c); }
    /// Adds to the offset path's share of neighbour d's primal (radiance).
    void add_share(int d, const Color& c) { add(layout_.share[d], c); }
    /// Adds directly visible emission (radiance), which gradients leave out.
    void add_direct(const Color& c) { add(layout_.direct, c); }
    /// The pair of the base path and its offset towards neighbour d, as
    /// estimated by evaluate_pair(): each of the four pairs carries a quarter
    /// of the base's and the offset's primal estimates.
    void add_pair(int d, const Color& base, const Color& offset, const Color& gradient) {
        add_self(0.25f * base);
        add_gradient(d, gradient);
        add_share(d, 0.25f * offset);
    }
    /// A direction with no neighbour to pair with (the border, or a pixel
    /// without gradients): the base alone estimates its quarter.
    void add_alone(const Color& base) { add_self(0.25f * base); }
    /// Sets the albedo (RGB, unitless) and shading normal (unit vector) features.
    void set_surface(const Color& albedo, const Vec3& normal) {
        set(layout_.albedo, albedo);
        out_[layout_.normal] = normal.x, out_[layout_.normal + 1] = normal.y, out_[layout_.normal + 2] = normal.z;
    }
    /// Sets the depth feature (scene units; 0 for a ray that left the scene).
    void set_depth(float t) { out_[layout_.depth] = t; }
    /// Adds an RGB value at float `offset` (an integrator-specific slot, from slot_offset()).
    void add(int offset, const Color& c) { out_[offset] += c.r, out_[offset + 1] += c.g, out_[offset + 2] += c.b; }
    /// Sets an RGB value at float `offset`.
    void set(int offset, const Color& c) { out_[offset] = c.r, out_[offset + 1] = c.g, out_[offset + 2] = c.b; }

private:
    float* out_;
    const GradientLayout& layout_;
};

/// One set of gradient-domain samples' estimates, per pixel (RGB radiance;
/// variances per sample, in radiance squared).
struct GradientEstimates {
    Image primal;      ///< Each pixel's own share plus its neighbours' offset shares.
    Image primal_var;  ///< Per-sample variance of primal.
    Image dx;          ///< I(x + 1, y) - I(x, y); 0 in the last column.
    Image dy;          ///< I(x, y + 1) - I(x, y); 0 in the last row.
    Image dx_var;      ///< Per-sample variance of dx.
    Image dy_var;      ///< Per-sample variance of dy.
};

/// Gathers the samples of `layout`'s slots into primal, dx and dy: the
/// primal of pixel p adds p's own share and the shares its neighbours' offset
/// paths left towards it, and dx(x) combines the pair shifted each way across
/// the edge. Under adaptive sampling a neighbour's per-sample variance is
/// scaled by count(p) / count(neighbour), so every variance is over the
/// pixel's own count. With `light_splats`, the integrator's splat layers hold
/// light tracing's primal (layer 0) and one-sided gradients (layer 1 + d),
/// which are added to the pixel's own terms (gbdpt).
GradientEstimates gather_gradients(const Accumulated& acc, const GradientLayout& layout, bool light_splats = false);

/// Sets the standard gradient-domain layers of `out` from `g` and the
/// accumulated features of `layout`: color (primal + direct), primal, dx, dy,
/// direct, primal_variance, dx_variance, dy_variance, albedo, normal, depth,
/// and spp under adaptive sampling.
void set_gradient_layers(FrameBuffer& out, GradientEstimates&& g, const Accumulated& acc,
                         const GradientLayout& layout);

}  // namespace gdr
