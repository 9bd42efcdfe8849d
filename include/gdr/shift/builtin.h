// gdr's built-in shift mappings on any host (gdr/path/host.h): a renderer
// that runs the path-space core on its own scene makes its shifts here, by
// the names gdr's own integrators take (shift=half-vector, ...), and adds
// its own with register_shift<S>(shift_registry_on<MyHost>(), ...).
#pragma once

#include <memory>
#include <string>

#include "gdr/registry.h"
#include "gdr/shift/half_vector.h"
#include "gdr/shift/reconnection.h"
#include "gdr/shift/replay.h"
#include "gdr/shift/shift.h"

namespace gdr {

/// Adds the built-in shifts (half-vector, reconnection, replay,
/// replay-reconnect) to a registry of shifts on host H.
template <class H>
void register_builtin_shifts_on(Registry<BasicShift<H>>& r) {
    register_shift<HalfVectorShift>(r, "reconnection where possible, half-vector copy through glossy/specular vertices (PI)");
    register_shift<ReconnectionShift>(r, "reconnect at the first vertex, fail otherwise");
    register_shift<ReplayShift>(r, "random-number replay at every vertex");
    register_shift<ReplayReconnectShift>(r, "replay until connectable, then reconnect (survey's simple shift)");
}

/// The process-wide registry of shifts on host H, the built-in ones
/// registered (on gdr's Scene this is shift_registry()).
template <PathHost H>
Registry<BasicShift<H>>& shift_registry_on() {
    if constexpr (std::is_same_v<H, Scene>) return shift_registry();
    else return process_registry<BasicShift<H>>("shift mapping", register_builtin_shifts_on<H>);
}

/// Makes the registered shift `name` on host H with parameters `p` (a key
/// the shift does not read is refused: ParameterError naming it).
template <PathHost H>
std::unique_ptr<BasicShift<H>> make_shift_on(const std::string& name, const Params& p = Params()) {
    return shift_registry_on<H>().create(name, p);
}

}  // namespace gdr
