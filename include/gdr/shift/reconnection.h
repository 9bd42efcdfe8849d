// The reconnection shift: the offset follows its own primary ray to y_1 and
// reconnects to the base's x_2; it is defined only if y_1, x_1 and x_2 are
// all connectable and y_1 sees x_2.
#pragma once

#include "gdr/shift/steps.h"

namespace gdr {

/// Reconnect at the first vertex or fail.
struct ReconnectionShift {
    static constexpr std::string_view kName = "reconnection";
    /// Shifts vertex in.k (only the first vertex is ever shifted; later ones are shared).
    template <class H>
    ShiftStep step(const BasicShiftStepInput<H>& in) const {
        if (in.k == 1 && shift::can_reconnect(in)) return shift::reconnect(in);
        return ShiftStep{};
    }
};
static_assert(ShiftMapping<ReconnectionShift>);

}  // namespace gdr
