// Helpers of the tests that run the gdr tool in-process through cli::run.
#pragma once

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"

namespace gdr::test {

/// A fresh directory named gdr-test-NAME-PID in the temporary directory, removed when destroyed.
struct OutDir {
    std::filesystem::path path;
    explicit OutDir(const std::string& name)
        : path(std::filesystem::temp_directory_path() / ("gdr-test-" + name + "-" + std::to_string(getpid()))) {
        std::filesystem::create_directories(path);
    }
    ~OutDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
    /// The path of `file` inside the directory.
    std::string operator()(const std::string& file) const { return (path / file).string(); }
};

/// The message of the gdr::Error that cli::run throws for `args` ("" if none).
inline std::string error_of(const std::vector<std::string>& args) {
    try {
        cli::run(args);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

/// The bytes of the file at `path` ("" if it cannot be read).
inline std::string file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

/// What `fn` prints on stdout; stdout is restored before an exception propagates.
template <typename Fn>
std::string stdout_of(Fn&& fn) {
    std::fflush(stdout);
    FILE* tmp = std::tmpfile();
    if (!tmp) throw RuntimeFailure("stdout_of: no temporary file");
    const int saved = dup(fileno(stdout));
    dup2(fileno(tmp), fileno(stdout));
    const auto restore = [&] {
        std::fflush(stdout);
        dup2(saved, fileno(stdout));
        close(saved);
    };
    try {
        fn();
    } catch (...) {
        restore();
        std::fclose(tmp);
        throw;
    }
    restore();
    std::string text;
    std::rewind(tmp);
    for (int c; (c = std::fgetc(tmp)) != EOF;) text += char(c);
    std::fclose(tmp);
    return text;
}

}  // namespace gdr::test
