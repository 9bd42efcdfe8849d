// The gdr command-line tool: render scenes, inspect and compare EXR files,
// reconstruct gradient-domain renders.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"

int main(int argc, char** argv) {
    std::vector<std::string> args(argv + 1, argv + argc);
    try {
        return gdr::cli::run(args);
    } catch (const gdr::Error& e) {
        fmt::print(stderr, "gdr: error: {}\n", e.what());
        return gdr::cli::stop_status() ? gdr::cli::stop_status() : 1;
    } catch (const std::exception& e) {
        fmt::print(stderr, "gdr: error: {}\n", e.what());
        return gdr::cli::stop_status() ? gdr::cli::stop_status() : 1;
    }
}
