// OpenEXR reading and writing of frame buffers (see gdr/io/exr.h).
//
// Channel naming: layer L with 1 channel -> "L.Y"; 2..4 channels ->
// "L.R", "L.G"[, "L.B"[, "L.A"]]. The layer "color" (1, 3 or 4 channels) is
// written with bare names (Y or R, G, B[, A]) so that ordinary viewers show
// it. Metadata key k -> string attribute "gdr:k"; the layer insertion order
// goes into the string attribute "gdrLayers" (one name per line), because the
// EXR channel list is always sorted by name.

#include "gdr/io/exr.h"

#include "file_target.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/Iex.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

namespace gdr {
namespace {

constexpr const char* kMetaPrefix = "gdr:";
constexpr const char* kLayerOrderAttr = "gdrLayers";

/// Channel suffixes for a layer of `channels` channels, in storage order.
std::vector<std::string> channel_suffixes(int channels) {
    switch (channels) {
        case 1: return {"Y"};
        case 2: return {"R", "G"};
        case 3: return {"R", "G", "B"};
        default: return {"R", "G", "B", "A"};
    }
}

/// The full EXR channel names of one layer.
std::vector<std::string> exr_channel_names(const std::string& layer, int channels) {
    // "color" with 2 channels keeps its prefix: bare R, G would look like a
    // broken RGB image to a viewer.
    const bool bare = layer == "color" && channels != 2;
    std::vector<std::string> names;
    for (const auto& s : channel_suffixes(channels)) names.push_back(bare ? s : layer + "." + s);
    return names;
}

/// Rank of a channel suffix inside its layer; -1 if it is not part of the
/// given family ("RGBA" or "XYZW").
int suffix_rank(const std::string& suffix, const std::string& family) {
    if (suffix.size() != 1) return -1;
    const auto pos = family.find(suffix[0]);
    return pos == std::string::npos ? -1 : int(pos);
}

struct ChannelGroup {
    std::string layer;                  // layer name in the frame buffer
    std::vector<std::string> channels;  // full EXR channel names, in layer order
};

/// Groups EXR channel names (sorted, as OpenEXR lists them) into layers.
std::vector<ChannelGroup> group_channels(const std::vector<std::string>& names, const std::string& path) {
    // Prefix before the last '.', "" for bare channels.
    std::map<std::string, std::vector<std::string>> by_prefix;
    std::vector<std::string> prefix_order;
    for (const auto& n : names) {
        const auto dot = n.rfind('.');
        const std::string prefix = dot == std::string::npos ? "" : n.substr(0, dot);
        if (!by_prefix.count(prefix)) prefix_order.push_back(prefix);
        by_prefix[prefix].push_back(n);
    }
    std::vector<ChannelGroup> groups;
    for (const auto& prefix : prefix_order) {
        const auto& chans = by_prefix[prefix];
        const std::string layer = prefix.empty() ? "color" : prefix;
        auto suffix = [&](const std::string& n) { return prefix.empty() ? n : n.substr(prefix.size() + 1); };
        bool grouped = false;
        for (const std::string family : {"RGBA", "XYZW"}) {
            if (chans.size() > 4) break;
            std::vector<std::pair<int, std::string>> ranked;
            for (const auto& n : chans) ranked.emplace_back(suffix_rank(suffix(n), family), n);
            if (std::any_of(ranked.begin(), ranked.end(), [](const auto& r) { return r.first < 0; })) continue;
            std::sort(ranked.begin(), ranked.end());
            ChannelGroup g{layer, {}};
            for (const auto& r : ranked) g.channels.push_back(r.second);
            groups.push_back(std::move(g));
            grouped = true;
            break;
        }
        if (grouped) continue;
        if (chans.size() == 1) {
            groups.push_back({layer, chans});
            continue;
        }
        // Unknown layout (e.g. "Z" next to R, G, B, or 5+ channels): every
        // channel becomes its own 1-channel layer rather than being dropped.
        // A bare R/G/B/A subset still forms "color".
        std::vector<std::string> rgba, rest;
        for (const auto& n : chans) (prefix.empty() && suffix_rank(n, "RGBA") >= 0 ? rgba : rest).push_back(n);
        if (!rgba.empty()) {
            std::sort(rgba.begin(), rgba.end(),
                      [](const auto& a, const auto& b) { return suffix_rank(a, "RGBA") < suffix_rank(b, "RGBA"); });
            groups.push_back({"color", rgba});
        }
        for (const auto& n : rest) groups.push_back({n, {n}});
    }
    // Two groups mapping to one layer (bare R, G, B next to "color.R", ...)
    // cannot be represented in a FrameBuffer.
    for (size_t i = 0; i < groups.size(); ++i)
        for (size_t j = i + 1; j < groups.size(); ++j)
            if (groups[i].layer == groups[j].layer)
                throw InputError(path + ": channels of layer '" + groups[i].layer +
                                 "' appear both with and without a prefix");
    return groups;
}

// What a file that is not a regular one is, for an error message.
std::string file_kind(mode_t mode) {
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISFIFO(mode)) return "a pipe (FIFO)";
    if (S_ISCHR(mode) || S_ISBLK(mode)) return "a device";
    if (S_ISSOCK(mode)) return "a socket";
    return "not a regular file";
}

// An EXR read from a regular file only. Opened with O_NONBLOCK and checked
// with fstat on the descriptor it reads, so that a FIFO, a device or a
// directory is a named error and never blocks the reader (a FIFO with no
// writer would wait for ever, a device such as /dev/zero never ends).
class RegularFileIn : public Imf::IStream {
public:
    explicit RegularFileIn(const std::string& path) : Imf::IStream(path.c_str()) {
        struct stat st {};
        // Before opening: opening some devices does something.
        if (::stat(path.c_str(), &st) != 0) throw InputError(path + ": EXR file not found");
        if (!S_ISREG(st.st_mode)) throw InputError(path + ": " + file_kind(st.st_mode) + ", not an EXR file");
        fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
        if (fd_ < 0) throw InputError(path + ": cannot open: " + std::strerror(errno));
        if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
            const std::string what = file_kind(st.st_mode);
            ::close(fd_);
            throw InputError(path + ": " + what + ", not an EXR file");
        }
        size_ = uint64_t(st.st_size);
    }
    ~RegularFileIn() override { ::close(fd_); }
    RegularFileIn(const RegularFileIn&) = delete;
    RegularFileIn& operator=(const RegularFileIn&) = delete;

