// Cooperative cancellation (see gdr/core/cancel.h).
#include "gdr/core/cancel.h"

#include <string>

#include "gdr/core/error.h"

namespace gdr {
namespace {
// Per thread: a solver checks on the thread that runs its iteration loop.
thread_local const std::atomic<bool>* t_flag = nullptr;
}  // namespace

CancelScope::CancelScope(const std::atomic<bool>* flag) : previous_(t_flag) { t_flag = flag; }

CancelScope::~CancelScope() { t_flag = previous_; }

void check_cancelled(const char* what) {
    if (t_flag && t_flag->load(std::memory_order_relaxed)) throw Interrupted(std::string(what) + " interrupted");
}

}  // namespace gdr
