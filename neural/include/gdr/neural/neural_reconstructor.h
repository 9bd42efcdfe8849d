// The "neural" reconstructor: the U-Net of gdr/neural/unet.h behind the
// Reconstructor interface, so `gdr reconstruct --method neural` and library
// callers use it like the screened Poisson solvers.
#pragma once

#include "gdr/reconstruct/reconstructor.h"

namespace gdr::neural {

/// Adds "neural" to a reconstructor registry. Parameters: weights = path of a
/// file written by save_weights (required; InputError naming it if absent or
/// not a gdr U-Net), threads = torch intra-op threads (0 = one per hardware
/// thread; torch's thread count is process-wide, so it is set on every solve).
/// The method reads the layers albedo, normal and depth besides primal / dx / dy.
void register_neural_reconstructor(Registry<Reconstructor>& r);

}  // namespace gdr::neural
