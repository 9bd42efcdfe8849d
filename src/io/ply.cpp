// A small PLY reader (Debian packages no C or C++ PLY library). The header
// declares elements and their typed properties; the body holds them in
// order, as whitespace-separated text or packed binary of either byte order.
#include "gdr/io/ply.h"

#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "gdr/core/error.h"
#include "obj_lines.h"

namespace gdr {
namespace {

enum class Format { Ascii, BinaryLittle, BinaryBig };

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// The PLY type names, both the classic and the sized spelling.
bool type_of(const std::string& s, Type& t) {
    static const struct {
        const char* name;
        Type type;
    } kTypes[] = {{"char", Type::Int8},     {"int8", Type::Int8},       {"uchar", Type::UInt8},
                  {"uint8", Type::UInt8},   {"short", Type::Int16},     {"int16", Type::Int16},
                  {"ushort", Type::UInt16}, {"uint16", Type::UInt16},   {"int", Type::Int32},
                  {"int32", Type::Int32},   {"uint", Type::UInt32},     {"uint32", Type::UInt32},
                  {"float", Type::Float32}, {"float32", Type::Float32}, {"double", Type::Float64},
                  {"float64", Type::Float64}};
    for (const auto& k : kTypes)
        if (s == k.name) return t = k.type, true;
    return false;
}

size_t size_of(Type t) {
    switch (t) {
    case Type::Int8:
    case Type::UInt8: return 1;
    case Type::Int16:
    case Type::UInt16: return 2;
    case Type::Int32:
    case Type::UInt32:
    case Type::Float32: return 4;
    case Type::Float64: return 8;
    }
    return 1;
}

bool is_integer(Type t) { return t != Type::Float32 && t != Type::Float64; }

struct Property {
    std::string name;
    Type type = Type::Float32;
    bool list = false;
    Type count_type = Type::UInt8;  // of a list
};

struct Element {
    std::string name;
    size_t count = 0;
    std::vector<Property> props;
    int header_line = 0;
};

/// Reads the body: a cursor over binary bytes or ASCII tokens, whichever the format is.
class Body {
public:
    Body(const std::string& bytes, size_t start, Format f, const std::string& name, int first_line)
        : b_(bytes), pos_(start), f_(f), name_(name), line_(first_line) {}

    /// The next value of type t, as a double (exact for every PLY integer type).
    double read(Type t, const std::string& what) {
        if (f_ == Format::Ascii) return read_text(t, what);
        const size_t n = size_of(t);
        if (pos_ + n > b_.size()) throw InputError(name_ + ": the file ends inside " + what + " (truncated?)");
        unsigned char raw[8];
        std::memcpy(raw, b_.data() + pos_, n);
        pos_ += n;
        const bool little_host = std::endian::native == std::endian::little;
        if ((f_ == Format::BinaryLittle) != little_host)
            for (size_t i = 0; i < n / 2; ++i) std::swap(raw[i], raw[n - 1 - i]);
        switch (t) {
        case Type::Int8: return double(int8_t(raw[0]));
        case Type::UInt8: return double(raw[0]);
        case Type::Int16: { int16_t v; std::memcpy(&v, raw, 2); return v; }
        case Type::UInt16: { uint16_t v; std::memcpy(&v, raw, 2); return v; }
        case Type::Int32: { int32_t v; std::memcpy(&v, raw, 4); return v; }
        case Type::UInt32: { uint32_t v; std::memcpy(&v, raw, 4); return v; }
        case Type::Float32: { float v; std::memcpy(&v, raw, 4); return v; }
        case Type::Float64: { double v; std::memcpy(&v, raw, 8); return v; }
        }
        return 0.0;
    }

    /// "line N" of the ASCII body, or "" for binary files (for messages).
    std::string where() const { return f_ == Format::Ascii ? " (line " + std::to_string(line_) + ")" : ""; }

private:
    double read_text(Type t, const std::string& what) {
        // Skip whitespace, counting lines.
        while (pos_ < b_.size() && (b_[pos_] == ' ' || b_[pos_] == '\t' || b_[pos_] == '\r' || b_[pos_] == '\n')) {
            if (b_[pos_] == '\n') ++line_;
            ++pos_;
        }
        if (pos_ >= b_.size()) throw InputError(name_ + ": the file ends inside " + what + " (truncated?)");
        size_t end = pos_;
        while (end < b_.size() && !std::isspace(static_cast<unsigned char>(b_[end]))) ++end;
        const std::string tok = b_.substr(pos_, end - pos_);
        pos_ = end;
        double v = 0.0;
        const char* first = tok.data();
        const char* last = first + tok.size();
        if (*first == '+') ++first;
        const auto r = std::from_chars(first, last, v);
        if (r.ec != std::errc() || r.ptr != last)
            throw InputError(name_ + ": line " + std::to_string(line_) + ": '" + tok + "' is not a number (in " + what + ")");
        if (is_integer(t) && v != std::floor(v))
            throw InputError(name_ + ": line " + std::to_string(line_) + ": '" + tok + "' is not an integer (in " +
                             what + ")");
        return v;
    }

