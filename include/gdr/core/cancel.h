// Cooperative cancellation of a long computation on the calling thread: a
// caller that runs a reconstruction on a thread of its own (the Python
// module, which must answer Ctrl-C) sets a flag, and the solver's iteration
// loops check it between iterations and stop with gdr::Interrupted.
#pragma once

#include <atomic>

namespace gdr {

/// While alive, makes check_cancelled() on this thread throw once `*flag` is
/// true. Scopes nest; the innermost one is checked.
class CancelScope {
public:
    /// Watches `flag` (not owned; must outlive the scope) on this thread.
    explicit CancelScope(const std::atomic<bool>* flag);
    ~CancelScope();
    CancelScope(const CancelScope&) = delete;
    CancelScope& operator=(const CancelScope&) = delete;

private:
    const std::atomic<bool>* previous_;
};

/// Throws Interrupted ("`what` interrupted") if a CancelScope of this thread
/// has its flag set; otherwise nothing (one relaxed load: cheap enough per iteration).
void check_cancelled(const char* what);

}  // namespace gdr
