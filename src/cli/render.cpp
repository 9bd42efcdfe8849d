#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <mutex>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"
#include "gdr/io/scene_file.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/shift/shift.h"

namespace gdr::cli {

namespace {

// More threads than this is a typing error, not a machine.
constexpr long long kMaxThreads = 1 << 16;

std::atomic<bool> g_interrupted{false};
std::atomic<int> g_signal{0};  // the signal that interrupted the render
// SIGTERM too: a batch scheduler ending a job sends it (before SIGKILL),
// and the samples taken so far should still reach the file.
extern "C" void on_stop_signal(int sig) {
    g_signal = sig;
    g_interrupted = true;
}

// Prints progress: a redrawn bar on a terminal, a plain line every 10% otherwise.
class ProgressPrinter {
public:
    ProgressPrinter() : tty_(isatty(fileno(stderr)) != 0) {}
    void operator()(const Progress& p) {
        std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
        if (!lock.owns_lock()) return;
        const double rate = p.seconds > 0 ? double(p.samples) / p.seconds : 0.0;
        const double eta = p.fraction > 0 ? p.seconds * (1.0 - p.fraction) / p.fraction : 0.0;
        if (tty_) {
            if (p.seconds - last_ < 0.1 && p.fraction < 1.0) return;
            last_ = p.seconds;
            const int width = 30, filled = int(p.fraction * width);
            fmt::print(stderr, "\r[{}{}] {:5.1f}%  {:.2f} M samples/s  ETA {:.1f} s   ", std::string(filled, '#'),
                       std::string(width - filled, '.'), 100.0 * p.fraction, rate * 1e-6, eta);
        } else {
            const int decile = int(p.fraction * 10.0);
            if (decile <= last_decile_) return;
            last_decile_ = decile;
            fmt::print(stderr, "progress {:3d}%  {:.2f} M samples/s  ETA {:.1f} s\n", decile * 10, rate * 1e-6, eta);
        }
    }
    void finish() {
        if (tty_) fmt::print(stderr, "\n");
    }

private:
    std::mutex mutex_;
    bool tty_;
    double last_ = -1.0;
    int last_decile_ = 0;
};

// The non-negative integer metadata entry `key` of a render read from `file`.
uint64_t metadata_count(const FrameBuffer& fb, const std::string& file, const std::string& key) {
    const auto it = fb.metadata().find(key);
    if (it == fb.metadata().end()) throw InputError(file + ": not a gdr render (no '" + key + "' entry)");
    const std::string& v = it->second;
    char* end = nullptr;
    errno = 0;
    const unsigned long long x = std::strtoull(v.c_str(), &end, 10);
    if (v.empty() || *end || v[0] == '-' || errno == ERANGE)
        throw InputError(file + ": metadata entry '" + key + "' is not a sample count or seed: '" + v + "'");
    return x;
}

// The render time recorded in a render read from `file` (s), 0 if none.
double metadata_seconds(const FrameBuffer& fb, const std::string& file) {
    const auto it = fb.metadata().find("render_seconds");
    if (it == fb.metadata().end()) return 0.0;
    char* end = nullptr;
    const double x = std::strtod(it->second.c_str(), &end);
    if (it->second.empty() || *end || !(x >= 0.0))
        throw InputError(file + ": metadata entry 'render_seconds' is not a time: '" + it->second + "'");
    return x;
}

}  // namespace

StoredRender read_stored_render(const std::string& file) {
    StoredRender r{file, read_exr(file)};
    const auto& m = r.fb.metadata();
    for (const char* k : {"integrator", "scene"})
        if (!m.count(k)) throw InputError(file + ": not a gdr render (no '" + std::string(k) + "' entry)");
    if (m.count("seed") && m.at("seed") == kMixedSeeds)
        throw InputError(file + ": merged from renders with different seeds, so it holds no single sample sequence to "
                         "continue or to merge again; render more with a new seed and merge the parts (gdr merge)");
    r.seed = metadata_count(r.fb, file, "seed");
    r.first_sample = metadata_count(r.fb, file, "first_sample");
    r.spp = metadata_count(r.fb, file, "spp");
    constexpr uint64_t kMaxSamples = uint64_t(std::numeric_limits<long long>::max());
    if (r.first_sample > kMaxSamples || r.spp > kMaxSamples - r.first_sample)
        throw InputError(file + ": sample counts in the metadata are out of range");
    r.seconds = metadata_seconds(r.fb, file);
    return r;
}

void check_output_path(const std::string& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_directory(path, ec)) throw InputError("cannot write '" + path + "': it is a directory");
    if (fs::is_fifo(path, ec) || fs::is_socket(path, ec))
        throw InputError("cannot write '" + path + "': an EXR cannot go to a pipe (its writer seeks back)");
    fs::path dir = fs::path(path).parent_path();
    if (dir.empty()) dir = ".";
    if (!fs::is_directory(dir, ec)) throw InputError("cannot write '" + path + "': no directory '" + dir.string() + "'");
    if (access(dir.c_str(), W_OK) != 0)
        throw InputError("cannot write '" + path + "': directory '" + dir.string() + "' is not writable");
}