    const std::string& b_;
    size_t pos_;
    Format f_;
    const std::string& name_;
    int line_;
};

}  // namespace

PlyMesh read_ply(const std::string& path) { return parse_ply(detail::read_file_text(path), path); }

PlyMesh parse_ply(const std::string& bytes, const std::string& name) {
    // Header: text lines up to and including "end_header".
    size_t pos = 0;
    int line_no = 0;
    const auto next_line = [&](std::string& line) {
        if (pos >= bytes.size()) return false;
        size_t e = bytes.find('\n', pos);
        if (e == std::string::npos) e = bytes.size();
        line = bytes.substr(pos, e - pos);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        pos = std::min(bytes.size(), e + 1);
        ++line_no;
        return true;
    };
    const auto fail = [&](const std::string& what) -> void {
        throw InputError(name + ": line " + std::to_string(line_no) + ": " + what);
    };
    std::string line;
    if (!next_line(line) || line != "ply") throw InputError(name + ": not a PLY file (it does not start with 'ply')");
    Format format = Format::Ascii;
    bool have_format = false, ended = false;
    std::vector<Element> elements;
    while (next_line(line)) {
        std::istringstream in(line);
        std::string word;
        in >> word;
        if (word.empty() || word == "comment" || word == "obj_info") continue;
        if (word == "end_header") {
            ended = true;
            break;
        }
        if (word == "format") {
            std::string f, version;
            in >> f >> version;
            if (f == "ascii") format = Format::Ascii;
            else if (f == "binary_little_endian") format = Format::BinaryLittle;
            else if (f == "binary_big_endian") format = Format::BinaryBig;
            else fail("unknown format '" + f + "' (expected ascii, binary_little_endian or binary_big_endian)");
            if (version != "1.0") fail("unsupported PLY version '" + version + "' (expected 1.0)");
            have_format = true;
        } else if (word == "element") {
            Element e;
            std::string count;
            in >> e.name >> count;
            size_t n = 0;
            const auto r = std::from_chars(count.data(), count.data() + count.size(), n);
            if (e.name.empty() || r.ec != std::errc() || r.ptr != count.data() + count.size())
                fail("malformed element line '" + line + "' (expected: element NAME COUNT)");
            e.count = n;
            e.header_line = line_no;
            elements.push_back(std::move(e));
        } else if (word == "property") {
            if (elements.empty()) fail("a property before any element");
            Property p;
            std::string t;
            in >> t;
            if (t == "list") {
                std::string ct, it;
                in >> ct >> it >> p.name;
                p.list = true;
                if (!type_of(ct, p.count_type) || !type_of(it, p.type)) fail("unknown property type in '" + line + "'");
                if (!is_integer(p.count_type)) fail("a list's count type must be an integer type in '" + line + "'");
            } else {
                in >> p.name;
                if (!type_of(t, p.type)) fail("unknown property type '" + t + "'");
            }
            if (p.name.empty()) fail("a property without a name");
            elements.back().props.push_back(std::move(p));
        } else {
            fail("unknown header keyword '" + word + "'");
        }
    }
    if (!ended) throw InputError(name + ": the header has no end_header line (truncated?)");
    if (!have_format) throw InputError(name + ": the header has no format line");

    // An item of an element with properties takes at least one byte, so the
    // counts are checked against the body before any loop or allocation: a
    // header may declare 10^12 items in a file of a few bytes. (A shorter
    // shortfall is left to the reader, whose message names the item cut off.)
    const size_t body_bytes = bytes.size() - pos;
    size_t need = 0;
    for (const Element& e : elements) {
        if (e.props.empty()) continue;  // an element without properties holds nothing to read
        if (e.count > body_bytes - need)
            throw InputError(name + ": line " + std::to_string(e.header_line) + ": element '" + e.name + "' declares " +
                             std::to_string(e.count) + " items, more than the " + std::to_string(body_bytes) +
                             " bytes after the header can hold (truncated, or a damaged header?)");
        need += e.count;
    }

    PlyMesh m;
    Body body(bytes, pos, format, name, line_no + 1);
    bool have_vertices = false, have_faces = false;
    for (const Element& e : elements) {
        const std::string where_e = "element '" + e.name + "'";
        if (e.name == "vertex") {
            have_vertices = true;
            // Which property feeds which attribute: -1 for none.
            int ix[8];
            std::fill(ix, ix + 8, -1);
            static const char* const kNames[][4] = {{"x"}, {"y"}, {"z"}, {"nx"}, {"ny"}, {"nz"},
                                                    {"u", "s", "texture_u", "texture_s"},
                                                    {"v", "t", "texture_v", "texture_t"}};
            for (size_t i = 0; i < e.props.size(); ++i)
                for (int a = 0; a < 8; ++a)
                    for (const char* n : kNames[a])
                        if (n && e.props[i].name == n && ix[a] < 0) ix[a] = int(i);
            for (int a = 0; a < 3; ++a)
                if (ix[a] < 0)
                    throw InputError(name + ": line " + std::to_string(e.header_line) +
                                     ": the vertex element has no '" + kNames[a][0] + "' property");
            for (int a = 0; a < 8; ++a)
                if (ix[a] >= 0 && e.props[ix[a]].list)
                    throw InputError(name + ": vertex property '" + e.props[ix[a]].name + "' must not be a list");
            const bool normals = ix[3] >= 0 && ix[4] >= 0 && ix[5] >= 0;
            const bool uvs = ix[6] >= 0 && ix[7] >= 0;
            m.positions.reserve(std::min<size_t>(e.count, bytes.size()));
            std::vector<double> v(e.props.size());
            for (size_t k = 0; k < e.count; ++k) {
                const std::string what = "vertex " + std::to_string(k);
                for (size_t i = 0; i < e.props.size(); ++i) {
                    const Property& p = e.props[i];
                    if (p.list) {
                        const double n = body.read(p.count_type, what);
                        for (double j = 0; j < n; ++j) body.read(p.type, what);
                    } else {
                        v[i] = body.read(p.type, what);
                    }
                }
                const Vec3 pos3(float(v[ix[0]]), float(v[ix[1]]), float(v[ix[2]]));
                if (!is_finite(pos3)) throw InputError(name + ": vertex " + std::to_string(k) + " is not a finite number" + body.where());
                m.positions.push_back(pos3);
                if (normals) m.normals.emplace_back(float(v[ix[3]]), float(v[ix[4]]), float(v[ix[5]]));
                if (uvs) m.uvs.emplace_back(float(v[ix[6]]), float(v[ix[7]]));
            }
        } else if (e.name == "face") {
            if (!have_vertices) throw InputError(name + ": the face element comes before the vertex element");
            have_faces = true;
            int list = -1;
            for (size_t i = 0; i < e.props.size(); ++i)
                if (e.props[i].list && (e.props[i].name == "vertex_indices" || e.props[i].name == "vertex_index")) list = int(i);
            if (list < 0)
                throw InputError(name + ": line " + std::to_string(e.header_line) +
                                 ": the face element has no 'vertex_indices' list property");
            if (!is_integer(e.props[list].type)) throw InputError(name + ": face indices must have an integer type");
            std::vector<uint32_t> corners;
            for (size_t k = 0; k < e.count; ++k) {
                const std::string what = "face " + std::to_string(k);
                for (size_t i = 0; i < e.props.size(); ++i) {
                    const Property& p = e.props[i];
                    if (!p.list) {
                        body.read(p.type, what);
                        continue;
                    }
                    const double n = body.read(p.count_type, what);
                    if (int(i) != list) {
                        for (double j = 0; j < n; ++j) body.read(p.type, what);
                        continue;
                    }
                    if (n < 3)
                        throw InputError(name + ": face " + std::to_string(k) + " has " + std::to_string(long(n)) +
                                         " corners (at least 3 needed)" + body.where());
                    corners.clear();
                    for (double j = 0; j < n; ++j) {
                        const double idx = body.read(p.type, what);
                        if (idx < 0 || idx >= double(m.positions.size()))
                            throw InputError(name + ": face " + std::to_string(k) + " references vertex " +
                                             std::to_string((long long)idx) + ", but there are " +
                                             std::to_string(m.positions.size()) + " vertices" + body.where());
                        corners.push_back(uint32_t(idx));
                    }
                    for (size_t c = 1; c + 1 < corners.size(); ++c)
                        m.indices.insert(m.indices.end(), {corners[0], corners[c], corners[c + 1]});
                    ++m.polygons;
                }
            }
        } else if (!e.props.empty()) {
            for (size_t k = 0; k < e.count; ++k) {
                const std::string what = where_e + " " + std::to_string(k);
                for (const Property& p : e.props) {
                    if (p.list) {
                        const double n = body.read(p.count_type, what);
                        for (double j = 0; j < n; ++j) body.read(p.type, what);
                    } else {
                        body.read(p.type, what);
                    }
                }
            }
        }
    }
    if (!have_vertices) throw InputError(name + ": the file has no vertex element");
    if (!have_faces || m.indices.empty()) throw InputError(name + ": the file has no faces");
    return m;
}

}  // namespace gdr
