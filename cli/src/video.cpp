// gdr video: an animation's EXR frames as a PNG sequence and an MP4. Each
// frame is tone-mapped by the PNG previews' own code (preview_bytes), so the
// video shows what the renders' PNGs show. The MP4 is encoded by Debian's
// ffmpeg, fed raw RGB frames on a pipe; without ffmpeg the PNG sequence is
// still written, since it is what an MP4 can be made from later.

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "frames.h"
#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"
#include "gdr/reconstruct/temporal.h"
#include "process.h"
#include "say.h"
#include "stop.h"

namespace gdr::cli {

namespace fs = std::filesystem;

namespace {

bool ends_with_ci(const std::string& s, const std::string& suffix) {
    if (s.size() < suffix.size()) return false;
    for (size_t i = 0; i < suffix.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i]) return false;
    return true;
}

std::string layer_list(const FrameBuffer& fb) {
    std::string s;
    for (const auto& n : fb.names()) s += (s.empty() ? "" : ", ") + n;
    return s;
}

// What the command was asked for.
struct VideoJob {
    std::string pattern;            // input EXR frame pattern
    int first = 0, last = 0;
    std::string mp4;                // "" for a PNG sequence only
    std::string png;                // PNG frame pattern, "" for none
    std::string layer;              // "" for each frame's final image
    std::optional<double> fps;      // --fps
    int crf = 18;
    float exposure = 0.f;
};

// One frame read and tone-mapped.
struct Frame {
    std::string layer;
    std::string reason;  // why that layer
    Image img;
};

Frame read_frame(const std::string& path, const std::string& layer) {
    const FrameBuffer fb = read_exr(path);
    Frame f;
    if (fb.names().empty()) throw InputError(path + ": holds no image layers");
    if (layer.empty()) {
        f.layer = preview_layer(fb), f.reason = "its final image, as its PNG preview shows";
    } else {
        if (!fb.has(layer))
            throw InputError(path + " has no layer '" + layer + "' (layers: " + layer_list(fb) + ")");
        f.layer = layer, f.reason = "--layer";
    }
    f.img = fb.get(f.layer);
    return f;
}

// The frame rate: --fps, else the "fps" that gdr render --frames stores, also
// through a reconstructed frame's input (its "reconstruction_input"), else 24.
std::pair<double, std::string> frame_rate(const VideoJob& job, const std::string& first_file) {
    if (job.fps) return {*job.fps, "--fps"};
    const auto stored = [](const ExrHeader& h, const std::string& file) -> std::optional<double> {
        const auto it = h.metadata.find("fps");
        if (it == h.metadata.end()) return std::nullopt;
        char* end = nullptr;
        const double v = std::strtod(it->second.c_str(), &end);
        if (it->second.empty() || *end || !std::isfinite(v) || v <= 0.0)
            throw InputError(file + ": its \"fps\" entry '" + it->second + "' is not a positive number (give --fps)");
        return v;
    };
    const ExrHeader h = read_exr_header(first_file);
    if (const auto v = stored(h, first_file)) return {*v, "the \"fps\" of " + first_file};
    const auto in = h.metadata.find("reconstruction_input");
    std::error_code ec;
    if (in != h.metadata.end() && fs::exists(in->second, ec)) {
        if (const auto v = stored(read_exr_header(in->second), in->second))
            return {*v, "the \"fps\" of " + in->second + ", the input of " + first_file};
    }
    return {24.0, "the default; " + first_file + " holds no \"fps\""};
}

// Tone-mapped RGB bytes of `img`, padded to `w` x `h` (even) by repeating the last column and row.
std::string rgb24(const Image& img, float exposure, int w, int h) {
    const std::vector<uint8_t> px = preview_bytes(img, exposure);
    const int iw = img.width(), ih = img.height(), c = img.channels() == 2 ? 3 : img.channels();
    std::string out(size_t(w) * size_t(h) * 3, '\0');
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const uint8_t* s = px.data() + (size_t(std::min(y, ih - 1)) * iw + size_t(std::min(x, iw - 1))) * c;
            char* d = out.data() + (size_t(y) * w + x) * 3;
            // Grey is one value in R, G and B; alpha is coverage, which a video has no place for.
            for (int k = 0; k < 3; ++k) d[k] = char(s[c == 1 ? 0 : k]);
        }
    return out;
}

// The last lines of a program's standard error, for an error message.
std::string tail(const std::string& err, int lines = 12) {
    size_t at = err.size();
    while (at > 0 && (err[at - 1] == '\n' || err[at - 1] == ' ')) --at;
    const size_t end = at;
    for (int n = 0; at > 0; --at)
        if (err[at - 1] == '\n' && ++n == lines) break;
    return err.substr(at, end - at);
}

// Removes the temporary MP4 unless it was renamed into place.
struct PartialFile {
    std::string path;
    bool kept = false;
    ~PartialFile() {
        std::error_code ec;
        if (!kept) fs::remove(path, ec);
    }
};

