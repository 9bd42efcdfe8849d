// Random-number replay: the offset path is traced with exactly the random
// numbers of the base path; each vertex contributes J = pdf_x / pdf_y.
#pragma once

#include "gdr/shift/steps.h"

namespace gdr {

/// Pure random replay (never reconnects).
struct ReplayShift {
    static constexpr std::string_view kName = "replay";
    /// Shifts vertex in.k.
    template <class H>
    ShiftStep step(const BasicShiftStepInput<H>& in) const {
        if (!shift::base_has_next(in)) return ShiftStep{};
        return shift::replay(in);
    }
};
static_assert(ShiftMapping<ReplayShift>);

/// The survey's simple shift (thesis 4.3.4): replay until x_k, y_k and x_{k+1}
/// are connectable, then reconnect.
struct ReplayReconnectShift {
    static constexpr std::string_view kName = "replay-reconnect";
    /// Shifts vertex in.k.
    template <class H>
    ShiftStep step(const BasicShiftStepInput<H>& in) const { return shift::reconnect_or(in, shift::replay<H>); }
};
static_assert(ShiftMapping<ReplayReconnectShift>);

}  // namespace gdr
