// Render files as the `gdr` tool reads and writes them: what a stored render
// must hold, which renders may be pooled, and output paths that can never
// destroy an input.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"

namespace gdr::cli {

namespace fs = std::filesystem;

namespace {

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

// The non-negative real metadata entry `key` (seconds) of a render read from `file`, 0 if absent.
double metadata_seconds(const FrameBuffer& fb, const std::string& file, const std::string& key) {
    const auto it = fb.metadata().find(key);
    if (it == fb.metadata().end()) return 0.0;
    char* end = nullptr;
    const double x = std::strtod(it->second.c_str(), &end);
    if (it->second.empty() || *end || !(x >= 0.0) || !std::isfinite(x))
        throw InputError(file + ": metadata entry '" + key + "' is not a time in seconds: '" + it->second + "'");
    return x;
}

constexpr uint64_t kMaxSamples = uint64_t(std::numeric_limits<long long>::max());

// "seed:first:count" ranges separated by commas, as written by format_sample_ranges().
std::vector<SampleRange> parse_sample_ranges(const std::string& text, const std::string& file) {
    std::vector<SampleRange> out;
    size_t at = 0;
    while (at <= text.size()) {
        const size_t end = std::min(text.find(',', at), text.size());
        const std::string item = text.substr(at, end - at);
        unsigned long long v[3];
        size_t pos = 0;
        for (int k = 0; k < 3; ++k) {
            const size_t stop = k < 2 ? item.find(':', pos) : item.size();
            const std::string num = stop == std::string::npos ? "" : item.substr(pos, stop - pos);
            char* e = nullptr;
            errno = 0;
            v[k] = std::strtoull(num.c_str(), &e, 10);
            if (num.empty() || *e || num[0] == '-' || errno == ERANGE)
                throw InputError(file + ": metadata entry 'sample_ranges' has a malformed range '" + item +
                                 "' (expected seed:first_sample:spp)");
            pos = stop + 1;
        }
        if (v[2] == 0 || v[1] > kMaxSamples || v[2] > kMaxSamples - v[1])
            throw InputError(file + ": metadata entry 'sample_ranges' has an empty or out-of-range range '" + item + "'");
        out.push_back({v[0], v[1], v[2]});
        at = end + 1;
    }
    return out;
}

// The integrator parameters stored in a header ("key=value" lines) as a map.
std::map<std::string, std::string> parameter_map(const std::string& lines) {
    std::map<std::string, std::string> out;
    for (size_t at = 0; at < lines.size();) {
        const size_t end = std::min(lines.find('\n', at), lines.size());
        const std::string line = lines.substr(at, end - at);
        const size_t eq = line.find('=');
        if (!line.empty()) out[line.substr(0, eq)] = eq == std::string::npos ? "" : line.substr(eq + 1);
        at = end + 1;
    }
    return out;
}

// Two stored parameter values are the same setting: the same text, or the
// same number however it was printed ("0.001000" and "0.001").
bool same_value(const std::string& a, const std::string& b) {
    if (a == b) return true;
    char *ea = nullptr, *eb = nullptr;
    const double x = std::strtod(a.c_str(), &ea), y = std::strtod(b.c_str(), &eb);
    return !a.empty() && !b.empty() && !*ea && !*eb && x == y;
}

// The settings every render file written by `gdr render` or `gdr merge` holds.
constexpr const char* kRenderSettings[] = {"integrator", "integrator_params", "scene", "spp", "seed", "first_sample"};

}  // namespace

std::string format_sample_ranges(const std::vector<SampleRange>& ranges) {
    std::string s;
    for (const SampleRange& r : ranges) s += fmt::format("{}{}:{}:{}", s.empty() ? "" : ",", r.seed, r.first, r.count);
    return s;
}

std::vector<SampleRange> normalized_ranges(std::vector<SampleRange> ranges) {
    std::sort(ranges.begin(), ranges.end(), [](const SampleRange& a, const SampleRange& b) {
        return a.seed != b.seed ? a.seed < b.seed : a.first < b.first;
    });
    std::vector<SampleRange> out;
    for (const SampleRange& r : ranges) {
        if (!out.empty() && out.back().seed == r.seed && out.back().first + out.back().count == r.first)
            out.back().count += r.count;
        else
            out.push_back(r);
    }
    return out;
}

bool looks_like_render(const FrameBuffer& fb) {
    for (const char* k : kRenderSettings)
        if (fb.metadata().count(k)) return true;
    // Only gdr writes a per-pixel sample count layer; a file that has one but
    // none of the settings lost its header.
    return fb.has("spp");
}

void check_render_settings(const FrameBuffer& fb, const std::string& file) {
    std::vector<std::string> missing;
    for (const char* k : kRenderSettings)
        if (!fb.metadata().count(k)) missing.emplace_back(k);
    if (!missing.empty()) {
        std::string list;
        for (const auto& k : missing) list += (list.empty() ? "'" : ", '") + k + "'";
        throw InputError(file + ": a gdr render without its settings " + list +
                         (missing.size() == std::size(kRenderSettings) ? " (its header is damaged or was rewritten)" : ""));
    }
    if (!fb.has("spp")) throw InputError(file + ": a gdr render without its 'spp' layer");
}

StoredRender read_stored_render(const std::string& file) {
    StoredRender r;
    r.file = file;
    r.fb = read_exr(file);
    check_render_settings(r.fb, file);
    const auto& m = r.fb.metadata();
    r.spp = metadata_count(r.fb, file, "spp");
    if (r.spp == 0 || r.spp > kMaxSamples) throw InputError(file + ": metadata entry 'spp' is not a positive sample count: '" + m.at("spp") + "'");
    if (m.count("sample_ranges")) {
        r.ranges = parse_sample_ranges(m.at("sample_ranges"), file);
    } else if (m.at("seed") == kMixedSeeds) {
        throw InputError(file + ": merged from several seeds without a 'sample_ranges' entry, so the samples it holds "
                         "are unknown");
    } else {
        const uint64_t seed = metadata_count(r.fb, file, "seed"), first = metadata_count(r.fb, file, "first_sample");
        if (first > kMaxSamples || r.spp > kMaxSamples - first)
            throw InputError(file + ": sample counts in the metadata are out of range");
        r.ranges = {{seed, first, r.spp}};
    }
    r.ranges = normalized_ranges(r.ranges);
    uint64_t held = 0;
    for (const SampleRange& s : r.ranges) held += s.count;
    if (held != r.spp)
        throw InputError(file + ": metadata entry 'sample_ranges' holds " + std::to_string(held) +
                         " samples per pixel, but 'spp' says " + m.at("spp"));
    if (r.ranges.size() == 1) {
        r.seed = r.ranges[0].seed;
        r.first_sample = r.ranges[0].first;
        if (m.at("seed") != kMixedSeeds && (metadata_count(r.fb, file, "seed") != r.seed ||
                                            metadata_count(r.fb, file, "first_sample") != r.first_sample))
            throw InputError(file + ": metadata entries 'seed' and 'first_sample' disagree with 'sample_ranges'");
    }

    // Every pixel of a render holds the same number of samples, or under
    // adaptive sampling the number its density gives for the passes taken: a
    // layer that says otherwise was damaged, and would weight a merge wrongly.
    const Image& spp = r.fb.get("spp");
    if (spp.channels() != 1) throw InputError(file + ": layer 'spp' has " + std::to_string(spp.channels()) + " channels, not 1");
    const Image* density = r.fb.has("sample_density") ? &r.fb.get("sample_density") : nullptr;
    // Merged from adaptive renders of different densities: each pixel holds
    // its own sum of counts, which no single density reproduces.
    const bool mixed = m.count("sample_density") && m.at("sample_density") == "mixed";
    if (density && density->channels() != 1)
        throw InputError(file + ": layer 'sample_density' has " + std::to_string(density->channels()) +
                         " channels, not 1");
    if (r.fb.has("gradient_mask")) {
        // Which pixels took gradient samples (RenderSettings::gradient_mask).
        const Image& mask = r.fb.get("gradient_mask");
        if (mask.channels() != 1)
            throw InputError(file + ": layer 'gradient_mask' has " + std::to_string(mask.channels()) + " channels, not 1");
        for (int y = 0; y < mask.height(); ++y)
            for (int x = 0; x < mask.width(); ++x)
                if (const float v = mask.at(x, y); v != 0.f && v != 1.f)
                    throw InputError(fmt::format("{}: layer 'gradient_mask' holds {} at pixel ({}, {}), not 0 or 1",
                                                 file, v, x, y));
    }
    for (int y = 0; y < spp.height(); ++y)
        for (int x = 0; x < spp.width(); ++x) {
            double want = double(r.spp);
            if (mixed) {
                const float n = spp.at(x, y, 0);
                if (!(n >= 1.f && n == std::floor(n) && double(n) <= double(kMaxSamples)))
                    throw InputError(fmt::format("{}: layer 'spp' holds {} at pixel ({}, {}), not a sample count", file,
                                                 n, x, y));
                continue;
            }
            if (density) {
                const float d = density->at(x, y);
                if (!(d >= 0.f && d <= kMaxSampleDensity))
                    throw InputError(fmt::format("{}: layer 'sample_density' holds {} at pixel ({}, {})", file, d, x, y));
                want = 0.0;
                for (const SampleRange& s : r.ranges)
                    want += double(sample_count((long long)(s.first + s.count), d) - sample_count((long long)s.first, d));
            }
            if (double(spp.at(x, y, 0)) != want)
                throw InputError(fmt::format("{}: layer 'spp' holds {} at pixel ({}, {}), but the render has {} samples "
                                             "there",
                                             file, spp.at(x, y, 0), x, y, want));
        }
    r.seconds = metadata_seconds(r.fb, file, "render_seconds");
    r.time_budget = metadata_seconds(r.fb, file, "time_budget");
    if (m.count("target_spp")) r.target_spp = metadata_count(r.fb, file, "target_spp");
    return r;
}

Params stored_params(const StoredRender& r) {
    Params p(r.file + " (integrator_params)");
    for (const auto& [k, v] : parameter_map(r.fb.metadata().at("integrator_params"))) p.set_from_text(k + "=" + v);
    return p;
}

RenderIdentity identity_of(const StoredRender& r) {
    const auto& m = r.fb.metadata();
    RenderIdentity id;
    id.integrator = m.at("integrator");
    id.params = m.at("integrator_params");
    id.width = r.fb.width(), id.height = r.fb.height();
    id.scene = m.at("scene");
    if (m.count("scene_hash")) id.scene_hash = m.at("scene_hash");
    if (m.count("frame")) id.frame = m.at("frame");
    return id;
}

void check_same_render(const RenderIdentity& a, const std::string& a_name, const RenderIdentity& b,
                       const std::string& b_name) {
    const std::string both = a_name + " and " + b_name;
    if (a.integrator != b.integrator)
        throw InputError(both + " differ in 'integrator': '" + a.integrator + "' against '" + b.integrator + "'");
    const auto pa = parameter_map(a.params), pb = parameter_map(b.params);
    for (const auto& [k, v] : pa) {
        const auto it = pb.find(k);
        if (it == pb.end()) throw InputError(both + " differ in integrator parameter '" + k + "': " + v + " against none");
        if (!same_value(v, it->second))
            throw InputError(both + " differ in integrator parameter '" + k + "': " + v + " against " + it->second);
    }
    for (const auto& [k, v] : pb)
        if (!pa.count(k)) throw InputError(both + " differ in integrator parameter '" + k + "': none against " + v);
    // Frames of one animation share everything else; their samples are of different images.
    if (a.frame != b.frame)
        throw InputError(both + " differ in 'frame': " + (a.frame.empty() ? "a still image" : "frame " + a.frame) +
                         " against " + (b.frame.empty() ? "a still image" : "frame " + b.frame));
    if (a.width != b.width || a.height != b.height)
        throw InputError(fmt::format("{} differ in resolution: {}x{} against {}x{}", both, a.width, a.height, b.width,
                                     b.height));
    // The content hash decides where both have one: a scene that moved is
    // the same scene, one whose meshes or materials changed is not.
    if (!a.scene_hash.empty() && !b.scene_hash.empty()) {
        if (a.scene_hash != b.scene_hash)
            throw InputError(both + " differ in 'scene_hash' (the scene file, its meshes, materials or textures): " +
                             a.scene + " (" + a.scene_hash + ") against " + b.scene + " (" + b.scene_hash + ")");
    } else if (a.scene != b.scene) {
        throw InputError(both + " differ in 'scene': " + a.scene + " against " + b.scene);
    }
}

void check_output_path(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) throw InputError("cannot write '" + path + "': it is a directory");
    if (fs::is_fifo(path, ec) || fs::is_socket(path, ec))
        throw InputError("cannot write '" + path + "': an EXR cannot go to a pipe (its writer seeks back)");
    // A device (-o /dev/null) takes anything; a file must be an EXR, since
    // the PNG preview goes beside it and would otherwise replace it.
    const bool device = fs::exists(path, ec) && !fs::is_regular_file(path, ec);
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (!device && ext != ".exr")
        throw ParameterError("cannot write '" + path + "': the output must be an .exr file (a PNG preview is written "
                             "beside it, as OUT.png)");
    fs::path dir = fs::path(path).parent_path();
    if (dir.empty()) dir = ".";
    if (!fs::is_directory(dir, ec)) throw InputError("cannot write '" + path + "': no directory '" + dir.string() + "'");
    if (access(dir.c_str(), W_OK) != 0)
        throw InputError("cannot write '" + path + "': directory '" + dir.string() + "' is not writable");
}

