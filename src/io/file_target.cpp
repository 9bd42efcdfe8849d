#include "file_target.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <thread>
#include <filesystem>

#include "gdr/core/error.h"

namespace gdr::io {

FileTarget file_target(const std::string& requested) {
    namespace fs = std::filesystem;
    static std::atomic<unsigned> counter{0};
    FileTarget t;
    t.path = requested;
    std::error_code ec;
    if (fs::exists(requested, ec)) {
        const fs::path resolved = fs::canonical(requested, ec);
        if (!ec) t.path = resolved.string();
        const fs::file_status st = fs::status(t.path, ec);
        if (!ec && !fs::is_regular_file(st) && !fs::is_directory(st)) {
            t.direct = true;
            t.write_path = t.path;
            return t;
        }
    }
    // A unique sibling, so concurrent writers never collide.
    t.write_path = t.path + ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
    return t;
}

void commit(const FileTarget& t) {
    if (t.direct) return;
    // For tests only: holds the finished temporary this many milliseconds
    // before the rename, so that a test can stop a process in that window.
    if (const char* delay = std::getenv("GDR_TEST_WRITE_DELAY_MS"))
        std::this_thread::sleep_for(std::chrono::milliseconds(std::strtol(delay, nullptr, 10)));
    std::error_code ec;
    std::filesystem::rename(t.write_path, t.path, ec);
    if (ec) {
        const std::string why = ec.message();
        discard(t);
        throw RuntimeFailure("cannot move '" + t.write_path + "' to '" + t.path + "': " + why);
    }
}

void discard(const FileTarget& t) noexcept {
    if (t.direct) return;
    std::error_code ec;
    std::filesystem::remove(t.write_path, ec);
}

}  // namespace gdr::io
