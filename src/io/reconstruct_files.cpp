#include "gdr/io/reconstruct_files.h"

#include <filesystem>

#include "gdr/core/error.h"
#include "gdr/io/exr.h"

namespace gdr {

namespace {
// An image's size as "WxHxC", for errors.
std::string shape_text(const Image& img) {
    return std::to_string(img.width()) + "x" + std::to_string(img.height()) + "x" + std::to_string(img.channels());
}
}  // namespace

GradientFrame load_reference_layout(const std::string& prefix) {
    namespace fs = std::filesystem;
    GradientFrame f;
    const std::string primal = prefix + "-primal.exr", throughput = prefix + "-throughput.exr";
    if (fs::exists(primal)) f.primal = read_exr_rgb(primal);
    else if (fs::exists(throughput)) f.primal = read_exr_rgb(throughput);
    else throw InputError("reference layout: neither " + primal + " nor " + throughput + " exists");
    for (auto [img, suffix] : {std::pair{&f.dx, "-dx.exr"}, std::pair{&f.dy, "-dy.exr"}}) {
        const std::string path = prefix + suffix;
        if (!fs::exists(path)) throw InputError("reference layout: missing " + path);
        *img = read_exr_rgb(path);
    }
    if (fs::exists(prefix + "-direct.exr")) f.direct = read_exr_rgb(prefix + "-direct.exr");
    const std::pair<const Image*, const char*> layers[] = {{&f.dx, "-dx.exr"}, {&f.dy, "-dy.exr"}, {&f.direct, "-direct.exr"}};
    for (const auto& [img, suffix] : layers)
        if (!img->empty() && !img->same_shape(f.primal))
            throw InputError("reference layout: " + prefix + suffix + " is " + shape_text(*img) +
                             " but the primal image is " + shape_text(f.primal));
    return f;
}

FrameSequenceReport reconstruct_frame_sequence(const std::string& input_pattern, int first, int last,
                                               const std::string& output_pattern, const TemporalOptions& options,
                                               const std::function<void(int, const std::string&)>& on_frame) {
    namespace fs = std::filesystem;
    check_temporal_options(options);
    if (last < first)
        throw ParameterError("frame range " + std::to_string(first) + ":" + std::to_string(last) + " is empty");
    std::vector<std::string> inputs, outputs;
    for (int k = first; k <= last; ++k) inputs.push_back(frame_path(input_pattern, k));
    for (int k = first; k <= last; ++k) outputs.push_back(frame_path(output_pattern, k));
    for (const auto& in : inputs)
        if (!fs::exists(in)) throw InputError(in + ": no such file (frame input of '" + input_pattern + "')");
    for (const auto& out : outputs) {
        std::error_code ec;
        const fs::path o = fs::weakly_canonical(out, ec);
        for (const auto& in : inputs)
            if (out == in || (!ec && o == fs::weakly_canonical(in, ec)))
                throw ParameterError("output " + out + " is the input " + in + ": an output never replaces an input");
    }
    TemporalReconstructor rec(options);
    FrameSequenceReport report;
    int written = 0;
    auto drain = [&]() {
        while (rec.ready()) {
            const int k = first + written;
            const std::string& in = inputs[size_t(written)];
            Image img = rec.pop();
            FrameBuffer fb(img.width(), img.height());
            fb.set("color", std::move(img));
            fb.metadata()["reconstruction"] = "temporal";
            fb.metadata()["reconstruction_params"] = describe(options);
            fb.metadata()["reconstruction_input"] = fs::absolute(in).string();
            fb.metadata()["frame"] = std::to_string(k);
            write_exr(outputs[size_t(written)], fb);
            report.outputs.push_back(outputs[size_t(written)]);
            ++written;
            if (on_frame) on_frame(k, report.outputs.back());
        }
    };
    // One frame ahead: a tgpt frame's dt needs the next frame's first half.
    FrameBuffer fb = read_exr(inputs[0]);
    for (size_t i = 0; i < inputs.size(); ++i) {
        FrameBuffer next;
        if (i + 1 < inputs.size()) next = read_exr(inputs[i + 1]);
        if (i + 1 < inputs.size() && !fb.has(temporal_layers::dt) && has_temporal_halves(fb, next))
            add_temporal_difference(fb, next, inputs[i], inputs[i + 1]);
        rec.push(temporal_frame(fb, inputs[i]));
        drain();
        fb = std::move(next);
    }
    rec.finish();
    drain();
    report.frames = written;
    report.windows = rec.reports();
    return report;
}

}  // namespace gdr
