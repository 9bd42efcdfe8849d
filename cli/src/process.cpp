// Running other programs without a shell (see process.h).
#include "process.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <exception>

extern char** environ;

namespace gdr::cli {

std::string find_program(const std::string& program) {
    if (program.find('/') != std::string::npos) return access(program.c_str(), X_OK) == 0 ? program : "";
    const char* path = std::getenv("PATH");
    const std::string dirs = path ? path : "/usr/bin:/bin";
    for (size_t at = 0; at <= dirs.size();) {
        const size_t end = std::min(dirs.find(':', at), dirs.size());
        const std::string dir = end > at ? dirs.substr(at, end - at) : ".";
        const std::string candidate = dir + "/" + program;
        if (access(candidate.c_str(), X_OK) == 0) return candidate;
        at = end + 1;
    }
    return "";
}

namespace {

// Ignores SIGPIPE while it lives: a program that exits before taking all its
// input must make write() fail with EPIPE, not kill the gdr tool.
struct IgnorePipe {
    void (*old)(int) = std::signal(SIGPIPE, SIG_IGN);
    ~IgnorePipe() { std::signal(SIGPIPE, old); }
};

// run_program() and run_program_fed(): standard input from /dev/null when `feed` is null.
ProgramResult run(const std::vector<std::string>& argv, const std::function<std::string()>* feed) {
    ProgramResult r;
    if (argv.empty()) return r;
    int out_pipe[2], err_pipe[2], in_pipe[2] = {-1, -1};
    if (pipe2(out_pipe, O_CLOEXEC) != 0) {
        r.err = std::string("pipe: ") + std::strerror(errno);
        return r;
    }
    if (pipe2(err_pipe, O_CLOEXEC) != 0) {
        r.err = std::string("pipe: ") + std::strerror(errno);
        close(out_pipe[0]), close(out_pipe[1]);
        return r;
    }
    if (feed && pipe2(in_pipe, O_CLOEXEC) != 0) {
        r.err = std::string("pipe: ") + std::strerror(errno);
        close(out_pipe[0]), close(out_pipe[1]), close(err_pipe[0]), close(err_pipe[1]);
        return r;
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    if (feed) posix_spawn_file_actions_adddup2(&actions, in_pipe[0], 0);
    else posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&actions, out_pipe[1], 1);
    posix_spawn_file_actions_adddup2(&actions, err_pipe[1], 2);
    std::vector<char*> cargv;
    for (const std::string& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
    cargv.push_back(nullptr);
    // The program starts with no signal blocked: the gdr tool blocks SIGINT
    // and SIGTERM in its threads (stop.h), and a blocked mask is inherited.
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t none;
    sigemptyset(&none);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK);
    pid_t pid = -1;
    const int rc = posix_spawnp(&pid, argv[0].c_str(), &actions, &attr, cargv.data(), environ);
    posix_spawnattr_destroy(&attr);
    posix_spawn_file_actions_destroy(&actions);
    close(out_pipe[1]), close(err_pipe[1]);
    if (feed) close(in_pipe[0]);
    if (rc != 0) {
        close(out_pipe[0]), close(err_pipe[0]);
        if (feed) close(in_pipe[1]);
        r.err = argv[0] + ": " + std::strerror(rc);
        return r;
    }
    r.started = true;
    // Set after the spawn: an ignored SIGPIPE would be inherited by the program.
    const IgnorePipe ignore_pipe;
    // Non-blocking, so that a write never waits for the program while it waits for us to read its output.
    if (feed) fcntl(in_pipe[1], F_SETFL, fcntl(in_pipe[1], F_GETFL) | O_NONBLOCK);
    // All pipes at once: a program that fills one while we wait on another would block.
    pollfd fds[3] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}, {feed ? in_pipe[1] : -1, POLLOUT, 0}};
    std::string* sinks[2] = {&r.out, &r.err};
    std::string pending;  // input taken from `feed` and not yet written
    size_t written = 0;
    const auto close_input = [&] {
        if (fds[2].fd >= 0) close(fds[2].fd);
        fds[2].fd = -1;
    };
    std::exception_ptr failure;
    char buf[4096];
    while (fds[0].fd >= 0 || fds[1].fd >= 0 || fds[2].fd >= 0) {
        if (poll(fds, 3, -1) < 0) {
            if (errno == EINTR) continue;
            break;
        }
        for (int k = 0; k < 2; ++k) {
            if (fds[k].fd < 0 || !(fds[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
            const ssize_t n = read(fds[k].fd, buf, sizeof buf);
            if (n > 0) {
                sinks[k]->append(buf, size_t(n));
            } else if (n == 0 || errno != EINTR) {
                close(fds[k].fd);
                fds[k].fd = -1;
            }
        }
        if (fds[2].fd < 0 || !(fds[2].revents & (POLLOUT | POLLHUP | POLLERR))) continue;
        if (fds[2].revents & (POLLHUP | POLLERR)) {  // the program closed its input
            close_input();
            continue;
        }
        if (written == pending.size()) {
            try {
                pending = (*feed)();
            } catch (...) {
                failure = std::current_exception();
                break;
            }
            written = 0;
            if (pending.empty()) {
                close_input();
                continue;
            }
        }
        const ssize_t n = write(fds[2].fd, pending.data() + written, pending.size() - written);
        if (n > 0) written += size_t(n);
        else if (n < 0 && errno != EAGAIN && errno != EINTR) close_input();  // EPIPE: it stopped reading
    }
    for (const pollfd& f : fds)
        if (f.fd >= 0) close(f.fd);
    if (failure) kill(pid, SIGTERM);
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR) {
    }
    if (failure) std::rethrow_exception(failure);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1;
    return r;
}

}  // namespace

ProgramResult run_program(const std::vector<std::string>& argv) { return run(argv, nullptr); }

ProgramResult run_program_fed(const std::vector<std::string>& argv, const std::function<std::string()>& next_input) {
    return run(argv, &next_input);
}

}  // namespace gdr::cli
