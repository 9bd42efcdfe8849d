// Runs the real gdr binary from a test, as a separate process: what a user
// sees (exit status, messages), including process-wide start-up such as the
// plugin search, which an in-process cli::run shares with other tests.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern char** environ;

namespace gdr::test {

/// What a run of a program did.
struct ToolRun {
    int status = -1;     ///< Exit status (128 + N if killed by signal N, -1 if it could not start).
    std::string output;  ///< Its standard output and standard error, interleaved.
};

/// Runs `program` with `args`, standard input from /dev/null, standard output
/// and error into `log` (a file path, overwritten), with GDR_PLUGIN_PATH set
/// to `plugin_path` unless that is nullptr (then the variable is as in this
/// process), and waits for it.
inline ToolRun run_tool(const std::string& program, const std::vector<std::string>& args, const std::string& log,
                        const char* plugin_path = nullptr) {
    std::vector<std::string> env;
    for (char** e = environ; *e; ++e)
        if (!plugin_path || std::string(*e).rfind("GDR_PLUGIN_PATH=", 0) != 0) env.emplace_back(*e);
    if (plugin_path) env.push_back(std::string("GDR_PLUGIN_PATH=") + plugin_path);
    std::vector<char*> envp, argv{const_cast<char*>(program.c_str())};
    for (std::string& e : env) envp.push_back(e.data());
    envp.push_back(nullptr);
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    pid_t pid = 0;
    ToolRun r;
    const int rc = posix_spawn(&pid, program.c_str(), &fa, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) return r;
    int ws = 0;
    while (waitpid(pid, &ws, 0) < 0)
        if (errno != EINTR) return r;
    r.status = WIFEXITED(ws) ? WEXITSTATUS(ws) : 128 + WTERMSIG(ws);
    std::ifstream in(log, std::ios::binary);
    r.output.assign(std::istreambuf_iterator<char>(in), {});
    return r;
}

}  // namespace gdr::test
