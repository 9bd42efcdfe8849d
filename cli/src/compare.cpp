// gdr compare: the error of one image against a reference, on the layers a
// user means. A gradient-domain render holds a noisy primal ("color") beside
// its reconstruction; comparing the former by default once reported the
// error of an image nobody looks at, so the final image is the default and
// every choice made is printed before the numbers.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "frames.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "gdr/metrics.h"

namespace gdr::cli {

namespace {

// The layer a file's PNG preview shows (preview_layer()); an EXR without layers has none.
std::string final_layer(const FrameBuffer& fb, const std::string& path) {
    if (fb.names().empty()) throw InputError(path + ": holds no image layers");
    return preview_layer(fb);
}

std::string layer_list(const FrameBuffer& fb) {
    std::string s;
    for (const auto& n : fb.names()) s += (s.empty() ? "" : ", ") + n;
    return s;
}

/// One side of the comparison: the file, the layer chosen and why.
struct Side {
    std::string role;    // "image" or "reference"
    std::string path;
    std::string layer;
    std::string reason;
    Image img;
    std::string label() const { return role + " " + path + " layer '" + layer + "'"; }
};

/// How many times `big` is `small`, as text for an error ("3" or "96/33").
std::string ratio_text(int big, int small) {
    if (small > 0 && big % small == 0) return std::to_string(big / small);
    return std::to_string(big) + "/" + std::to_string(small);
}

std::string size_text(const Image& im) { return std::to_string(im.width()) + "x" + std::to_string(im.height()); }

/// Brings both sides to one resolution; returns a line saying what was done ("" if nothing).
std::string match_sizes(Side& a, Side& b, int explicit_factor) {
    const Image &ia = a.img, &ib = b.img;
    const std::string sizes =
        a.role + " " + a.path + " is " + size_text(ia) + " but " + b.role + " " + b.path + " is " + size_text(ib);
    const auto bad_factor = [&] {
        return ParameterError(fmt::format("--downsample {}: {}; the larger must be exactly {} times the smaller in "
                                          "both dimensions",
                                          explicit_factor, sizes, explicit_factor));
    };
    if (ia.width() == ib.width() && ia.height() == ib.height()) {
        if (explicit_factor > 1) throw bad_factor();
        return "";
    }
    const bool a_larger = ia.width() >= ib.width() && ia.height() >= ib.height();
    const bool b_larger = ib.width() >= ia.width() && ib.height() >= ia.height();
    Side& big = a_larger ? a : b;
    const Side& small = a_larger ? b : a;
    if (explicit_factor > 0) {
        if (!(a_larger || b_larger) || big.img.width() != explicit_factor * small.img.width() ||
            big.img.height() != explicit_factor * small.img.height())
            throw bad_factor();
    } else if (!(a_larger || b_larger)) {
        throw InputError(sizes + ": one is wider, the other taller, so no downsampling can match them");
    } else {
        const int sw = small.img.width(), sh = small.img.height(), bw = big.img.width(), bh = big.img.height();
        if (sw == 0 || sh == 0 || bw % sw != 0 || bh % sh != 0 || bw / sw != bh / sh)
            throw InputError(sizes + ": they differ by " + ratio_text(bw, sw) + " horizontally and " +
                             ratio_text(bh, sh) +
                             " vertically, not by one integer factor in both dimensions, so neither can be "
                             "downsampled to the other");
    }
    const int k = big.img.width() / small.img.width();
    const std::string from = size_text(big.img);
    big.img = box_downsample(big.img, k);
    return fmt::format("downsampled the {} from {} to {} (box filter, factor {}{}) to match the {}\n", big.role, from,
                       size_text(big.img), k, explicit_factor > 0 ? ", --downsample" : ", automatically", small.role);
}

/// Brings both sides to one channel count where that has an obvious meaning;
/// returns a line saying what was done ("" if nothing).
std::string match_channels(Side& a, Side& b) {
    const int ca = a.img.channels(), cb = b.img.channels();
    if (ca == cb) return "";
    Side& fewer = ca < cb ? a : b;
    Side& more = ca < cb ? b : a;
    const int cf = fewer.img.channels(), cm = more.img.channels();
    // Grey is the same value in R, G and B; alpha is coverage, not radiance.
    Side* change = cf == 1 && cm == 3 ? &fewer : cf == 3 && cm == 4 ? &more : nullptr;
    if (!change)
        throw InputError(fmt::format("{} has {} channels but {} has {}: only 1 and 3 (grey broadcast) or 4 and 3 "
                                     "(alpha dropped) can be compared",
                                     a.label(), ca, b.label(), cb));
    Image rgb(change->img.width(), change->img.height(), 3);
    for (int y = 0; y < rgb.height(); ++y)
        for (int x = 0; x < rgb.width(); ++x) rgb.set_rgb(x, y, change->img.rgb(x, y));
    change->img = std::move(rgb);
    return cf == 1 ? "broadcast the " + fewer.role + "'s grey channel to RGB to match the " + more.role + "\n"
                   : "dropped the alpha channel of the " + more.role + " to match the " + fewer.role + "'s RGB\n";
}

/// A line saying how many values differ at all and by how much at most:
/// "0 of N" is a bit-for-bit match, which the means and errors cannot show.
std::string differences_line(const Image& img, const Image& ref) {
    size_t differ = 0;
    double max_abs = 0.0, max_rel = 0.0, max_ref = 0.0;
    const auto& a = img.values();
    const auto& b = ref.values();
    for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
        max_ref = std::max(max_ref, std::abs(double(b[i])));
        if (a[i] == b[i]) continue;
        ++differ;
        const double d = std::abs(double(a[i]) - double(b[i]));
        max_abs = std::max(max_abs, d);
        if (b[i] != 0.f) max_rel = std::max(max_rel, d / std::abs(double(b[i])));
    }
    return fmt::format("differences:   {} of {} values differ; max |x-r| {:.6g} ({:.3g} of max |r|), max |x-r|/|r| "
                       "{:.6g} (over r != 0)\n",
                       differ, a.size(), max_abs, max_ref > 0.0 ? max_abs / max_ref : 0.0, max_rel);
}

/// Both sides read and brought to one shape, with the lines saying which layers and what was done.
struct Pair {
    Side img, ref;
    std::string notes;
};

Pair load_pair(const std::string& img_path, const std::string& ref_path, const std::string& layer,
               const std::string& ref_layer, int factor) {
    const FrameBuffer img_fb = read_exr(img_path), ref_fb = read_exr(ref_path);
    Side img{"image", img_path, layer, "--layer", {}};
    if (layer.empty()) img.layer = final_layer(img_fb, img_path), img.reason = "its final image";
    else if (!img_fb.has(layer))
        throw InputError("--layer '" + layer + "': " + img_path + " has no layer '" + layer + "' (layers: " +
                         layer_list(img_fb) + ")");
    Side ref{"reference", ref_path, ref_layer, "--ref-layer", {}};
    if (!ref_layer.empty()) {
        if (!ref_fb.has(ref_layer))
            throw InputError("--ref-layer '" + ref_layer + "': " + ref_path + " has no layer '" + ref_layer +
                             "' (layers: " + layer_list(ref_fb) + ")");
    } else if (!layer.empty() && ref_fb.has(layer)) {
        ref.layer = layer, ref.reason = "--layer, which it has too";
    } else {
        // A PT reference has no "primal": the user wants it held against the reference's image.
        ref.layer = final_layer(ref_fb, ref_path);
        ref.reason = layer.empty() ? "its final image" : "its final image; it has no layer '" + layer + "'";
    }
    img.img = img_fb.get(img.layer);
    ref.img = ref_fb.get(ref.layer);
    // Before any resampling, so that the pixel named is one of the file's.
    require_finite(img.img, img.label());
    require_finite(ref.img, ref.label());

    std::string out = fmt::format("image:         {} layer '{}' ({})\n", img.path, img.layer, img.reason);
    out += fmt::format("reference:     {} layer '{}' ({})\n", ref.path, ref.layer, ref.reason);
    out += match_sizes(img, ref, factor);
    out += match_channels(img, ref);
    return {std::move(img), std::move(ref), std::move(out)};
}

// gdr compare --frames: each frame's relMSE, and the temporal error of the sequence.
int compare_frames(const std::string& img_pattern, const std::string& ref_pattern, const std::string& range,
                   const std::string& layer, const std::string& ref_layer, int factor) {
    if (range.empty()) throw ParameterError("compare --frames: give the frame range FIRST:LAST after the two patterns");
    const auto [first, last] = parse_frame_range("--frames", range);
    if (last > first && (!has_frame_pattern(img_pattern) || !has_frame_pattern(ref_pattern)))
        throw ParameterError("compare --frames: '" + (has_frame_pattern(img_pattern) ? ref_pattern : img_pattern) +
                             "' has no frame number pattern (%04d)");
    std::vector<Image> imgs, refs;
    std::string out;
    double sum = 0.0;
    for (int k = first; k <= last; ++k) {
        Pair p = load_pair(frame_path("--frames", img_pattern, k), frame_path("--frames", ref_pattern, k), layer,
                           ref_layer, factor);
        if (k == first) out += p.notes;
        if (!imgs.empty() && !p.img.img.same_shape(imgs.back()))
            throw InputError(p.img.label() + " differs in size or channels from the frame before it");
        const double e = relmse(p.img.img, p.ref.img, RelMseOptions::thesis());
        sum += e;
        out += fmt::format("frame {}: relMSE {:.6g}\n", k, e);
        imgs.push_back(std::move(p.img.img));
        refs.push_back(std::move(p.ref.img));
    }
    out += fmt::format("mean relMSE:   {:.6g} over {} frames (mean of (x-r)^2/(r^2+0.01) per frame; thesis convention)\n",
                       sum / double(imgs.size()), imgs.size());
    if (imgs.size() >= 2)
        out += fmt::format("temporal relMSE: {:.6g} (flicker: mean over consecutive frames k, pixels and channels of "
                           "((x[k+1]-x[k])-(r[k+1]-r[k]))^2/(((r[k+1]+r[k])/2)^2+0.01))\n",
                           temporal_relmse(imgs, refs, 0.01f));
    else
        out += "temporal relMSE: n/a (one frame has no frame-to-frame differences)\n";
    fmt::print("{}", out);
    return 0;
}

}  // namespace

