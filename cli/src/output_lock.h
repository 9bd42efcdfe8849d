// Exclusive outputs: a command that writes OUT holds an advisory lock
// (flock(2)) on the lock file OUT.lock beside it for its whole run, so that a
// second run to the same output (two `gdr render --continue` of one part, a
// merge into a file being continued) is refused instead of silently replacing
// the first one's samples. The lock file names its holder (pid, host,
// command) and is removed when the holder ends, even by a stop signal; a lock
// left by a killed process is free, since the kernel drops it with the
// process. Where the file system does not support flock, the run goes on with
// a warning (the content check of --continue still refuses to replace a file
// that changed); where flock is honoured only on one node (for example Lustre
// mounted with localflock), runs on different nodes are not kept apart.
#pragma once

#include <string>

namespace gdr::cli {

/// The lock file of the output `out`: beside the file a symlink at `out` points to, named after it with ".lock".
std::string lock_path(const std::string& out);

/// Holds the lock of one output while it lives.
class OutputLock {
public:
    /// Takes the lock of `out` for `command` (e.g. "gdr render"); throws
    /// InputError naming the holder if another process has it. A device
    /// output (/dev/null) takes no lock.
    OutputLock(const std::string& out, const std::string& command);
    ~OutputLock();
    OutputLock(const OutputLock&) = delete;
    OutputLock& operator=(const OutputLock&) = delete;

private:
    int fd_ = -1;
    std::string path_;
};

/// A digest of the bytes of the file at `path` (64-bit FNV-1a, as hex), "" if it cannot be read: tells whether a
/// file was replaced or changed between two moments.
std::string file_digest(const std::string& path);

}  // namespace gdr::cli