std::string preview_path(const std::string& out) { return fs::path(out).replace_extension(".png").string(); }

void check_not_an_input(const std::string& out, const std::vector<std::string>& inputs) {
    const auto same = [](const std::string& a, const std::string& b) {
        std::error_code ec;
        // equivalent() follows symlinks and knows hard links; it needs both to exist.
        if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
        return fs::weakly_canonical(a, ec) == fs::weakly_canonical(b, ec);
    };
    std::error_code ec;
    const bool device = fs::exists(out, ec) && !fs::is_regular_file(out, ec);
    if (device) return;
    for (const std::string& in : inputs) {
        if (in.empty()) continue;
        if (same(out, in))
            throw InputError("refusing to write '" + out + "': it is the input '" + in + "', which would be lost");
        if (same(preview_path(out), in))
            throw InputError("refusing to write '" + out + "': its preview " + preview_path(out) + " is the input '" +
                             in + "', which would be lost");
    }
}

std::string write_render(const std::string& out, const FrameBuffer& fb, float exposure) {
    write_exr_or_rescue(out, fb);
    // A device or pipe (-o /dev/null) gets no preview: it would be a stray file in /dev.
    std::error_code ec;
    if (fs::exists(out, ec) && !fs::is_regular_file(out, ec)) return "";
    const std::string png = preview_path(out);
    const std::string layer = preview_layer(fb);
    write_png_preview(png, fb.get(layer), exposure);
    return png + " (" + layer + ")";
}

