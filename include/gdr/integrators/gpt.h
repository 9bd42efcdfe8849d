// Gradient-domain path tracing (Kettunen et al., "Gradient-Domain Path Tracing" (2015)): the estimator of one
// base/offset pair.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gdr/integrators/integrator.h"
#include "gdr/shift/mis.h"
#include "gdr/shift/offset_path.h"

namespace gdr {

class Reconstructor;

/// Sums of the MIS-weighted contributions of one base path and its offset.
struct PairEstimate {
    Color base{0.f};      ///< Sum of w f(x)/q(x): the base's share of its own pixel (W/(m^2 sr)).
    Color offset{0.f};    ///< Sum of w f(y)|J|/q(x): the offset's share of the neighbour pixel.
    Color gradient{0.f};  ///< Sum of w (f(y)|J| - f(x))/q(x): an estimate of I_j - I_i.
};

/// What the base path contributes at each vertex, computed once and shared by
/// its four offsets. Densities are solid-angle (1/sr), contributions radiance.
struct BaseTerms {
    /// The terms of one base vertex x_k.
    struct Vertex {
        Color emitted{0.f};     ///< Radiance emitted by x_k towards x_{k-1} (W/(m^2 sr)).
        Color emit{0.f};        ///< f(x)/q(x) of the emitter hit at x_k by BSDF sampling at x_{k-1}.
        double emit_pdf_bsdf = 0.0;   ///< BSDF density of that direction at x_{k-1}.
        double emit_pdf_light = 0.0;  ///< Light-sampling density of it (0 if light sampling could not produce it).
        Color beta{0.f};        ///< Base throughput up to x_k (before it scatters).
        Color nee{0.f};         ///< f(x)/q(x) of the light sample at x_k (0 if blocked).
        Color nee_unit{0.f};    ///< The same without the throughput: f |cos| Le / pdf at x_k.
        double nee_pdf_light = 0.0;   ///< Light-sampling density of the light direction at x_k.
        double nee_pdf_bsdf = 0.0;    ///< BSDF density of that direction at x_k.
        double inv_nee_pdf_light = 0.0;  ///< 1 / nee_pdf_light (0 if that is 0), in sr.
        double inv_bs_pdf = 0.0;         ///< 1 / the BSDF density of the sampled direction at x_k (sr; 0 if none).
        double inv_scatter_pdf = 0.0;    ///< inv_bs_pdf / the Russian-roulette survival after x_k.
        Color scatter{0.f};              ///< Throughput of the scattering at x_k (scatter_weight; 0 if none).
        /// Path-tracing-MIS-weighted contributions of the light sample at x_k and of
        /// every later vertex, per unit throughput at x_k (emitter hit at x_k
        /// excluded). An offset that has merged with the base at x_k contributes
        /// its own throughput times this, scaled by one MIS factor (see evaluate_pair).
        Color suffix{0.f};
    };
    std::vector<Vertex> v;  ///< One entry per base vertex (v[0], the camera's, stays empty).
};

/// Fills `terms` for base path `x`; `heuristic` weighs the suffix sums.
void compute_base_terms(const Scene& scene, const CameraPath& x, MisHeuristic heuristic, BaseTerms& terms);

/// Evaluates every contribution (light sampling and emitter hits, from the second
/// vertex on: directly visible emitters are left out) of base path `x` and
/// offset `y` (nullptr or empty = the shift failed: plain path-tracing MIS).
/// The suffix an offset shares with the base is summed in closed form from
/// terms.suffix; `closed_form = false` walks it vertex by vertex instead (the
/// reference evaluation the closed form is tested against).
PairEstimate evaluate_pair(const Scene& scene, const CameraPath& x, const BaseTerms& terms, const OffsetPath* y,
                           const GradientMis& mis, bool closed_form = true);

/// The reconstructions a gradient-domain integrator (gpt, gbdpt) stores
/// beside its primal and gradients, from its `reconstruct` and `alpha` parameters.
struct GradientReconstructions {
    /// The `reconstruct` parameter as given: a comma list of registered
    /// reconstructor names (see methods_of()), "all" or "none".
    std::string choice = "all";
    double alpha = 0.2;  ///< Weight of the primal in the screened Poisson energy of poisson-l1, poisson-l2 (unitless).

    /// One chosen reconstruction.
    struct Method {
        std::string name;   ///< Registry name ("poisson-l1", a plugin's name).
        std::string layer;  ///< Its layer: reconstruction_layer(name).
        std::shared_ptr<const Reconstructor> made;  ///< Made once, from its parameters, when the integrator is.
    };
    std::vector<Method> methods;  ///< In the order `choice` names them.
    /// The reconstruct.* parameters as stored "key=value" lines, a text value
    /// as its reconstructor reports it in describe() where it does (a weights
    /// file made absolute), so a resume or merge elsewhere makes the same.
    std::string stored;

    /// Reads `reconstruct`, `alpha` and every `reconstruct.<key>` (to the one
    /// chosen reconstructor) or `reconstruct.<name>.<key>` (to reconstructor
    /// `name` of a list) for integrator `who`, and makes the reconstructors;
    /// throws ParameterError naming an unregistered name (with the registered
    /// ones), a key no chosen reconstructor reads, or `neural_weights` (now
    /// reconstruct.weights).
    static GradientReconstructions from(const Params& p, const std::string& who);
    /// The registry names a `reconstruct` value asks for, in order: a comma
    /// list of names, where the short names of the built-in solves stay
    /// (all = weighted,l1,l2; l1+l2; weighted = poisson-weighted; l1 =
    /// poisson-l1; l2 = poisson-l2) and none is the empty list. Names are not
    /// checked against the registry; ParameterError for an empty or repeated entry.
    static std::vector<std::string> methods_of(const std::string& choice, const std::string& who);
    /// The parameters above as "key=value" lines, for describe().
    std::string describe() const;
    /// Sets each chosen method's layer (radiance) from fb's primal and
    /// gradients, with the directly visible emitters added back. The weighted
    /// one reads the variances and the sample counts: `spp`, where fb has no
    /// spp layer yet (a render's own finalize(); TiledIntegrator adds it after).
    void add(FrameBuffer& fb, int64_t spp, const std::string& who) const;
};

/// The layer a render stores reconstructor `method`'s result in:
/// "reconstruction_<method>", except the built-in solves' short names
/// (reconstruction_weighted, reconstruction_l1, reconstruction_l2).
std::string reconstruction_layer(const std::string& method);

/// For a render with a "gradient_mask" layer (RenderSettings::gradient_mask):
/// sets every gradient layer (dx, dy, and combined shifts' dx_<shift>,
/// dy_<shift>) on each edge with a primal-only pixel, which has no gradient
/// estimate, to the difference of the two primal estimates (radiance), and
/// its variance layer to the sum of theirs (per sample, the far pixel's
/// scaled by the ratio of counts of the "spp" layer, if fb has one). A
/// reconstruction that knows nothing of the mask (poisson-l1, poisson-l2)
/// then gives back the primal where every edge is masked, as if those rows
/// were absent; poisson-weighted reads the mask and weights those rows zero.
/// Does nothing without a mask.
void fill_masked_gradients(FrameBuffer& fb);

/// Registers "gpt".
void register_gpt(Registry<Integrator>& r);

}  // namespace gdr
