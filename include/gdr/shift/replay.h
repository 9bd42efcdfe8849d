// Random-number replay: the offset path is traced with exactly the random
// numbers of the base path; each vertex contributes J = pdf_x / pdf_y.
#pragma once

#include "gdr/shift/steps.h"

namespace gdr {

/// Random replay, which reconnects only onto the environment: where x_k and
/// y_k are connectable, the environment's light sample at x_k is shifted by
/// its direction, so a base that leaves the scene from there is shifted by
/// its direction too (shift::reconnect; the gradients' MIS weights need both
/// strategies of a path to shift it alike), and a replayed ray that leaves
/// the scene from there is refused (the inverse would have copied it).
struct ReplayShift {
    static constexpr std::string_view kName = "replay";
    /// Shifts vertex in.k.
    template <class H>
    ShiftStep step(const BasicShiftStepInput<H>& in) const {
        if (!shift::base_has_next(in)) return ShiftStep{};
        const bool both = shift::both_connectable(in);
        if (both && shift::base_next_infinite(in)) return shift::reconnect(in);
        ShiftStep s = shift::replay(in);
        s.reject_if_escapes = both;
        return s;
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
