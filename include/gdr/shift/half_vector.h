// The shift of Kettunen et al., "Gradient-Domain Path Tracing" (2015): reconnect as soon as x_k,
// y_k and x_{k+1} are connectable; otherwise copy the base's half-vector
// through the vertex (glossy and specular, reflection and refraction). When
// only x_{k+1} prevented the reconnection, the shift is undefined if the
// offset reaches a connectable y_{k+1}: the inverse would reconnect there.
#pragma once

#include "gdr/shift/steps.h"

namespace gdr {

/// Reconnection + half-vector copy.
struct HalfVectorShift {
    static constexpr std::string_view kName = "half-vector";
    /// Shifts vertex in.k.
    template <class H>
    ShiftStep step(const BasicShiftStepInput<H>& in) const { return shift::reconnect_or(in, shift::half_vector<H>); }
};
static_assert(ShiftMapping<HalfVectorShift>);

}  // namespace gdr
