// Exclusive outputs (see output_lock.h).
#include "output_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>

#include <fmt/core.h>

#include "gdr/core/error.h"
#include "say.h"
#include "stop.h"

namespace gdr::cli {

namespace fs = std::filesystem;

std::string lock_path(const std::string& out) {
    std::error_code ec;
    // Through a symlink: two runs that name one file by different links share its lock.
    const fs::path resolved = fs::weakly_canonical(out, ec);
    return (ec ? fs::path(out) : resolved).string() + ".lock";
}

namespace {

// Who holds a lock, as its holder wrote it into the lock file ("" if not yet written).
std::string holder_of(int fd) {
    std::string text;
    char buf[512];
    ssize_t n = 0;
    for (off_t at = 0; (n = pread(fd, buf, sizeof buf, at)) > 0 && text.size() < 4096; at += n) text.append(buf, size_t(n));
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text;
}

}  // namespace

OutputLock::OutputLock(const std::string& out, const std::string& command) {
    std::error_code ec;
    if (fs::exists(out, ec) && !fs::is_regular_file(out, ec)) return;  // a device: nothing to keep apart
    const std::string path = lock_path(out);
    // A few tries: the holder removes the file as it ends, so the file opened
    // may be gone (or replaced) by the time the lock is granted.
    for (int attempt = 0; attempt < 16; ++attempt) {
        const int fd = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
        if (fd < 0)
            throw RuntimeFailure("cannot create the lock file " + path + " of " + out + ": " + std::strerror(errno));
        if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            const int err = errno;
            if (err == EWOULDBLOCK) {
                const std::string holder = holder_of(fd);
                close(fd);
                throw InputError("refusing to write " + out + ": another run is writing it (" +
                                 (holder.empty() ? std::string("its lock file ") + path + " names no holder yet"
                                                 : holder) +
                                 "); run again once it has ended");
            }
            close(fd);
            // No flock on this file system: the documented fallback (output_lock.h).
            say("warning: {}: no lock could be taken ({}); another run to {} at the same time would not be refused\n",
                path, std::strerror(err), out);
            return;
        }
        struct stat held {}, now {};
        if (fstat(fd, &held) != 0 || stat(path.c_str(), &now) != 0 || held.st_ino != now.st_ino ||
            held.st_dev != now.st_dev) {
            close(fd);
            continue;
        }
        char host[256] = "unknown host";
        if (gethostname(host, sizeof host) != 0) std::strcpy(host, "unknown host");
        host[sizeof host - 1] = '\0';
        const std::time_t t = std::time(nullptr);
        char when[32] = "";
        std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S UTC", std::gmtime(&t));
        const std::string text = fmt::format("pid {} on host {}, {}, since {}\n", getpid(), host, command, when);
        if (ftruncate(fd, 0) == 0) {
            const ssize_t w = pwrite(fd, text.data(), text.size(), 0);
            (void)w;  // the name of the holder helps a message; the lock holds without it
        }
        fd_ = fd;
        path_ = path;
        remove_on_stop(path_);
        return;
    }
    throw RuntimeFailure("cannot take the lock " + path + " of " + out + ": it keeps being replaced");
}

OutputLock::~OutputLock() {
    if (fd_ < 0) return;
    forget_on_stop(path_);
    // Removed while still held, so that a waiting run re-opens a new file
    // (the inode check above) rather than locking the removed one.
    unlink(path_.c_str());
    close(fd_);
}

std::string file_digest(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return "";
    uint64_t h = 1469598103934665603ull;  // FNV-1a, 64 bits
    char buf[1 << 16];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
        for (std::streamsize i = 0; i < in.gcount(); ++i) h = (h ^ uint8_t(buf[i])) * 1099511628211ull;
        if (!in) break;
    }
    return fmt::format("{:016x}", h);
}

}  // namespace gdr::cli
