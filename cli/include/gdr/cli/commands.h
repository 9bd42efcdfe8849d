// The subcommands of the `gdr` tool, as library functions so tests can run
// them. Each returns the process exit code and throws gdr::Error on bad input.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "gdr/core/args.h"
#include "gdr/core/image.h"
#include "gdr/core/params.h"
#include "gdr/io/render_header.h"

namespace gdr::cli {

/// Dispatches `args` (without the program name) to a subcommand.
int run(const std::vector<std::string>& args);

/// The exit status a stop signal (SIGINT, SIGTERM) asked for during the last
/// run(): 128 + the signal's number, 0 if none came. A command that fails
/// after such a signal exits with it rather than 1.
int stop_status();

/// gdr render SCENE.json [options] -o OUT.exr
int render(const std::vector<std::string>& args);
/// gdr merge A.exr B.exr [...] -o OUT.exr
int merge(const std::vector<std::string>& args);

/// Throws an InputError naming `path` unless a file can be created there and
/// it is an .exr (or a device such as /dev/null): checked before rendering,
/// so that a typing error costs no render time.
void check_output_path(const std::string& path);

/// Throws an InputError naming both unless the output `out` and its PNG
/// preview are none of `inputs` (the same file after symlinks and hard
/// links): an output never replaces an input.
void check_not_an_input(const std::string& out, const std::vector<std::string>& inputs);

/// The PNG preview written beside the EXR `out` (OUT.png).
std::string preview_path(const std::string& out);

/// A render written by `gdr render` or `gdr merge`, read back with the
/// samples it holds (what --resume continues and merge pools).
struct StoredRender {
    std::string file;                 ///< Where it was read from.
    FrameBuffer fb;                   ///< Its layers and metadata.
    std::vector<SampleRange> ranges;  ///< The samples it holds, normalised (one range: one sequence).
    uint64_t seed = 0;                ///< Sampler seed, when it holds one range.
    uint64_t first_sample = 0;        ///< Number of its first sample in each pixel, when it holds one range.
    uint64_t spp = 0;                 ///< Samples per pixel it holds.
    uint64_t target_spp = 0;          ///< Samples per pixel that were asked for (0: unknown or a time budget).
    double time_budget = 0.0;         ///< Wall-clock budget that was asked for (s), 0 if none.
    double seconds = 0.0;             ///< Render time recorded in it (s), 0 if none.
};

/// True if `fb` claims to be a gdr render: it has any of the render settings
/// or the per-pixel "spp" layer that only gdr writes.
bool looks_like_render(const FrameBuffer& fb);

/// Throws an InputError naming `file` and every missing entry unless `fb`
/// holds the settings and layers every gdr render has.
void check_render_settings(const FrameBuffer& fb, const std::string& file);

/// Reads `file` with its metadata; throws an InputError naming the file (and
/// the pixel, for a damaged "spp" layer) if an entry every render has is
/// missing, malformed or inconsistent.
StoredRender read_stored_render(const std::string& file);

/// The integrator parameters stored in a render's header ("integrator_params"),
/// as Params that --set may override and the integrator registry takes.
Params stored_params(const StoredRender& r);

/// What must agree between two renders for their samples to be pooled.
struct RenderIdentity {
    std::string integrator;  ///< Registered integrator name.
    std::string params;      ///< The integrator's describe() lines.
    int width = 0;           ///< Columns (pixels).
    int height = 0;          ///< Rows (pixels).
    std::string scene;       ///< Absolute path of the scene file.
    std::string scene_hash;  ///< Content hash of the scene and every file it loads ("" if unknown).
    std::string frame;       ///< Frame number of an animation's frame ("" for a still image).
};

/// The identity stored in a render file.
RenderIdentity identity_of(const StoredRender& r);

/// Throws an InputError naming both renders and the first key in which they
/// differ (integrator, an integrator parameter, resolution, scene content).
void check_same_render(const RenderIdentity& a, const std::string& a_name, const RenderIdentity& b,
                       const std::string& b_name);

/// Writes `fb` to `out` (write_exr_or_rescue) and a PNG preview beside it
/// (preview_path(out)) of preview_layer(fb). Returns "PNG (layer)", or ""
/// when `out` is a device or pipe (-o /dev/null), which gets no preview.
std::string write_render(const std::string& out, const FrameBuffer& fb, float exposure = 0.f);

// The header entries both the tool and the Python module write (gdr/io/render_header.h),
// also known by their former names here.
using gdr::format_sample_ranges;
using gdr::kMixedSeeds;
using gdr::normalized_ranges;
using gdr::preview_layer;
using gdr::SampleRange;

/// Throws a RuntimeFailure naming `file`, the layer and the pixel of the
/// first NaN or Inf in `fb`: no output image ever holds one.
void check_finite(const FrameBuffer& fb, const std::string& file);

/// Writes `fb` to `path` and returns it; if that fails (disk full, directory
/// gone), writes it to rescue_path() and throws a RuntimeFailure naming both,
/// so that a finished render is never lost.
std::string write_exr_or_rescue(const std::string& path, const FrameBuffer& fb);

/// The file in the temporary directory that a render goes to when its
/// output cannot be written.
std::string rescue_path();

/// gdr info FILE.exr
int info(const std::vector<std::string>& args);

/// Usage text of the whole tool: every command's synopsis.
std::string usage();
/// Usage text of one command: its synopsis and options (the whole tool's if unknown).
std::string usage(const std::string& command);
/// Prints usage(command) (the whole tool's for "") to stdout and returns 0, as --help does.
int print_usage(const std::string& command);
/// gdr's version ("MAJOR.MINOR.PATCH"), as written into render headers.
std::string version();

/// Command-line scanning (gdr/core/args.h), shared by the subcommands.
using ArgReader = gdr::ArgReader;

}  // namespace gdr::cli
