// Running other programs (sbatch, squeue, sacct, scancel, ffmpeg) from the gdr
// tool: by argument vector, never through a shell, so no path needs quoting.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace gdr::cli {

/// What a program run by run_program() did.
struct ProgramResult {
    bool started = false;  ///< False if it could not be started (not found, not executable).
    int status = -1;       ///< Its exit status; 128 + N if killed by signal N; -1 if not started.
    std::string out;       ///< Everything it wrote to standard output.
    std::string err;       ///< Everything it wrote to standard error (or why it could not start).
};

/// Runs argv[0] (looked up on PATH) with the arguments argv[1..], standard
/// input from /dev/null, and waits for it.
ProgramResult run_program(const std::vector<std::string>& argv);

/// Runs argv[0] (looked up on PATH) as run_program() does, but with standard
/// input a pipe fed by `next_input`: called whenever the program can take
/// more, it returns the next bytes, or "" at the end (the pipe is then
/// closed). Feeding stops early if the program closes its input (its status
/// says why). If `next_input` throws, the program is killed and waited for
/// before the exception propagates, so no child outlives the call.
ProgramResult run_program_fed(const std::vector<std::string>& argv, const std::function<std::string()>& next_input);

/// The full path of `program` on PATH, "" if none is executable.
std::string find_program(const std::string& program);

}  // namespace gdr::cli
