// What the shift validators (validate.cpp, validate_bidir.cpp) share.
#pragma once

#include <vector>

#include "gdr/shift/validate.h"

namespace gdr {

using detail::finish_report;
using detail::step_as_sample;

}  // namespace gdr
