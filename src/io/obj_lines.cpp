// OBJ and MTL line checks (see obj_lines.h).
#include "obj_lines.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string_view>

#include "gdr/core/error.h"

namespace gdr::detail {

namespace fs = std::filesystem;

namespace {

// True if `t` is a whole decimal number that is finite in float; with
// `allow_overflow`, also one too large for float (1e39), which parses to inf.
bool finite_number(const std::string& t, bool allow_overflow) {
    if (t.empty()) return false;
    float v = 0.f;
    const char* first = t.c_str() + (t[0] == '+' ? 1 : 0);
    const auto res = std::from_chars(first, t.c_str() + t.size(), v);
    if (res.ec == std::errc::result_out_of_range) return allow_overflow;
    return res.ec == std::errc() && res.ptr == t.c_str() + t.size() && std::isfinite(v);
}

// Calls f(line number from 1, line without its end) for each line of `text`,
// split as tinyobjloader splits them (at \n, \r\n or a lone \r), so that line
// numbers in messages are the reader's.
template <class F>
void for_each_line(const std::string& text, F&& f) {
    size_t line_no = 0, i = 0;
    while (i < text.size()) {
        const size_t end = std::min(text.find_first_of("\r\n", i), text.size());
        f(++line_no, std::string_view(text).substr(i, end - i));
        i = end + (end < text.size() && text[end] == '\r' && end + 1 < text.size() && text[end + 1] == '\n' ? 2 : 1);
    }
}

// The line without the blanks that start it (the reader skips them too).
std::string_view trim_start(std::string_view line) {
    const size_t b = line.find_first_not_of(" \t");
    return b == std::string_view::npos ? std::string_view() : line.substr(b);
}

// What a face's index refers to, by its position in v/vt/vn.
constexpr const char* kElement[3] = {"vertex", "texture coordinate", "normal"};
constexpr const char* kElements[3] = {"vertices", "texture coordinates", "normals"};

std::string count_of(long long n, int kind) { return std::to_string(n) + " " + (n == 1 ? kElement[kind] : kElements[kind]); }

// An index of a face vertex that points past the elements defined before its
// line. The OBJ reader resolves such (positive) indices against the whole
// file, so it is checked once every line has been counted.
struct ForwardIndex {
    size_t line_no;
    std::string vertex;  // the face vertex as written, e.g. 7/7/2
    int kind;            // 0 vertex, 1 texture coordinate, 2 normal
    long long index;     // LLONG_MAX when too large for any file
};

// Checks one face vertex (v, v/vt, v//vn or v/vt/vn) against the `defined`
// vertices, texture coordinates and normals before its line. tinyobjloader
// reads an index with atoi and drops a face whose index is out of range,
// so a typo would silently leave a hole in the mesh.
void check_face_vertex(const std::string& path, size_t line_no, std::string_view vertex, const long long defined[3],
                       std::vector<ForwardIndex>& forward) {
    const auto where = [&] { return path + ": line " + std::to_string(line_no) + ": "; };
    const auto malformed = [&] {
        return InputError(where() + "face vertex '" + std::string(vertex) +
                          "' is not v, v/vt, v//vn or v/vt/vn with whole-number indices");
    };
    std::string_view part[3];
    int parts = 0;
    for (size_t b = 0;;) {
        const size_t e = vertex.find('/', b);
        if (parts == 3) throw malformed();
        part[parts++] = vertex.substr(b, e == std::string_view::npos ? std::string_view::npos : e - b);
        if (e == std::string_view::npos) break;
        b = e + 1;
    }
    for (int kind = 0; kind < parts; ++kind) {
        std::string_view t = part[kind];
        if (t.empty()) {
            if (kind == 1 && parts == 3) continue;  // v//vn: no texture coordinate
            throw malformed();
        }
        const bool negative = t[0] == '-';
        const std::string_view digits = t.substr(t[0] == '-' || t[0] == '+' ? 1 : 0);
        if (digits.empty() || digits.find_first_not_of("0123456789") != std::string_view::npos) throw malformed();
        long long index = 0;
        const auto res = std::from_chars(digits.data(), digits.data() + digits.size(), index);
        if (res.ec == std::errc::result_out_of_range) index = LLONG_MAX;
        if (index == 0)
            throw InputError(where() + "face vertex '" + std::string(vertex) + "' has " + kElement[kind] +
                             " index 0 (OBJ indices count from 1, or back from -1 for the latest)");
        if (negative) {
            if (index > defined[kind])
                throw InputError(where() + "face vertex '" + std::string(vertex) + "' references a missing " +
                                 kElement[kind] + ": -" + std::string(digits) + " counts back past the " +
                                 count_of(defined[kind], kind) + " defined before this line");
        } else if (index > defined[kind]) {
            forward.push_back({line_no, std::string(vertex), kind, index});
        }
    }
}

}  // namespace

// Why `file` cannot be read as a file (": file not found", ": not a file (a
// directory)"), or "" if it can.
std::string not_a_file(const std::string& file) {
    std::error_code ec;
    const fs::file_status st = fs::status(file, ec);
    if (fs::is_regular_file(st)) return "";
    if (fs::is_directory(st)) return ": not a file (it is a directory)";
    return fs::exists(st) ? ": not a file" : ": file not found";
}

// The whole of a file, or an InputError naming it. Only a regular file is
// read: the file is opened without blocking and checked on the open
// descriptor, so a FIFO swapped in after the name was checked cannot block
// the reader, and a device (/dev/zero) cannot feed it until memory runs out.
std::string read_file_text(const std::string& file) {
    if (const std::string why = not_a_file(file); !why.empty()) throw InputError(file + why);
    const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) throw InputError(file + ": cannot open: " + std::strerror(errno));
    struct Close {
        int fd;
        ~Close() { ::close(fd); }
    } close_fd{fd};
    struct stat st {};
    if (::fstat(fd, &st) != 0) throw InputError(file + ": cannot open: " + std::strerror(errno));
    if (!S_ISREG(st.st_mode)) throw InputError(file + ": not a file");
    // One read of the whole size: meshes run to tens of megabytes, which a
    // character-wise copy takes a noticeable part of the load to read. A file
    // that grows meanwhile (or reports no size, as /proc does) is read to its end.
    std::string text(size_t(st.st_size) + 1, '\0');  // + 1: the end is seen without growing the buffer
    size_t got = 0;
    for (;;) {
        if (got == text.size()) text.resize(std::max<size_t>(4096, 2 * text.size()));
        const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) throw InputError(file + ": cannot read: " + std::strerror(errno));
        if (n == 0) break;
        got += size_t(n);
    }
    text.resize(got);
    return text;
}