    bool read(char c[], int n) override {
        if (n < 0) throw Iex::InputExc("negative read size");
        for (size_t done = 0; done < size_t(n);) {
            const ssize_t r = ::pread(fd_, c + done, size_t(n) - done, off_t(pos_ + done));
            if (r < 0 && errno == EINTR) continue;
            if (r < 0) throw Iex::InputExc(std::string("read failed: ") + std::strerror(errno));
            if (r == 0) throw Iex::InputExc("early end of file");
            done += size_t(r);
        }
        pos_ += uint64_t(n);
        return pos_ < size_;
    }
    /// Size of the file (bytes) when it was opened.
    uint64_t size() const { return size_; }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override { pos_ = pos; }

private:
    int fd_ = -1;
    uint64_t pos_ = 0, size_ = 0;
};

/// The string attributes of `header` as metadata: "gdr:k" -> k, others as named; the layer order is not metadata.
std::map<std::string, std::string> header_metadata(const Imf::Header& header) {
    std::map<std::string, std::string> out;
    for (auto it = header.begin(); it != header.end(); ++it) {
        const std::string key = it.name();
        if (key == kLayerOrderAttr) continue;
        const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute());
        if (!s) continue;
        const bool ours = key.rfind(kMetaPrefix, 0) == 0;
        out[ours ? key.substr(std::string(kMetaPrefix).size()) : key] = s->value();
    }
    return out;
}