std::string write_render(const std::string& out, const FrameBuffer& fb, float exposure) {
    write_exr_or_rescue(out, fb);
    // A device or pipe (-o /dev/null) gets no preview: it would be a stray file in /dev.
    std::error_code ec;
    if (std::filesystem::exists(out, ec) && !std::filesystem::is_regular_file(out, ec)) return "";
    const std::string png = std::filesystem::path(out).replace_extension(".png").string();
    // A gradient-domain render is shown as its L1 reconstruction, anything else as its colour.
    const std::string layer = fb.has("reconstruction_l1") ? "reconstruction_l1" : fb.has("color") ? "color" : fb.names().front();
    write_png_preview(png, fb.get(layer), exposure);
    return png + " (" + layer + ")";
}

std::string write_exr_or_rescue(const std::string& path, const FrameBuffer& fb) {
    try {
        write_exr(path, fb);
        return path;
    } catch (const Error& e) {
        const std::string rescue =
            (std::filesystem::temp_directory_path() / fmt::format("gdr-rescue-{}.exr", getpid())).string();
        bool saved = false;
        try {
            write_exr(rescue, fb);
            saved = true;
        } catch (const Error&) {
        }
        if (!saved) throw;
        throw RuntimeFailure(std::string(e.what()) + "\nthe render was saved to " + rescue +
                             " instead (gdr render --resume accepts it)");
    }
}

int render(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::string scene_path, out_path, integrator_name, resume_path;
    long long spp = -1, seed = -1;
    double time_budget = 0.0, exposure = 0.0;
    int threads = 0;
    std::vector<std::string> sets;
    while (a.more()) {
        const std::string opt = a.next();
        if (opt == "-o" || opt == "--output") out_path = a.value(opt);
        else if (opt == "--integrator") integrator_name = a.value(opt);
        else if (opt == "--spp") spp = a.int_value(opt, 1, std::numeric_limits<long long>::max());
        else if (opt == "--time") {
            time_budget = a.real_value(opt);
            if (!(time_budget > 0.0)) throw ParameterError("option --time must be positive, got " + fmt::format("{}", time_budget));
        } else if (opt == "--threads") threads = int(a.int_value(opt, 0, kMaxThreads));
        else if (opt == "--seed") seed = a.int_value(opt, 0, std::numeric_limits<long long>::max());
        else if (opt == "--set") sets.push_back(a.value(opt));
        else if (opt == "--resume") resume_path = a.value(opt);
        else if (opt == "--exposure") exposure = a.real_value(opt);
        else if (!opt.empty() && opt[0] == '-') throw ParameterError("render: unknown option '" + opt + "'\n" + usage());
        else if (scene_path.empty()) scene_path = opt;
        else throw ParameterError("render: unexpected argument '" + opt + "'");
    }
    if (scene_path.empty()) throw ParameterError("render: no scene file given\n" + usage());
    if (out_path.empty()) throw ParameterError("render: no output given (-o OUT.exr)");
    if (spp > 0 && time_budget > 0.0) throw ParameterError("render: give either --spp or --time, not both");
    check_output_path(out_path);

    // Resuming continues the previous render's sample sequence, so the merged
    // image equals one longer render.
    // Read and checked before rendering, so that a bad entry cannot cost the new samples.
    StoredRender previous;
    if (!resume_path.empty()) previous = read_stored_render(resume_path);

    const auto t_load = std::chrono::steady_clock::now();
    SceneFile sf = load_scene_file(scene_path);
    const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count();
    const std::string name = integrator_name.empty() ? sf.defaults.integrator : integrator_name;
    // Messages about a parameter name where it came from: the scene file, and
    // the --set assignments when there are any (a typo may be in either).
    std::string origin = sf.defaults.params.context();
    for (size_t i = 0; i < sets.size(); ++i) origin += (i ? ", --set " : " with --set ") + sets[i];
    Params params(origin);
    for (const auto& [k, v] : sf.defaults.params.values()) params.set(k, v);
    for (const auto& s : sets) params.set_from_text(s);
    auto integrator = integrator_registry().create(name, params);

    RenderSettings st;
    st.spp = spp > 0 ? spp : sf.defaults.spp;
    st.time_budget = time_budget;
    st.threads = threads;
    st.seed = uint64_t(seed >= 0 ? seed : sf.defaults.seed);
    st.cancel = &g_interrupted;
    if (!resume_path.empty()) {
        const auto& m = previous.fb.metadata();
        if (m.at("integrator") != name)
            throw InputError(resume_path + ": rendered with integrator '" + m.at("integrator") + "', not '" + name + "'");
        if (m.count("integrator_params") && m.at("integrator_params") != integrator->describe())
            throw InputError(resume_path + ": rendered with other integrator parameters:\n" + m.at("integrator_params"));
        if (seed >= 0 && uint64_t(seed) != previous.seed)
            throw InputError(resume_path + ": rendered with seed " + m.at("seed") + ", not " + std::to_string(seed));
        st.seed = previous.seed;
        st.first_sample = (long long)(previous.first_sample + previous.spp);
    }

    const auto& cam = sf.scene->camera();
    const auto& ss = sf.scene->stats();
    fmt::print(stderr, "scene {}: {} triangles ({} degenerate skipped), {} emitting, {}x{}, loaded in {:.2f} s\n",
               scene_path, ss.triangles, ss.degenerate_skipped, ss.emitters, cam.width(), cam.height(), load_s);
    if (!sf.scene->has_lights()) fmt::print(stderr, "warning: the scene has no emitters; the image will be black\n");

    g_interrupted = false;
    g_signal = 0;
    auto old_int = std::signal(SIGINT, on_stop_signal);
    auto old_term = std::signal(SIGTERM, on_stop_signal);
    ProgressPrinter printer;
    FrameBuffer fb;
    RenderStats rs = integrator->render(*sf.scene, st, fb, [&](const Progress& p) { printer(p); });
    printer.finish();
    std::signal(SIGINT, old_int);
    std::signal(SIGTERM, old_term);

    auto& meta = fb.metadata();
    meta["integrator"] = name;
    meta["scene"] = std::filesystem::absolute(scene_path).string();
    meta["render_seconds"] = fmt::format("{:.3f}", rs.seconds);
    meta["time_budget"] = fmt::format("{}", time_budget);
    meta["gdr_version"] = "0.1.0";
    meta["interrupted"] = g_interrupted ? "true" : "false";
    if (!resume_path.empty()) {
        merge_renders(previous.fb, fb);
        integrator->update_merged(previous.fb);
        // The merged image is as complete as its last part.
        previous.fb.metadata()["interrupted"] = meta["interrupted"];
        previous.fb.metadata()["render_seconds"] = fmt::format("{:.3f}", previous.seconds + rs.seconds);
        fb = std::move(previous.fb);
    }
    const std::string preview = write_render(out_path, fb, float(exposure));

    fmt::print(stderr, "{} {} spp in {:.2f} s: {:.2f} M samples/s, {:.2f} M rays/s\n",
               g_interrupted ? "interrupted after" : "rendered", rs.spp, rs.seconds,
               rs.samples / std::max(1e-9, rs.seconds) * 1e-6, rs.rays / std::max(1e-9, rs.seconds) * 1e-6);
    if (rs.nonfinite) {
        std::string where;
        for (auto [x, y] : rs.nonfinite_pixels) where += fmt::format(" ({}, {})", x, y);
        fmt::print(stderr, "warning: {} NaN/Inf samples were dropped, first at pixels{}\n", rs.nonfinite, where);
    } else {
        fmt::print(stderr, "no NaN/Inf samples\n");
    }
    fmt::print(stderr, "wrote {} (layers:", out_path);
    for (const auto& n : fb.names()) fmt::print(stderr, " {}", n);
    fmt::print(stderr, "){}\n", preview.empty() ? "" : " and " + preview);
    return g_interrupted ? 128 + (g_signal ? g_signal.load() : SIGINT) : 0;  // the shell's convention
}