// tinyobjloader reads an MTL number it cannot parse ("Kd nan 0 0", "Ns x")
// as 0 too, which would silently turn a colour black or a lobe rough; so the
// numeric lines of a material library are checked first.
void check_material_lines(const std::string& lib) {
    static const std::map<std::string, int> kNumbers = {{"Kd", 3}, {"Ks", 3}, {"Ke", 3}, {"Ka", 3}, {"Ns", 1},
                                                        {"Ni", 1}, {"Pr", 1}, {"Pm", 1}, {"d", 1},  {"Tr", 1},
                                                        {"illum", 1}};
    if (!not_a_file(lib).empty()) return;  // the reader reports a missing library
    for_each_line(read_file_text(lib), [&](size_t line_no, std::string_view line) {
        std::istringstream words{std::string(line)};
        std::string key, t;
        words >> key;
        const auto it = kNumbers.find(key);
        if (it == kNumbers.end()) return;
        for (int k = 0; k < it->second && words >> t; ++k) {
            if (t[0] == '#' || (k == 0 && (t == "spectral" || t == "xyz"))) break;  // a comment; a non-RGB colour
            if (!finite_number(t, false))
                throw InputError(lib + ": line " + std::to_string(line_no) + ": " + key + " value '" + t +
                                 "' is not a finite number");
        }
    });
}

