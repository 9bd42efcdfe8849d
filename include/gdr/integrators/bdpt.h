// Bidirectional path tracing on the path-space core.
#pragma once

#include "gdr/integrators/integrator.h"

namespace gdr {

/// Registers "bdpt": every (s, t) strategy (s = 0 camera walks that hit an
/// emitter, s = 1 next-event estimation, t = 1 light tracing, splatted)
/// combined by the power or balance heuristic. Layers as "pt" (color,
/// albedo, normal, depth, variance, spp); strategy_layers=true adds each
/// strategy's weighted contribution for paths up to 4 segments as
/// "strategy_s<S>_t<T>".
void register_bdpt(Registry<Integrator>& r);

}  // namespace gdr