// Thrown into the encoding loop by a stop signal.
struct Stopped {};

int run_video(const VideoJob& job) {
    std::vector<std::string> inputs;
    for (int k = job.first; k <= job.last; ++k) inputs.push_back(gdr::frame_path(job.pattern, k));
    // Before anything is read or written, so that a gap in the sequence costs no encoding time.
    for (size_t i = 0; i < inputs.size(); ++i) {
        std::error_code ec;
        if (!fs::exists(inputs[i], ec))
            throw InputError(fmt::format("{}: no such file (frame {} of '{}')", inputs[i], job.first + int(i),
                                         job.pattern));
    }

    const std::string ffmpeg = job.mp4.empty() ? "" : find_program("ffmpeg");
    std::string png = job.png;
    bool png_default = false;
    if (!job.mp4.empty() && ffmpeg.empty() && png.empty()) {
        png = (fs::path(job.mp4).parent_path() / (fs::path(job.mp4).stem().string() + ".%04d.png")).string();
        png_default = true;
    }
    std::vector<std::string> pngs;
    if (!png.empty())
        for (int k = job.first; k <= job.last; ++k) pngs.push_back(gdr::frame_path(png, k));
    for (const std::string& p : pngs) check_not_an_input(p, inputs);
    const bool encode = !job.mp4.empty() && !ffmpeg.empty();
    if (!job.mp4.empty()) check_not_an_input(job.mp4, inputs);
    for (const std::string& out : encode ? std::vector<std::string>{job.mp4} : pngs) {
        const fs::path dir = fs::path(out).parent_path();
        std::error_code ec;
        if (!dir.empty() && !fs::is_directory(dir, ec))
            throw InputError("cannot write " + out + ": the directory " + dir.string() + " does not exist");
    }

    Frame first = read_frame(inputs[0], job.layer);
    const std::string layer = first.layer;
    const int w = first.img.width(), h = first.img.height();
    if (w == 0 || h == 0) throw InputError(inputs[0] + ": layer '" + layer + "' is empty");
    fmt::print("frames:  {} .. {} ({} frames, {}x{}), layer '{}' ({})\n", inputs.front(), inputs.back(),
               inputs.size(), w, h, layer, first.reason);

    // Frame i read, checked, written as PNG when asked for, and returned as padded RGB bytes.
    const int vw = w + (w & 1), vh = h + (h & 1);  // yuv420p needs even sizes
    size_t next = 0;
    const auto frame = [&](size_t i) -> std::string {
        Frame f = i == 0 ? std::move(first) : read_frame(inputs[i], layer);
        if (f.img.width() != w || f.img.height() != h)
            throw InputError(fmt::format("{}: layer '{}' is {}x{}, but the first frame {} is {}x{}", inputs[i], layer,
                                         f.img.width(), f.img.height(), inputs[0], w, h));
        size_t bad = 0;
        for (const float v : f.img.values()) bad += !std::isfinite(v);
        if (bad)
            say("warning: {} layer '{}': {} NaN or infinite values, shown as its PNG shows them (NaN and -Inf "
                "black, +Inf white)\n",
                inputs[i], layer, bad);
        if (!pngs.empty()) {
            const WriteSection section;
            write_png_preview(pngs[i], f.img, job.exposure);
        }
        say("  frame {} -> {}\n", job.first + int(i), pngs.empty() ? job.mp4 : pngs[i]);
        return encode ? rgb24(f.img, job.exposure, vw, vh) : std::string();
    };

    if (!encode) {
        for (size_t i = 0; i < inputs.size(); ++i) frame(i);
        fmt::print("wrote the PNG sequence {} ({} frames, {}x{}{})\n", png, pngs.size(), w, h,
                   job.exposure != 0.f ? fmt::format(", exposure {:+g}", job.exposure) : "");
        if (!job.mp4.empty())
            fmt::print("ffmpeg not found: install Debian's ffmpeg (apt-get install ffmpeg) for MP4 output; wrote "
                       "the PNG sequence {}{} instead of {}\n",
                       png, png_default ? " (beside it)" : "", job.mp4);
        return 0;
    }

    const auto [fps, fps_source] = frame_rate(job, inputs[0]);
    // Debian's ffmpeg has libx264; a build without it gets its default MP4 encoder (MPEG-4 part 2).
    const ProgramResult encoders = run_program({ffmpeg, "-hide_banner", "-encoders"});
    const bool x264 = encoders.status == 0 && encoders.out.find(" libx264 ") != std::string::npos;
    // Stops the encoding cleanly on Ctrl-C or SIGTERM, so that no partial MP4
    // stays behind: made before the temporary, so that it covers every moment
    // until the temporary is renamed or removed.
    const PolledStop stop;
    PartialFile partial{(fs::path(job.mp4).parent_path() /
                         fmt::format(".{}.partial-{}", fs::path(job.mp4).filename().string(), getpid()))
                            .string()};
    std::vector<std::string> argv = {ffmpeg,     "-hide_banner", "-nostats", "-loglevel", "error",
                                     "-f",       "rawvideo",     "-pix_fmt", "rgb24",     "-video_size",
                                     fmt::format("{}x{}", vw, vh), "-framerate", fmt::format("{}", fps),
                                     "-i",       "pipe:0"};
    if (x264) argv.insert(argv.end(), {"-c:v", "libx264", "-crf", std::to_string(job.crf), "-preset", "medium"});
    argv.insert(argv.end(), {"-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4", "-y", partial.path});

    ProgramResult r;
    {
        try {
            r = run_program_fed(argv, [&]() -> std::string {
                if (stop_flag()) throw Stopped{};
                return next < inputs.size() ? frame(next++) : std::string();
            });
        } catch (const Stopped&) {
        }
        // Ctrl-C reaches ffmpeg too, which may have stopped before the next frame was asked for.
        if (stop_flag()) {
            say("stopped: {} not written\n", job.mp4);
            return stop_status();
        }
    }
    if (!r.started) throw RuntimeFailure("cannot run ffmpeg (" + ffmpeg + "): " + r.err);
    if (r.status != 0 || next < inputs.size())
        throw RuntimeFailure(fmt::format("ffmpeg ({}) failed to encode {} (exit status {}, {} of {} frames sent){}{}",
                                         ffmpeg, job.mp4, r.status, next, inputs.size(),
                                         r.err.empty() ? "" : ":\n", tail(r.err)));
    std::error_code ec;
    if (fs::file_size(partial.path, ec) == 0 || ec)
        throw RuntimeFailure("ffmpeg (" + ffmpeg + ") reported success but wrote nothing for " + job.mp4);
    fs::rename(partial.path, job.mp4, ec);
    if (ec) throw RuntimeFailure("cannot write " + job.mp4 + ": " + ec.message());
    partial.kept = true;
    if (!pngs.empty()) fmt::print("wrote the PNG sequence {} ({} frames, {}x{})\n", png, pngs.size(), w, h);
    fmt::print("wrote {} ({} frames, {}x{}{}, {} fps from {}, {}, yuv420p{})\n", job.mp4, inputs.size(), vw, vh,
               vw != w || vh != h ? fmt::format(" padded from {}x{}", w, h) : "", fps, fps_source,
               x264 ? fmt::format("H.264 (libx264, crf {})", job.crf) : "ffmpeg's default MP4 encoder",
               job.exposure != 0.f ? fmt::format(", exposure {:+g}", job.exposure) : "");
    return 0;
}

}  // namespace

