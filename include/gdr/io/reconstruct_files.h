// Reconstruction inputs and outputs on files: the layout the public
// Mitsuba-based G-PT implementation writes, and temporal reconstruction of
// a sequence of frame files. The solvers themselves (gdr/reconstruct) read
// and write images in memory only, so that they can be used without any
// file format.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "gdr/reconstruct/reconstructor.h"
#include "gdr/reconstruct/temporal.h"

namespace gdr {

/// Loads the files the public Mitsuba-based G-PT implementation writes for
/// one render, e.g. prefix ".../cbox": cbox-primal.exr or cbox-throughput.exr,
/// cbox-dx.exr, cbox-dy.exr and optionally cbox-direct.exr. Throws InputError
/// naming the missing file.
GradientFrame load_reference_layout(const std::string& prefix);

/// What reconstruct_frame_sequence did.
struct FrameSequenceReport {
    int frames = 0;                                     ///< Frames written.
    std::vector<std::string> outputs;                   ///< Paths written, in frame order.
    std::vector<std::pair<int, TemporalReport>> windows;  ///< Each window's first frame and report.
};

/// Reads frames first..last (inclusive) of `input_pattern` with read_exr,
/// forms the temporal differences of tgpt frames that have no dt layer
/// (add_temporal_difference(), from the next frame in the range), reconstructs them with a TemporalReconstructor and writes each result
/// with write_exr to `output_pattern` as the layer "color" (metadata:
/// reconstruction = "temporal", reconstruction_params = describe(options),
/// reconstruction_input = the input's absolute path, frame = its number).
/// Before reading anything it checks that every input exists (InputError
/// naming the first missing file) and that no output is one of the inputs
/// (ParameterError naming both: an output never replaces an input). Errors
/// in a frame's layers name its file and the layer. `on_frame` (may be
/// empty) is called after each output is written with the frame number and path.
FrameSequenceReport reconstruct_frame_sequence(
    const std::string& input_pattern, int first, int last, const std::string& output_pattern,
    const TemporalOptions& options,
    const std::function<void(int frame, const std::string& path)>& on_frame = {});

}  // namespace gdr
