// Messages of the `gdr` tool on standard error.
#pragma once

#include <cstdio>
#include <utility>

#include <fmt/core.h>

namespace gdr::cli {

/// Prints a message to standard error. A closed or broken stderr (`2>&1 |
/// head -1`) is ignored: messages are optional, the files a command writes
/// are not.
template <typename... T>
void say(fmt::format_string<T...> format, T&&... args) {
    try {
        fmt::print(stderr, format, std::forward<T>(args)...);
    } catch (const std::exception&) {
    }
}

}  // namespace gdr::cli
