// The primal path tracer's core, reusable by other integrators and tests.
#pragma once

#include "gdr/core/sampler.h"
#include "gdr/integrators/integrator.h"
#include "gdr/path/path_tracer.h"

namespace gdr {

/// Registers "pt".
void register_pt(Registry<Integrator>& r);

}  // namespace gdr
