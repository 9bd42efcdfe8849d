// Gradient-domain path tracing (Kettunen et al., "Gradient-Domain Path
// Tracing", 2015): the integrator's settings and reconstructions; the
// estimator of one base/offset pair is in gdr/shift/gradient_estimate.h.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gdr/integrators/integrator.h"
#include "gdr/shift/mis.h"
#include "gdr/shift/gradient_estimate.h"
#include "gdr/shift/offset_path.h"

namespace gdr {

class Reconstructor;

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