int compare(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::string img_path, ref_path, layer, ref_layer;
    int factor = 0;  // 0: automatic
    bool frames = false;  // --frames: IMAGE and REFERENCE are %04d patterns, then a range FIRST:LAST
    std::string frames_arg;
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-h" || o == "--help") {
            fmt::print("{}", usage("compare"));
            return 0;
        } else if (o == "--layer") layer = a.value(o);
        else if (o == "--ref-layer") ref_layer = a.value(o);
        else if (o == "--downsample") factor = int(a.int_value(o, 1, 1 << 16));
        else if (o == "--frames") frames = true;
        else if (!o.empty() && o[0] == '-') throw ParameterError("compare: unknown option '" + o + "'\n" + usage("compare"));
        else if (img_path.empty()) img_path = o;
        else if (ref_path.empty()) ref_path = o;
        else if (frames && frames_arg.empty()) frames_arg = o;
        else throw ParameterError("compare: unexpected argument '" + o + "'");
    }
    if (ref_path.empty()) throw ParameterError("compare: expected IMAGE.exr REFERENCE.exr\n" + usage("compare"));

    if (frames) return compare_frames(img_path, ref_path, frames_arg, layer, ref_layer, factor);
    if (!frames_arg.empty()) throw ParameterError("compare: a frame range needs --frames");
    auto [img, ref, out] = load_pair(img_path, ref_path, layer, ref_layer, factor);
    out += compare_report(img.img, ref.img);
    out += differences_line(img.img, ref.img);
    fmt::print("{}", out);
    return 0;
}

}  // namespace gdr::cli
