// What the shift validators (validate.cpp, validate_bidir.cpp) share.
#pragma once

#include <vector>

#include "gdr/shift/validate.h"

namespace gdr {

/// Fills rep's Jacobian error statistics from the relative `errors` (sorted
/// here) and decides rep.passed from the required fraction of `o`.
void finish_report(ShiftReport& rep, std::vector<double>& errors, const ValidateOptions& o);

}  // namespace gdr