// tinyobjloader reads a coordinate it cannot parse ("nan", "1,5", "x") as 0,
// which would silently move a vertex or tilt a normal, and drops faces with
// fewer than 3 vertices or an index out of range, which would silently leave
// holes; so the vertex, normal, texture-coordinate and face lines are checked
// first. Also collects the material libraries, for check_material_lines(), and
// the triangle count, to catch faces the reader drops for other reasons.
ObjLines check_obj_lines(const std::string& path) {
    ObjLines found;
    std::vector<std::string>& libraries = found.libraries;
    if (!not_a_file(path).empty()) return found;  // the reader reports unreadable files
    long long defined[3] = {0, 0, 0};  // vertices, texture coordinates, normals so far
    std::vector<ForwardIndex> forward;
    for_each_line(read_file_text(path), [&](size_t line_no, std::string_view line) {
        line = trim_start(line);
        const auto where = [&] { return path + ": line " + std::to_string(line_no) + ": "; };
        const auto blank = [&](size_t i) { return i < line.size() && (line[i] == ' ' || line[i] == '\t'); };
        if (line.rfind("mtllib", 0) == 0 && blank(6)) {
            std::istringstream words{std::string(line.substr(6))};
            for (std::string name; words >> name;) libraries.push_back((fs::path(path).parent_path() / name).string());
            return;
        }
        if (line.size() >= 2 && line[0] == 'f' && blank(1)) {
            int corners = 0;
            for (size_t i = 1;;) {
                while (blank(i)) ++i;
                if (i >= line.size()) break;
                const size_t b = i;
                while (i < line.size() && !blank(i)) ++i;
                check_face_vertex(path, line_no, line.substr(b, i - b), defined, forward);
                ++corners;
            }
            if (corners < 3)
                throw InputError(where() + "a face needs at least 3 vertices, got " + std::to_string(corners));
            found.triangles += size_t(corners - 2);
            return;
        }
        // v x y z [colour], vn x y z, vt u [v [w]]: how many numbers are checked, and how many are required.
        int start, count, required, kind_index;
        const char* kind;   // what the line describes
        const char* value;  // what one of its numbers is called
        if (line.size() >= 2 && line[0] == 'v' && blank(1))
            start = 1, count = 3, required = 3, kind = "vertex", value = "vertex coordinate", kind_index = 0;
        else if (line.size() >= 3 && line[0] == 'v' && line[1] == 'n' && blank(2))
            start = 2, count = 3, required = 3, kind = "normal", value = "normal component", kind_index = 2;
        else if (line.size() >= 3 && line[0] == 'v' && line[1] == 't' && blank(2))
            start = 2, count = 3, required = 1, kind = "texture coordinate line", value = "texture coordinate",
            kind_index = 1;
        else
            return;
        ++defined[kind_index];
        const char* c = line.data() + start;
        const char* end = line.data() + line.size();
        for (int k = 0; k < count; ++k) {
            while (c < end && (*c == ' ' || *c == '\t')) ++c;
            if (c == end || *c == '#') {
                if (k >= required) break;
                throw InputError(where() + "a " + kind + " needs " + std::to_string(required) +
                                 (required == 1 ? " number" : " numbers"));
            }
            const char* tok = c;
            while (c < end && *c != ' ' && *c != '\t') ++c;
            const std::string t(tok, c);
            // Out-of-range values (1e39) parse to inf below; the loader reports those with the element's number.
            if (!finite_number(t, true))
                throw InputError(where() + value + " '" + t + "' is not a finite number");
        }
    });
    for (const ForwardIndex& f : forward)
        if (f.index > defined[f.kind])
            throw InputError(path + ": line " + std::to_string(f.line_no) + ": face vertex '" + f.vertex +
                             "' references a missing " + kElement[f.kind] + ": " +
                             (f.index == LLONG_MAX ? std::string("an index that large") : std::to_string(f.index)) +
                             " is past the " + count_of(defined[f.kind], f.kind) + " in the file");
    return found;
}

}  // namespace gdr::detail