int info(const std::vector<std::string>& args) {
    if (args.size() != 1) throw ParameterError("info: expected one EXR file\n" + usage());
    const FrameBuffer fb = read_exr(args[0]);
    fmt::print("{}: {}x{}\nlayers:\n", args[0], fb.width(), fb.height());
    for (const auto& n : fb.names()) {
        const Image& img = fb.get(n);
        double mean = 0.0;
        for (float v : img.values()) mean += v;
        mean /= std::max<size_t>(1, img.values().size());
        fmt::print("  {:<22} {} channel{}  mean {:.6g}\n", n, img.channels(), img.channels() > 1 ? "s" : "", mean);
    }
    if (!fb.metadata().empty()) {
        fmt::print("settings:\n");
        for (const auto& [k, v] : fb.metadata()) {
            std::string vv = v;
            for (auto& c : vv)
                if (c == '\n') c = ' ';
            fmt::print("  {} = {}\n", k, vv);
        }
    }
    return 0;
}

int list_plugins() {
    fmt::print("integrators:\n");
    for (const auto& n : integrator_registry().names()) fmt::print("  {:<18} {}\n", n, integrator_registry().description(n));
    fmt::print("shift mappings (gpt shift=NAME):\n");
    for (const auto& n : shift_registry().names()) fmt::print("  {:<18} {}\n", n, shift_registry().description(n));
    fmt::print("reconstructors (gdr reconstruct --method NAME):\n");
    for (const auto& n : reconstructor_registry().names())
        fmt::print("  {:<18} {}\n", n, reconstructor_registry().description(n));
    return 0;
}

}  // namespace gdr::cli
