// What the shift validators (validate.cpp, validate_bidir.cpp) share.
#pragma once

#include <vector>

#include "gdr/shift/validate.h"

namespace gdr {

/// The BSDF sample a camera walk would have recorded for an offset step `s`
/// taken at a vertex entered from local direction `wo`, whose base vertex
/// sampled `base` there: the inverse shift reads it as its base's sample.
BsdfSample step_as_sample(const ShiftStep& s, const Vec3& wo, const BsdfSample& base);

/// Fills rep's Jacobian error statistics from the relative `errors` (sorted
/// here) and decides rep.passed from the required fraction of `o`.
void finish_report(ShiftReport& rep, std::vector<double>& errors, const ValidateOptions& o);

}  // namespace gdr
