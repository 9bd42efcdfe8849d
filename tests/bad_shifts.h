// Deliberately wrong shift mappings: the validators' tests show that they catch them.
#pragma once

#include <algorithm>
#include <cmath>

#include "gdr/shift/steps.h"

namespace gdr::test {

/// A reconnection whose Jacobian forgets the cosine ratio at the vertex it reconnects to.
struct BadReconnection {
    static constexpr std::string_view kName = "bad-reconnection";
    ShiftStep step(const ShiftStepInput& in) const {
        if (in.k != 1 || !shift::can_reconnect(in)) return ShiftStep{};
        ShiftStep s = shift::reconnect(in);
        const Vec3 d = in.base.v[2].si.p - in.y.si.p;
        s.jacobian /= std::max(std::abs(glm::dot(glm::normalize(d), in.base.v[2].si.ng)), 1e-3f);
        return s;
    }
};

}  // namespace gdr::test