std::string preview_layer(const FrameBuffer& fb) {
    // A gradient-domain render is shown as its variance-weighted (else L1)
    // reconstruction, anything else as its colour. The neural one comes
    // first: a render holds it only when it was asked for (reconstruct=neural).
    for (const char* name : {"reconstruction_neural", "reconstruction_weighted", "reconstruction_l1"})
        if (fb.has(name)) return name;
    // Else the first other reconstruction it holds (reconstruct=NAME of a plugin's method).
    for (const std::string& name : fb.names())
        if (name.rfind("reconstruction_", 0) == 0) return name;
    return fb.has("color") ? "color" : fb.names().front();
}

std::string write_exr_or_rescue(const std::string& path, const FrameBuffer& fb) {
    // Not rescued: a NaN or Inf is a defect to report, never an image to keep.
    check_finite(fb, path);
    try {
        write_exr(path, fb);
        return path;
    } catch (const Error& e) {
        const std::string rescue = rescue_path();
        bool saved = false;
        try {
            write_exr(rescue, fb);
            saved = true;
        } catch (const Error&) {
        }
        if (!saved) throw;
        throw RuntimeFailure(std::string(e.what()) + "\nthe render was saved to " + rescue +
                             " instead (gdr render --resume and gdr merge accept it)");
    }
}

std::string rescue_path() {
    return (fs::temp_directory_path() / fmt::format("gdr-rescue-{}.exr", getpid())).string();
}

void check_finite(const FrameBuffer& fb, const std::string& file) {
    for (const auto& name : fb.names()) {
        try {
            require_finite(fb.get(name), file + ": layer '" + name + "'");
        } catch (const InputError& e) {
            // Not bad input: a layer computed here, which no image may keep.
            throw RuntimeFailure(std::string(e.what()) + "; no image is written with a NaN or Inf");
        }
    }
}

}  // namespace gdr::cli
