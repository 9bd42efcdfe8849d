// Temporal gradient-domain path tracing: Manzi, Kettunen, Durand,
// Zwicker and Lehtinen, "Temporal Gradient-Domain Path Tracing" (2016).
#pragma once

#include "gdr/integrators/integrator.h"

namespace gdr {

/// Registers "tgpt": per frame, two seed-shared G-PT halves, I(k, s=k)
/// replaying the previous frame's random numbers along the motion and
/// I(k, s=k+1) with the next frame's seed; their average is the frame's
/// primal and gradients (gpt's layers), and the halves are kept so that the
/// temporal difference dt_k = I(k+1, s=k+1) - I(k, s=k+1) can be formed
/// when frames are reconstructed together (temporal_layers::primal_a,
/// primal_b and replay; add_temporal_difference in reconstruct/temporal.h). One sample per pixel of tgpt is
/// one G-PT sample in each half.
void register_tgpt(Registry<Integrator>& r);

}  // namespace gdr
