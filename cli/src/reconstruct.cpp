#include <filesystem>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "gdr/reconstruct/reconstructor.h"

namespace gdr::cli {

namespace {

// "cbox-primal.exr" -> "cbox" for the reference implementation's file layout; "" otherwise.
std::string reference_prefix(const std::string& path) {
    for (const char* suffix : {"-primal.exr", "-throughput.exr", "-dx.exr", "-dy.exr", "-direct.exr"}) {
        const std::string s(suffix);
        if (path.size() > s.size() && path.compare(path.size() - s.size(), s.size(), s) == 0)
            return path.substr(0, path.size() - s.size());
    }
    return "";
}

}  // namespace

int reconstruct(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::string in, out, method = "poisson-l1";
    Params params("gdr reconstruct");
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-h" || o == "--help") return print_usage("reconstruct");
        if (o == "-o" || o == "--output") out = a.value(o);
        else if (o == "--method") method = a.value(o);
        else if (o == "--alpha") params.set("alpha", a.real_value(o));
        else if (o == "--set") params.set_from_text(a.value(o));
        else if (!o.empty() && o[0] == '-') throw ParameterError("reconstruct: unknown option '" + o + "'\n" + usage("reconstruct"));
        else if (in.empty()) in = o;
        else throw ParameterError("reconstruct: unexpected argument '" + o + "'");
    }
    if (in.empty()) throw ParameterError("reconstruct: no input given\n" + usage("reconstruct"));
    if (out.empty()) throw ParameterError("reconstruct: no output given (-o OUT.exr)");
    check_output_path(out);
    {
        // The input, or every file of the reference implementation's layout.
        std::vector<std::string> inputs{in};
        const std::string base = reference_prefix(in).empty() ? in : reference_prefix(in);
        for (const char* suffix : {"-primal.exr", "-throughput.exr", "-dx.exr", "-dy.exr", "-direct.exr"})
            inputs.push_back(base + suffix);
        check_not_an_input(out, inputs);
    }

    GradientFrame frame;
    FrameBuffer fb;
    GradientBuffers buffers;
    std::string layout;
    const std::string prefix = reference_prefix(in);
    if (!prefix.empty() || !std::filesystem::exists(in)) {
        // The reference implementation writes one file per buffer: NAME-primal.exr, NAME-dx.exr, ...
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
