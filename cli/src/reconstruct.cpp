#include <filesystem>

#include <fmt/core.h>

#include "gdr/io/reconstruct_files.h"
#include "gdr/cli/commands.h"
#include "gdr/cli/plugins.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/reconstruct/temporal.h"
#include "frames.h"
#include "output_lock.h"
#include "stop.h"

namespace gdr::cli {

namespace {

// "cbox-primal.exr" -> "cbox" for the file layout of the authors' public Mitsuba
// implementation of G-PT; "" otherwise.
std::string reference_prefix(const std::string& path) {
    for (const char* suffix : {"-primal.exr", "-throughput.exr", "-dx.exr", "-dy.exr", "-direct.exr"}) {
        const std::string s(suffix);
        if (path.size() > s.size() && path.compare(path.size() - s.size(), s.size(), s) == 0)
            return path.substr(0, path.size() - s.size());
    }
    return "";
}

}  // namespace

namespace {

// gdr reconstruct --frames: the spatio-temporal solve of a frame sequence (gdr/reconstruct/temporal.h).
int reconstruct_frames(const std::string& in, const std::pair<int, int>& range, const std::string& out,
                       const Params& params) {
    if (!has_frame_pattern(in) || !has_frame_pattern(out))
        throw ParameterError("reconstruct --frames: the input and -o must be frame patterns (%d, %04d), got '" + in +
                             "' and '" + out + "'");
    // Checked here too, so that a bad pattern is named with its option.
    for (int f : {range.first, range.second}) (void)frame_path("IN", in, f), (void)frame_path("-o", out, f);
    const TemporalOptions opt = temporal_options(params);
    // One lock for the sequence, named after its pattern.
    const OutputLock lock(out, "gdr reconstruct --frames");
    // The library writes each frame through a temporary: a stop signal is
    // taken after the frame being written, so that none is left half-written.
    const PolledStop polled;
    FrameSequenceReport rep;
    try {
        rep = reconstruct_frame_sequence(in, range.first, range.second, out, opt,
                                         [](int frame, const std::string& path) {
                                             fmt::print(stderr, "  frame {} -> {}\n", frame, path);
                                             if (stop_flag()) throw Interrupted("stopped after frame " + std::to_string(frame));
                                         });
    } catch (const Interrupted& e) {
        fmt::print(stderr, "stopped: {}\n", e.what());
        return stop_status();
    }
    fmt::print(stderr, "reconstructed frames {}..{} of {} ({} windows) -> {}\n", range.first, range.second, in,
               rep.windows.size(), out);
    return 0;
}

}  // namespace

int reconstruct(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::string in, out, method = "poisson-l1";
    Params params("gdr reconstruct");
    bool frames = false, method_set = false;
    std::pair<int, int> range{0, 0};
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-h" || o == "--help") return print_usage("reconstruct");
        if (o == "-o" || o == "--output") out = a.value(o);
        else if (o == "--frames") {
            // --frames IN_PATTERN A:B, as gdr compare --frames takes them.
            if (!in.empty()) throw ParameterError("reconstruct: --frames takes the input pattern after it");
            in = a.value(o);
            range = parse_frame_range(o, a.value(o));
            frames = true;
        } else if (o == "--method") method = a.value(o), method_set = true;
        else if (o == "--alpha") params.set("alpha", a.real_value(o));
        else if (o == "--set") params.set_from_text(a.value(o));
        else if (!o.empty() && o[0] == '-') throw ParameterError("reconstruct: unknown option '" + o + "'\n" + usage("reconstruct"));
        else if (in.empty()) in = o;
        else throw ParameterError("reconstruct: unexpected argument '" + o + "'");
    }
    if (in.empty()) throw ParameterError("reconstruct: no input given\n" + usage("reconstruct"));
    if (out.empty()) throw ParameterError("reconstruct: no output given (-o OUT.exr)");
    if (frames) {
        if (method_set && method != "temporal")
            throw ParameterError("reconstruct --frames: the method is the spatio-temporal solve ('temporal'), got '" +
                                 method + "'");
        return reconstruct_frames(in, range, out, params);
    }
    check_output_path(out);
    {
        // The input, or every file of that implementation's layout.
        std::vector<std::string> inputs{in};
        const std::string base = reference_prefix(in).empty() ? in : reference_prefix(in);
        for (const char* suffix : {"-primal.exr", "-throughput.exr", "-dx.exr", "-dy.exr", "-direct.exr"})
            inputs.push_back(base + suffix);
        check_not_an_input(out, inputs);
    }
    const OutputLock lock(out, "gdr reconstruct");
    // Before reading the input: a method that is not built is named at once.
    require_reconstructor(method, "gdr reconstruct --method " + method);

    GradientFrame frame;
    FrameBuffer fb;
    GradientBuffers buffers;
    std::string layout;
    const std::string prefix = reference_prefix(in);
    if (!prefix.empty() || !std::filesystem::exists(in)) {
        // The authors' public Mitsuba implementation of G-PT writes one file per buffer: NAME-primal.exr, NAME-dx.exr, ...
        frame = load_reference_layout(prefix.empty() ? in : prefix);
        buffers = frame.buffers();
        layout = "reference layout " + (prefix.empty() ? in : prefix) + "-*.exr";
    } else {
        fb = read_exr(in);
        try {
            buffers = gradient_buffers(fb);
        } catch (const InputError& e) {
            throw InputError(in + ": not a gradient-domain render: " + e.what());
        }
        layout = "gdr layers of " + in;
    }
    const auto rec = reconstructor_registry().create(method, params);
    Image img;
    try {
        img = rec->reconstruct(buffers);
    } catch (const Error& e) {
        // A non-finite or mis-shaped buffer: say which input it is in.
        throw InputError(layout + ": " + e.what());
    }

    FrameBuffer result(img.width(), img.height());
    result.set("color", img);
    result.metadata()["reconstruction"] = method;
    result.metadata()["reconstruction_params"] = rec->describe();
    result.metadata()["reconstruction_input"] = std::filesystem::absolute(in).string();
    const std::string preview = write_render(out, result);
    fmt::print(stderr, "reconstructed {} ({}x{}) with {} -> {}{}\n", layout, img.width(), img.height(), method, out,
               preview.empty() ? "" : " and " + preview);
    return 0;
}

}  // namespace gdr::cli