int video(const std::vector<std::string>& args) {
    ArgReader a{args};
    VideoJob job;
    std::string out, range;
    bool crf_set = false;
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-h" || o == "--help") return print_usage("video");
        if (o == "-o" || o == "--output") out = a.value(o);
        else if (o == "--layer") job.layer = a.value(o);
        else if (o == "--png") job.png = a.value(o);
        else if (o == "--fps") {
            job.fps = a.real_value(o);
            if (!(*job.fps > 0.0)) throw ParameterError("option --fps must be positive, got '" + args[a.i - 1] + "'");
        } else if (o == "--crf") job.crf = int(a.int_value(o, 0, 51)), crf_set = true;
        else if (o == "--exposure") job.exposure = float(a.real_value(o));
        else if (!o.empty() && o[0] == '-' && o.size() > 1)
            throw ParameterError("video: unknown option '" + o + "'\n" + usage("video"));
        else if (job.pattern.empty()) job.pattern = o;
        else if (range.empty()) range = o;
        else throw ParameterError("video: unexpected argument '" + o + "'");
    }
    if (range.empty()) throw ParameterError("video: expected 'PATTERN.exr' FIRST:LAST\n" + usage("video"));
    if (out.empty()) throw ParameterError("video: -o OUT.mp4 (or a PNG pattern such as 'f.%04d.png') is required");
    std::tie(job.first, job.last) = parse_frame_range("FIRST:LAST", range);
    // Checked before anything is read, naming the pattern that is wrong.
    (void)gdr::frame_path(job.pattern, job.first);
    if (ends_with_ci(out, ".png")) {
        if (!job.png.empty())
            throw ParameterError("video: -o '" + out + "' is a PNG pattern and --png '" + job.png +
                                 "' another: give one (-o OUT.mp4 --png PATTERN writes both)");
        if (crf_set) throw ParameterError("video: --crf is the MP4's quality; -o '" + out + "' writes PNGs only");
        job.png = out;
    } else if (ends_with_ci(out, ".mp4")) {
        job.mp4 = out;
    } else {
        throw ParameterError("video: -o '" + out + "' must be an .mp4 file or a PNG frame pattern ('f.%04d.png')");
    }
    if (!job.png.empty()) {
        if (!ends_with_ci(job.png, ".png"))
            throw ParameterError("video: --png '" + job.png + "' must be a .png frame pattern ('f.%04d.png')");
        (void)gdr::frame_path(job.png, job.first);
    }
    return run_video(job);
}

}  // namespace gdr::cli
