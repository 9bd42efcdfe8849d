// gdr's own Scene's instances of the shift steps (gdr/shift/steps.h).
#include "gdr/shift/steps.h"

namespace gdr::shift {

template ShiftStep reconnect(const ShiftStepInput&);
template ShiftStep half_vector(const ShiftStepInput&);
template ShiftStep replay(const ShiftStepInput&);
template ShiftStep reconnect_or(const ShiftStepInput&, ShiftStep (*)(const ShiftStepInput&));

}  // namespace gdr::shift
