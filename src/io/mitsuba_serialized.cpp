// Mitsuba 0.5/0.6's `.serialized` meshes, as its documentation of the
// `serialized` plugin describes them: per mesh an uncompressed header
// (uint16 0x041C, uint16 version) and a zlib stream of flags (uint32), the
// name (version 4: a NUL-terminated string), the vertex and triangle counts
// (uint64 each), positions, then normals, uvs and colours where the flags say
// so (float or double), and uint32 triangle indices; after the last mesh the
// meshes' byte offsets (uint64 in version 4, uint32 in version 3) and their
// count (uint32). All little endian. Every count is checked against what the
// compressed bytes could hold before anything is allocated.
#include "gdr/io/mitsuba_serialized.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/core.h>
#include <zlib.h>

#include "gdr/core/error.h"
#include "obj_lines.h"

namespace gdr {

namespace {

constexpr uint16_t kMagic = 0x041C;
constexpr uint32_t kHasNormals = 0x0001, kHasUvs = 0x0002, kHasColors = 0x0008, kFaceNormals = 0x0010,
                   kSingle = 0x1000, kDouble = 0x2000;
/// DEFLATE expands at most about 1032:1 (258-byte matches coded in at least
/// two bits): a bound on what a compressed range can decode to.
constexpr uint64_t kMaxDeflateRatio = 1040;
/// The longest mesh name accepted before the data is called corrupt.
constexpr size_t kMaxName = 1 << 16;

uint16_t le16(const unsigned char* p) { return uint16_t(p[0] | (p[1] << 8)); }
uint32_t le32(const unsigned char* p) {
    return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
uint64_t le64(const unsigned char* p) { return uint64_t(le32(p)) | (uint64_t(le32(p + 4)) << 32); }

/// Reads the decompressed stream of one mesh, piece by piece.
class Inflater {
public:
    Inflater(const unsigned char* data, size_t size, std::string where) : where_(std::move(where)), avail_(size) {
        std::memset(&z_, 0, sizeof(z_));
        z_.next_in = const_cast<unsigned char*>(data);
        if (inflateInit(&z_) != Z_OK) throw InputError(where_ + ": cannot start zlib decompression");
    }
    ~Inflater() { inflateEnd(&z_); }
    Inflater(const Inflater&) = delete;
    Inflater& operator=(const Inflater&) = delete;

    /// Fills `n` bytes at `dst`; `what` names them in the error of a short stream.
    void read(void* dst, size_t n, const char* what) {
        z_.next_out = static_cast<unsigned char*>(dst);
        size_t left = n;
        while (left > 0) {
            if (ended_) throw InputError(fmt::format("{}: truncated: the compressed data ends within the {}", where_, what));
            // zlib counts in uInt: feed at most 1 GiB per call.
            const uInt out_chunk = uInt(std::min<size_t>(left, size_t(1) << 30));
            if (z_.avail_in == 0) {
                const uInt in_chunk = uInt(std::min<size_t>(avail_, size_t(1) << 30));
                z_.avail_in = in_chunk;
                avail_ -= in_chunk;
            }
            z_.avail_out = out_chunk;
            const int r = inflate(&z_, Z_NO_FLUSH);
            left -= out_chunk - z_.avail_out;
            if (r == Z_STREAM_END) {
                ended_ = true;
            } else if (r == Z_BUF_ERROR && z_.avail_in == 0 && avail_ == 0) {
                throw InputError(fmt::format("{}: truncated: the file ends within the {}", where_, what));
            } else if (r != Z_OK && r != Z_BUF_ERROR) {
                throw InputError(fmt::format("{}: corrupt compressed data in the {} ({})", where_, what,
                                             z_.msg ? z_.msg : "zlib error " + std::to_string(r)));
            }
        }
    }
    /// Reads the stream to its end, which checks its Adler-32 checksum: the
    /// mesh's data must be all of it.
    void finish() {
        if (ended_ && z_.avail_in + avail_ > 0)
            throw InputError(fmt::format("{}: corrupt: {} bytes follow the mesh's compressed data (a file cut short, "
                                         "without its dictionary of shape offsets?)",
                                         where_, z_.avail_in + avail_));
        unsigned char scratch[256];
        while (!ended_) {
            z_.next_out = scratch;
            z_.avail_out = sizeof(scratch);
            if (z_.avail_in == 0) {
                const uInt in_chunk = uInt(std::min<size_t>(avail_, size_t(1) << 30));
                z_.avail_in = in_chunk;
                avail_ -= in_chunk;
            }
            const int r = inflate(&z_, Z_NO_FLUSH);
            if (z_.avail_out != sizeof(scratch))
                throw InputError(where_ + ": corrupt: the compressed data goes on after the triangle indices");
            if (r == Z_STREAM_END) {
                ended_ = true;
                if (z_.avail_in + avail_ > 0)
                    throw InputError(fmt::format("{}: corrupt: {} bytes follow the mesh's compressed data (a file cut "
                                                 "short, without its dictionary of shape offsets?)",
                                                 where_, z_.avail_in + avail_));
            } else if (r == Z_BUF_ERROR && z_.avail_in == 0 && avail_ == 0)
                throw InputError(where_ + ": truncated: the file ends before the compressed data does");
            else if (r != Z_OK && r != Z_BUF_ERROR)
                throw InputError(fmt::format("{}: corrupt compressed data ({})", where_,
                                             z_.msg ? z_.msg : "zlib error " + std::to_string(r)));
        }
    }
    uint32_t u32(const char* what) {
        unsigned char b[4];
        read(b, 4, what);
        return le32(b);
    }
    uint64_t u64(const char* what) {
        unsigned char b[8];
        read(b, 8, what);
        return le64(b);
    }
    /// `count` values of `dims` floats or doubles each, rounded to float.
    std::vector<float> reals(uint64_t count, int dims, bool dbl, const char* what) {
        std::vector<float> out(size_t(count) * dims);
        if (dbl) {
            std::vector<unsigned char> b(out.size() * 8);
            if (!b.empty()) read(b.data(), b.size(), what);
            for (size_t i = 0; i < out.size(); ++i) {
                const uint64_t bits = le64(&b[8 * i]);
                double d;
                std::memcpy(&d, &bits, 8);
                out[i] = float(d);
            }
        } else {
            std::vector<unsigned char> b(out.size() * 4);
            if (!b.empty()) read(b.data(), b.size(), what);
            for (size_t i = 0; i < out.size(); ++i) {
                const uint32_t bits = le32(&b[4 * i]);
                std::memcpy(&out[i], &bits, 4);
            }
        }
        return out;
    }

private:
    std::string where_;
    z_stream z_;
    size_t avail_;  // compressed bytes not yet given to zlib
    bool ended_ = false;
};

}  // namespace

SerializedFile::SerializedFile(const std::string& path) : bytes_(detail::read_file_text(path)), name_(path) { index(); }

SerializedFile::SerializedFile(std::string bytes, std::string name) : bytes_(std::move(bytes)), name_(std::move(name)) {
    index();
}

void SerializedFile::index() {
    const auto* b = reinterpret_cast<const unsigned char*>(bytes_.data());
    const size_t n = bytes_.size();
    if (n < 4) throw InputError(name_ + ": not a Mitsuba serialized mesh file (shorter than its 4-byte header)");
    const uint16_t magic = le16(b);
    if (magic == 0x1C04)
        throw InputError(name_ + ": a serialized mesh file of an old Mitsuba version (before format 3): re-export it");
    if (magic != kMagic)
        throw InputError(fmt::format("{}: not a Mitsuba serialized mesh file (header 0x{:04X}, expected 0x041C)", name_, magic));
    version_ = le16(b + 2);
    if (version_ != 3 && version_ != 4)
        throw InputError(fmt::format("{}: serialized mesh format version {} (gdr reads versions 3 and 4)", name_, version_));
    // The dictionary: the meshes' offsets, then their count. Mitsuba takes a
    // file too short to hold the dictionary it announces (at least a header,
    // flags, name, counts, one vertex and one triangle per mesh) as one mesh.
    const size_t entry = version_ == 4 ? 8 : 4;
    const uint64_t count = n >= 8 ? le32(b + n - 4) : 0;
    const uint64_t min_size = 4 + count * (4 + 4 + 1 + 16 + 12 + 12);
    if (count == 0 || n < min_size) {
        offsets_ = {0};
        data_end_ = n;
        return;
    }
    const size_t dict = n - 4 - size_t(count) * entry;
    data_end_ = dict;
    offsets_.resize(size_t(count));
    for (size_t i = 0; i < count; ++i) {
        const unsigned char* e = b + dict + entry * i;
        offsets_[i] = entry == 8 ? le64(e) : le32(e);
        // (offset <= dict - 4, not offset + 4 <= dict: a huge offset would wrap around.)
        const bool ok = offsets_[i] <= dict - 4 && (i == 0 ? offsets_[i] == 0 : offsets_[i] > offsets_[i - 1]) &&
                        le16(b + offsets_[i]) == kMagic && le16(b + offsets_[i] + 2) == version_;
        if (!ok)
            throw InputError(fmt::format("{}: corrupt shape index: the dictionary at the end of the file gives mesh {} "
                                         "of {} the offset {}, where no mesh header is",
                                         name_, i, count, offsets_[i]));
    }
}

SerializedMesh SerializedFile::mesh(size_t index) const {
    if (index >= offsets_.size())
        throw InputError(fmt::format("{}: shape index {} is out of range: the file holds {} mesh{} (0..{})", name_, index,
                                     offsets_.size(), offsets_.size() == 1 ? "" : "es", offsets_.size() - 1));
    const std::string where = fmt::format("{}: shape index {}", name_, index);
    const auto* b = reinterpret_cast<const unsigned char*>(bytes_.data());
    const size_t begin = size_t(offsets_[index]) + 4;
    // The mesh's compressed bytes run to the next mesh, or to the dictionary.
    size_t end = index + 1 < offsets_.size() ? size_t(offsets_[index + 1]) : data_end_;
    if (end < begin) end = begin;
    SerializedMesh m;
    m.version = version_;
    Inflater in(b + begin, end - begin, where);
    const uint32_t flags = in.u32("flags");
    m.face_normals = flags & kFaceNormals;
    m.double_precision = flags & kDouble;
    // As Mitsuba: double precision where flagged, else single.
    if ((flags & kSingle) && (flags & kDouble))
        throw InputError(fmt::format("{}: corrupt: flags 0x{:04X} give both single (0x1000) and double (0x2000) precision",
                                     where, flags));
    if (version_ == 4) {
        for (char c;;) {
            in.read(&c, 1, "mesh name");
            if (c == '\0') break;
            if (m.name.size() >= kMaxName) throw InputError(where + ": corrupt: the mesh name is not terminated");
            m.name += c;
        }
    }
    const uint64_t nv = in.u64("vertex count"), nt = in.u64("triangle count");
    // What the counts need, checked against what the compressed bytes can
    // hold before anything of that size is allocated.
    const uint64_t real = m.double_precision ? 8 : 4;
    const uint64_t per_vertex = real * (3 + (flags & kHasNormals ? 3 : 0) + (flags & kHasUvs ? 2 : 0) +
                                        (flags & kHasColors ? 3 : 0));
    const uint64_t limit = uint64_t(end - begin) * kMaxDeflateRatio + 1024;
    if (nv > std::numeric_limits<uint32_t>::max() || nt > limit / 12 || nv > limit / per_vertex ||
        nv * per_vertex + nt * 12 > limit)
        throw InputError(fmt::format("{}: corrupt or truncated: {} vertices and {} triangles cannot be held in the "
                                     "mesh's {} compressed bytes",
                                     where, nv, nt, end - begin));
    const bool dbl = m.double_precision;
    const auto vec3s = [&](const char* what) {
        const std::vector<float> v = in.reals(nv, 3, dbl, what);
        std::vector<Vec3> r(static_cast<size_t>(nv));
        for (size_t i = 0; i < r.size(); ++i) r[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
        return r;
    };
    m.positions = vec3s("vertex positions");
    for (size_t i = 0; i < m.positions.size(); ++i)
        if (!is_finite(m.positions[i])) throw InputError(fmt::format("{}: vertex {} is not a finite number", where, i));
    if (flags & kHasNormals) m.normals = vec3s("vertex normals");
    if (flags & kHasUvs) {
        const std::vector<float> v = in.reals(nv, 2, dbl, "texture coordinates");
        m.uvs.resize(size_t(nv));
        for (size_t i = 0; i < m.uvs.size(); ++i) m.uvs[i] = Vec2(v[2 * i], v[2 * i + 1]);
    }
    if (flags & kHasColors) m.colors = vec3s("vertex colours");
    std::vector<unsigned char> ib(size_t(nt) * 12);
    if (!ib.empty()) in.read(ib.data(), ib.size(), "triangle indices");
    m.indices.resize(size_t(nt) * 3);
    for (size_t i = 0; i < m.indices.size(); ++i) {
        m.indices[i] = le32(&ib[4 * i]);
        if (m.indices[i] >= nv)
            throw InputError(fmt::format("{}: triangle {} references vertex {}, but the mesh has {} vertices", where,
                                         i / 3, m.indices[i], nv));
    }
    in.finish();
    return m;
}

}  // namespace gdr
