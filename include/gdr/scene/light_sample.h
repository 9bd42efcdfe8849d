// A light sample: a point on an emitter (or a direction to an environment
// or a delta light) as a renderer's light sampling returns it to the
// path-space core (gdr/path/host.h).
#pragma once

#include <cstdint>

#include "gdr/core/math.h"

namespace gdr {

struct DeltaLight;

/// A point sampled on an emitter, or a direction to the environment.
struct LightSample {
    Vec3 p{0.f};         ///< Position on the emitter; for an infinite sample a point beyond the scene along -n (see `infinite`).
    Vec3 n{0.f};         ///< Emitter's geometric (front) normal; for an infinite sample minus the sampled direction.
    Color radiance{0.f}; ///< Emitted radiance towards the reference point (0 if it sees the back side).
    /// Area-measure density including light selection (1/m^2); 0 for an
    /// infinite sample, which has no area density: code that does not know
    /// of environments thus drops such samples instead of misweighting them.
    float pdf_a = 0.f;
    uint32_t prim = 0;   ///< Emitting triangle (unset for an infinite sample).
    /// The sample is a direction wi = -n towards the environment (light from
    /// infinitely far away): its density is pdf_w, and p lies outside the
    /// scene's bounding sphere along wi from the reference point (from the
    /// bounds centre for sample_emitter_point()), so that a segment to p is a
    /// shadow ray towards the environment.
    bool infinite = false;
    float pdf_w = 0.f;   ///< Infinite samples: solid-angle density of -n including light selection (1/sr).
    /// The sample is on a delta light (delta_light.h), which no other
    /// strategy can reach: its MIS weight against BSDF sampling is 1.
    /// - Point or spot (`infinite` false): p is the light's position, n the
    ///   unit direction from it towards the reference point (so that the
    ///   cosine at the light is 1; along the spot's axis for
    ///   sample_emitter_point()), radiance its intensity towards the
    ///   reference point (W/sr) and pdf_a the discrete probability of
    ///   selecting it (unitless): the area-light estimate L f cos cos_l /
    ///   (r^2 pdf_a) is then I f cos / (r^2 p_select), the point light's.
    /// - Directional (`infinite` true): n is the direction light travels,
    ///   radiance the irradiance E (W/m^2 perpendicular to n) and pdf_w the
    ///   discrete selection probability: L f cos / pdf_w is E f cos / p_select.
    bool delta = false;
    const DeltaLight* delta_light = nullptr;  ///< The delta light sampled (if `delta`); owned by the Scene.
};

}  // namespace gdr
