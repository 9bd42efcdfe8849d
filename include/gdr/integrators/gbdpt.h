// Gradient-domain bidirectional path tracing (Manzi, Kettunen, Aittala,
// Lehtinen, Durand and Zwicker, "Gradient-Domain Bidirectional Path
// Tracing", 2015): every base path that bidirectional path tracing builds
// from a camera subpath and a light subpath is shifted to the four
// neighbouring pixels, the light subpath shared and the camera side mapped by
// a registered shift, and the balance heuristic over the strategies of both
// the base and its offset weighs the differences (docs/algorithms.md, "Bidirectional").
#pragma once

#include "gdr/integrators/integrator.h"

namespace gdr {

/// Registers "gbdpt".
void register_gbdpt(Registry<Integrator>& r);

}  // namespace gdr
