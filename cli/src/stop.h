// Ctrl-C (SIGINT) and SIGTERM for the whole of one command of the gdr tool.
//
// While a command runs (CommandSignals), both signals are blocked in every
// thread and taken by one watcher thread, so that no signal can land in the
// middle of a file being written. What a signal does depends on what the
// command is doing at that moment:
//   - in a PolledStop scope (sampling a render and writing it, encoding a
//     video): it only sets stop_flag() (and, the second time, abort_flag()),
//     which the work polls; the command then finishes what it holds, writes
//     it and returns stop_status();
//   - in a WriteSection (replacing an output through a temporary): the
//     watcher waits for the section to end, so the file is complete, then
//     ends the process with 128 + the signal;
//   - elsewhere (loading, reading, solving: nothing to keep): it ends the
//     process at once with 128 + the signal.
// Files registered with remove_on_stop() (lock files) are removed first. The
// status follows the shell's convention: 130 for SIGINT, 143 for SIGTERM.
#pragma once

#include <atomic>
#include <string>
#include <thread>

#include "gdr/cli/commands.h"

#include <signal.h>

namespace gdr::cli {

/// Takes SIGINT and SIGTERM for as long as it lives (one command); clears the stop flags when made.
class CommandSignals {
public:
    CommandSignals();
    ~CommandSignals();
    CommandSignals(const CommandSignals&) = delete;
    CommandSignals& operator=(const CommandSignals&) = delete;

private:
    sigset_t old_mask_;
    std::thread watcher_;
    bool active_ = false;
};

/// While one lives, a stop signal only sets the flags (the work polls them and stops itself).
class PolledStop {
public:
    PolledStop();
    ~PolledStop();
    PolledStop(const PolledStop&) = delete;
    PolledStop& operator=(const PolledStop&) = delete;
};

/// While one lives, a stop signal waits for it to end (the file it writes is
/// then complete) and ends the process afterwards.
class WriteSection {
public:
    WriteSection();
    ~WriteSection();
    WriteSection(const WriteSection&) = delete;
    WriteSection& operator=(const WriteSection&) = delete;
};

/// Set by the first stop signal: stop within about a second (RenderSettings::cancel).
std::atomic<bool>& stop_flag();

/// Set by the second stop signal: stop at once (RenderSettings::abort).
std::atomic<bool>& abort_flag();

/// Removes `path` if the process is ended by a stop signal (until forget_on_stop(path)).
void remove_on_stop(const std::string& path);

/// Undoes remove_on_stop(path).
void forget_on_stop(const std::string& path);

}  // namespace gdr::cli
