// Where and how an output file is written: through a temporary sibling
// renamed into place, so that a reader never sees half a file and a failed
// write leaves the old file intact.
#pragma once

#include <string>

namespace gdr::io {

/// How to write the output `path`.
struct FileTarget {
    std::string path;        ///< The file finally written: `path`, or the file a symlink at `path` points to.
    std::string write_path;  ///< Where the bytes go: a temporary sibling of `path`, or `path` itself when direct.
    /// True for a device or pipe (/dev/null, a FIFO): written directly, since
    /// renaming a file over it would replace the device node.
    bool direct = false;
};

/// The target for writing `requested`: a symlink is followed (the link stays),
/// a device or FIFO is written directly, anything else through a temporary.
FileTarget file_target(const std::string& requested);

/// Moves a finished temporary into place (nothing for a direct target);
/// throws a RuntimeFailure, after removing the temporary, if that fails.
void commit(const FileTarget& t);

/// Removes a temporary left by a failed write (nothing for a direct target).
void discard(const FileTarget& t) noexcept;

}  // namespace gdr::io
