// The "neural" reconstructor: the U-Net of gdr/neural/unet.h behind the
// Reconstructor interface, so `gdr reconstruct --method neural` and library
// callers use it like the screened Poisson solvers.
#pragma once

#include <string>

#include "gdr/reconstruct/reconstructor.h"

namespace gdr::neural {

/// Adds "neural" to a reconstructor registry. Parameters: weights = path of a
/// file written by save_weights (InputError naming it if absent or not a gdr
/// U-Net; when not given, `default_weights`, and if that is empty too a
/// ParameterError asking for weights=PATH), threads = torch intra-op threads
/// (0 = one per hardware thread; torch's thread count is process-wide, so it
/// is set on every solve). The method reads the layers albedo, normal and
/// depth besides primal / dx / dy. `missing_default` (may be empty) is added
/// to the weights=PATH error, to say where a default model was looked for.
void register_neural_reconstructor(Registry<Reconstructor>& r, const std::string& default_weights = "",
                                   const std::string& missing_default = "");

}  // namespace gdr::neural