/// Largest ratio of decoded float bytes to file bytes that read_exr accepts
/// above kExrFreeBytes. zlib, which ZIP and PXR24 use, compresses at most
/// about 1032:1, doubled when half channels are decoded to float; the margin
/// admits PIZ and DWA files of flat colour. A damaged header that declares
/// a data window of 10^12 pixels in a file of a few kilobytes is refused
/// before its pixels are allocated.
constexpr uintmax_t kExrMaxExpansion = 16384;
/// Decoded size (bytes) read_exr allocates whatever the file size.
constexpr uintmax_t kExrFreeBytes = uintmax_t(256) << 20;

}  // namespace

void write_exr(const std::string& path, const FrameBuffer& fb) {
    if (fb.names().empty() || fb.width() <= 0 || fb.height() <= 0)
        throw ParameterError(path + ": cannot write an empty frame buffer (" + std::to_string(fb.width()) + "x" +
                             std::to_string(fb.height()) + ", " + std::to_string(fb.names().size()) + " layers)");
    for (const auto& name : fb.names())
        if (name.empty()) throw ParameterError(path + ": cannot write a layer with an empty name");

    const int w = fb.width(), h = fb.height();
    const io::FileTarget target = io::file_target(path);
    const std::string& tmp = target.write_path;
    try {
        Imf::Header header(w, h);
        header.compression() = Imf::ZIP_COMPRESSION;
        std::string order;
        for (const auto& name : fb.names()) order += name + "\n";
        header.insert(kLayerOrderAttr, Imf::StringAttribute(order));
        for (const auto& [key, value] : fb.metadata())
            header.insert(kMetaPrefix + key, Imf::StringAttribute(value));

        Imf::FrameBuffer slices;
        for (const auto& name : fb.names()) {
            const Image& img = fb.get(name);
            const auto chans = exr_channel_names(name, img.channels());
            const size_t xs = sizeof(float) * img.channels(), ys = xs * w;
            for (int c = 0; c < img.channels(); ++c) {
                header.channels().insert(chans[c], Imf::Channel(Imf::FLOAT));
                // OpenEXR only reads through the pointer when writing.
                slices.insert(chans[c], Imf::Slice(Imf::FLOAT, (char*)(img.data() + c), xs, ys));
            }
        }

        // Our own stream, so a failed flush at close (disk full) is seen:
        // OutputFile's destructor swallows errors.
        std::ofstream os(tmp, std::ios::binary | std::ios::trunc);
        if (!os) throw RuntimeFailure("cannot create '" + tmp + "'");
        {
            Imf::StdOFStream exr_os(os, tmp.c_str());
            Imf::OutputFile file(exr_os, header);
            file.setFrameBuffer(slices);
            file.writePixels(h);
        }
        os.close();
        if (!os) throw RuntimeFailure("write to '" + tmp + "' failed");
        io::commit(target);
    } catch (const std::exception& e) {
        io::discard(target);
        throw RuntimeFailure("cannot write EXR '" + path + "': " + e.what());
    }
}

