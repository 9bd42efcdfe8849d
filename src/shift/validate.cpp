// gdr's own Scene's instance of the shift validator (gdr/shift/validate.h).
#include "gdr/shift/validate.h"

namespace gdr {

template ShiftReport validate_shift(const Scene&, const Shift&, const ShiftConfig&, const ValidateOptions&);

}  // namespace gdr
