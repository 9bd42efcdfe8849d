// Stop signals for the whole of a command (see stop.h).
#include "stop.h"

#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <vector>

namespace gdr::cli {

namespace {

std::atomic<bool> g_stop{false};   // first stop signal
std::atomic<bool> g_abort{false};  // second stop signal
std::atomic<int> g_signal{0};      // the last stop signal's number
std::atomic<bool> g_done{false};   // the command ended: the watcher's next signal of this process ends it

// What the watcher needs to know of the sections open in any thread.
struct SectionState {
    std::mutex mutex;
    std::condition_variable changed;
    int sections = 0;       // PolledStop and WriteSection scopes open
    int polled = 0;         // of which PolledStop
    bool exiting = false;   // the watcher ends the process once `sections` is 0
    std::vector<std::string> remove;  // remove_on_stop()
};

SectionState& state() {
    static SectionState s;
    return s;
}

// Sections a thread holds: only its outermost one waits for a stop in progress.
thread_local int t_depth = 0;

// Writes a message with write(2): the main thread may hold stdio's lock.
void tell(const std::string& text) {
    const ssize_t r = write(STDERR_FILENO, text.data(), text.size());
    (void)r;
}

const char* signal_name(int sig) { return sig == SIGINT ? "Ctrl-C (SIGINT)" : sig == SIGTERM ? "SIGTERM" : "a signal"; }

void on_stop(int sig) {
    SectionState& s = state();
    std::unique_lock<std::mutex> lock(s.mutex);
    const bool first = !g_stop.exchange(true);
    if (!first) g_abort = true;
    g_signal = sig;
    if (s.polled > 0) {
        tell(first ? "\ngdr: stopping within about a second, then writing the image (interrupt again to stop at once)\n"
                   : "\ngdr: stopping at once, writing only the finished passes\n");
        return;
    }
    s.exiting = true;
    if (s.sections > 0) tell(std::string("\ngdr: ") + signal_name(sig) + ": finishing the file being written, then stopping\n");
    s.changed.wait(lock, [&] { return s.sections == 0; });
    for (const std::string& p : s.remove) unlink(p.c_str());
    tell(std::string("gdr: stopped by ") + signal_name(sig) + "\n");
    _exit(128 + sig);
}

sigset_t stop_signals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    return set;
}

void watch() {
    // Its messages go to a stderr that may be a closed pipe (`2>&1 | head -1`):
    // with SIGPIPE blocked here the write fails with EPIPE instead of ending
    // the process, in the middle of a file being written.
    sigset_t pipe;
    sigemptyset(&pipe);
    sigaddset(&pipe, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe, nullptr);
    const sigset_t set = stop_signals();
    for (;;) {
        siginfo_t info;
        const int sig = sigwaitinfo(&set, &info);
        if (sig < 0) continue;  // EINTR
        // CommandSignals' destructor wakes the watcher with a signal from this
        // process (si_code does not tell a thread's signal apart everywhere).
        if (g_done && info.si_pid == getpid()) return;
        on_stop(sig);
    }
}

void enter(bool polled) {
    SectionState& s = state();
    std::unique_lock<std::mutex> lock(s.mutex);
    // A stop in progress: the process ends as soon as the open sections end,
    // so a new one must not start a file that would then be left half-written.
    if (t_depth == 0) s.changed.wait(lock, [&] { return !s.exiting; });
    ++t_depth, ++s.sections;
    if (polled) ++s.polled;
}

void leave(bool polled) {
    SectionState& s = state();
    {
        const std::lock_guard<std::mutex> lock(s.mutex);
        --t_depth, --s.sections;
        if (polled) --s.polled;
    }
    s.changed.notify_all();
}

}  // namespace

CommandSignals::CommandSignals() {
    g_stop = false;
    g_abort = false;
    g_signal = 0;
    g_done = false;
    const sigset_t set = stop_signals();
    // Blocked here before any worker thread starts, so every thread inherits
    // the mask and only the watcher takes the signals.
    if (pthread_sigmask(SIG_BLOCK, &set, &old_mask_) != 0) return;
    watcher_ = std::thread(watch);
    active_ = true;
}

CommandSignals::~CommandSignals() {
    if (!active_) return;
    g_done = true;
    pthread_kill(watcher_.native_handle(), SIGTERM);
    watcher_.join();
    pthread_sigmask(SIG_SETMASK, &old_mask_, nullptr);
}

PolledStop::PolledStop() { enter(true); }
PolledStop::~PolledStop() { leave(true); }
WriteSection::WriteSection() { enter(false); }
WriteSection::~WriteSection() { leave(false); }

std::atomic<bool>& stop_flag() { return g_stop; }
std::atomic<bool>& abort_flag() { return g_abort; }

int stop_status() {
    const int sig = g_signal.load();
    return sig ? 128 + sig : 0;
}

void remove_on_stop(const std::string& path) {
    SectionState& s = state();
    const std::lock_guard<std::mutex> lock(s.mutex);
    s.remove.push_back(path);
}

void forget_on_stop(const std::string& path) {
    SectionState& s = state();
    const std::lock_guard<std::mutex> lock(s.mutex);
    const auto it = std::find(s.remove.begin(), s.remove.end(), path);
    if (it != s.remove.end()) s.remove.erase(it);
}

}  // namespace gdr::cli