FrameBuffer read_exr(const std::string& path) {
    try {
        RegularFileIn stream(path);
        const uintmax_t file_bytes = stream.size();
        Imf::InputFile file(stream, Imf::globalThreadCount());
        const Imf::Header& header = file.header();
        const Imath::Box2i dw = header.dataWindow();
        const long long wl = (long long)dw.max.x - dw.min.x + 1, hl = (long long)dw.max.y - dw.min.y + 1;
        if (wl <= 0 || hl <= 0 || wl > (1 << 20) || hl > (1 << 20))
            throw InputError(path + ": unsupported data window size " + std::to_string(wl) + "x" +
                             std::to_string(hl));
        const int w = int(wl), h = int(hl);

        std::vector<std::string> names;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
                throw InputError(path + ": channel '" + it.name() + "' is subsampled (unsupported)");
            names.emplace_back(it.name());
        }
        if (names.empty()) throw InputError(path + ": EXR has no channels");
        const uintmax_t decoded = uintmax_t(w) * uintmax_t(h) * names.size() * sizeof(float);
        if (decoded > kExrFreeBytes && decoded / kExrMaxExpansion > file_bytes)
            throw InputError(path + ": the header declares " + std::to_string(w) + "x" + std::to_string(h) + " pixels of " +
                             std::to_string(names.size()) + " channels (" + std::to_string(decoded >> 20) +
                             " MiB), more than a file of " + std::to_string(file_bytes) +
                             " bytes can hold (a damaged header?)");

        auto groups = group_channels(names, path);
        // Restore the writer's layer order where recorded; unknown layers keep
        // channel-list order after the listed ones.
        if (const auto* attr = header.findTypedAttribute<Imf::StringAttribute>(kLayerOrderAttr)) {
            std::vector<std::string> order;
            std::string line;
            for (char ch : attr->value()) {
                if (ch == '\n') order.push_back(line), line.clear();
                else line += ch;
            }
            if (!line.empty()) order.push_back(line);
            // The writer listed every layer it wrote: one that is gone was lost with part of the file.
            for (const std::string& layer : order)
                if (std::none_of(groups.begin(), groups.end(), [&](const auto& g) { return g.layer == layer; }))
                    throw InputError(path + ": layer '" + layer + "' is listed in the header but has no channels "
                                     "(the file is damaged)");
            auto rank = [&](const ChannelGroup& g) {
                const auto it = std::find(order.begin(), order.end(), g.layer);
                return size_t(it - order.begin());
            };
            std::stable_sort(groups.begin(), groups.end(),
                             [&](const auto& a, const auto& b) { return rank(a) < rank(b); });
        }

        FrameBuffer fb(w, h);
        Imf::FrameBuffer slices;
        for (const auto& g : groups) {
            Image& img = fb.add(g.layer, int(g.channels.size()));
            const size_t xs = sizeof(float) * img.channels(), ys = xs * w;
            for (size_t c = 0; c < g.channels.size(); ++c)
                // Slice::Make offsets the base pointer by the data window origin.
                slices.insert(g.channels[c],
                              Imf::Slice::Make(Imf::FLOAT, img.data() + c, dw, xs, ys));
        }
        file.setFrameBuffer(slices);
        file.readPixels(dw.min.y, dw.max.y);

        fb.metadata() = header_metadata(header);
        return fb;
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        // Iex exceptions derive from std::exception and do not name the file.
        throw InputError(path + ": cannot read EXR: " + e.what());
    }
}

ExrHeader read_exr_header(const std::string& path) {
    try {
        // The header alone: Imf::InputFile reads no pixels until asked to.
        RegularFileIn stream(path);
        Imf::InputFile file(stream, Imf::globalThreadCount());
        const Imf::Header& header = file.header();
        const Imath::Box2i dw = header.dataWindow();
        ExrHeader out;
        out.width = dw.max.x - dw.min.x + 1;
        out.height = dw.max.y - dw.min.y + 1;
        out.metadata = header_metadata(header);
        return out;
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        throw InputError(path + ": cannot read EXR: " + e.what());
    }
}

Image read_exr_rgb(const std::string& path) {
    FrameBuffer fb = read_exr(path);
    std::string layer;
    if (fb.names().size() == 1) layer = fb.names().front();
    else if (fb.has("color")) layer = "color";  // a gdr multi-layer output: its viewer-visible image
    else {
        std::string list;
        for (const auto& n : fb.names()) list += (list.empty() ? "" : ", ") + n;
        throw InputError(path + ": expected one RGB image, found layers " + list);
    }
    Image& src = fb.get(layer);
    if (src.channels() == 3) return std::move(src);
    if (src.channels() == 2)
        throw InputError(path + ": layer '" + layer + "' has 2 channels, expected RGB");
    // Grey is broadcast and alpha dropped so callers can rely on 3 channels.
    Image rgb(src.width(), src.height(), 3);
    for (int y = 0; y < src.height(); ++y)
        for (int x = 0; x < src.width(); ++x) rgb.set_rgb(x, y, src.rgb(x, y));
    return rgb;
}

void write_exr_image(const std::string& path, const Image& img) {
    FrameBuffer fb(img.width(), img.height());
    fb.set("color", img);
    write_exr(path, fb);
}

void set_exr_threads(int threads) {
    if (threads < 0) throw ParameterError("set_exr_threads: threads must be >= 0, got " + std::to_string(threads));
    Imf::setGlobalThreadCount(threads);
}

}  // namespace gdr
