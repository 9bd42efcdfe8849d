// The subcommands of the `gdr` tool, as library functions so tests can run
// them. Each returns the process exit code and throws gdr::Error on bad input.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "gdr/core/image.h"

namespace gdr::cli {

/// Dispatches `args` (without the program name) to a subcommand.
int run(const std::vector<std::string>& args);

/// gdr render SCENE.json [options] -o OUT.exr
int render(const std::vector<std::string>& args);
/// gdr merge A.exr B.exr [...] -o OUT.exr
int merge(const std::vector<std::string>& args);

/// The "seed" (and "first_sample") metadata of a render merged from several
/// seeds: it has no single sample sequence, so --resume refuses it.
inline const std::string kMixedSeeds = "mixed";

/// Throws an InputError naming `path` unless a file can be created there:
/// checked before rendering, so that a typing error costs no render time.
void check_output_path(const std::string& path);

/// A render written by `gdr render` or `gdr merge`, read back with the
/// sample range it holds (what --resume continues and merge pools).
struct StoredRender {
    std::string file;           ///< Where it was read from.
    FrameBuffer fb;             ///< Its layers and metadata.
    uint64_t seed = 0;          ///< Sampler seed of its samples.
    uint64_t first_sample = 0;  ///< Number of its first sample in each pixel.
    uint64_t spp = 0;           ///< Samples per pixel it holds.
    double seconds = 0.0;       ///< Render time recorded in it (s), 0 if none.
};

/// Reads `file` with its metadata; throws an InputError naming the file if
/// an entry every render has is missing or malformed, or if it is a merge of
/// several seeds, which holds no single sample range.
StoredRender read_stored_render(const std::string& file);

/// Writes `fb` to `out` (write_exr_or_rescue) and a PNG preview beside it
/// (OUT.png): the L1 reconstruction of a gradient-domain render, else its
/// colour. Returns "PNG (layer)", or "" when `out` is a device or pipe
/// (-o /dev/null), which gets no preview.
std::string write_render(const std::string& out, const FrameBuffer& fb, float exposure = 0.f);

/// Writes `fb` to `path` and returns it; if that fails (disk full, directory
/// gone), writes it to a rescue file in the temporary directory and throws a
/// RuntimeFailure naming both, so that a finished render is never lost.
std::string write_exr_or_rescue(const std::string& path, const FrameBuffer& fb);
/// gdr info FILE.exr
int info(const std::vector<std::string>& args);

/// Usage text of the whole tool.
std::string usage();

/// Command-line scanning helpers shared by the subcommands.
struct ArgReader {
    const std::vector<std::string>& args;  ///< All arguments of the subcommand.
    size_t i = 0;                          ///< Current position.
    /// True while arguments remain.
    bool more() const { return i < args.size(); }
    /// The next argument.
    const std::string& next() { return args[i++]; }
    /// The value following option `opt`; throws naming the option if absent.
    std::string value(const std::string& opt);
    /// The value of `opt` as an integer in [lo, hi] (throws naming the option if malformed or out of range).
    long long int_value(const std::string& opt, long long lo, long long hi);
    /// The value of `opt` as a finite real number (throws naming the option if malformed, NaN or infinite).
    double real_value(const std::string& opt);
    /// `v`, the text given for option `opt`, as an integer in [lo, hi] (throws naming the option otherwise).
    static long long parse_int(const std::string& opt, const std::string& v, long long lo, long long hi);
    /// `v`, the text given for option `opt`, as a finite real number (throws naming the option otherwise).
    static double parse_real(const std::string& opt, const std::string& v);
};

}  // namespace gdr::cli
