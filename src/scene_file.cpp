#include "gdr/io/scene_file.h"

#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <vector>

#include <fmt/core.h>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <tiny_obj_loader.h>

#include "gdr/core/error.h"

namespace gdr {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

[[noreturn]] void fail(const std::string& file, const std::string& what) { throw InputError(file + ": " + what); }

void check_keys(const std::string& file, const std::string& where, const json& obj, const std::set<std::string>& allowed) {
    if (!obj.is_object()) fail(file, where + " must be an object");
    for (auto it = obj.begin(); it != obj.end(); ++it)
        if (!allowed.count(it.key())) {
            std::string list;
            for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
            fail(file, "unknown key '" + it.key() + "' in " + where + " (expected: " + list + ")");
        }
}

float get_number(const std::string& file, const json& j, const std::string& key) {
    if (!j.is_number()) fail(file, "'" + key + "' must be a number");
    return j.get<float>();
}

// A whole number of at least `min` (resolutions, sample counts): 8.5 or "8" is an error, not 8.
long long get_integer(const std::string& file, const json& j, const std::string& key, long long min) {
    if (!j.is_number_integer() && !(j.is_number_float() && std::floor(j.get<double>()) == j.get<double>()))
        fail(file, "'" + key + "' must be an integer, got " + j.dump());
    const double v = j.get<double>();
    if (v < double(min) || v > 9.0e15)
        fail(file, "'" + key + "' must be an integer >= " + std::to_string(min) + ", got " + j.dump());
    return j.is_number_integer() ? j.get<long long>() : (long long)(v);
}

std::string get_string(const std::string& file, const json& j, const std::string& key) {
    if (!j.is_string()) fail(file, "'" + key + "' must be a string");
    return j.get<std::string>();
}

bool get_bool(const std::string& file, const json& j, const std::string& key) {
    if (!j.is_boolean()) fail(file, "'" + key + "' must be true or false");
    return j.get<bool>();
}

Vec3 get_vec3(const std::string& file, const json& j, const std::string& key) {
    if (j.is_number()) return Vec3(j.get<float>());
    if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
        fail(file, "'" + key + "' must be an array of 3 numbers");
    return Vec3(j[0].get<float>(), j[1].get<float>(), j[2].get<float>());
}

// Why `file` cannot be read as a file (": file not found", ": not a file (a
// directory)"), or "" if it can.
std::string not_a_file(const std::string& file) {
    std::error_code ec;
    const fs::file_status st = fs::status(file, ec);
    if (fs::is_regular_file(st)) return "";
    if (fs::is_directory(st)) return ": not a file (it is a directory)";
    return fs::exists(st) ? ": not a file" : ": file not found";
}

// The whole of a file, or an InputError naming it.
std::string read_file_text(const std::string& file) {
    if (const std::string why = not_a_file(file); !why.empty()) throw InputError(file + why);
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(file + ": cannot open: " + std::strerror(errno));
    // One read of the whole size: meshes run to tens of megabytes, which a
    // character-wise copy takes a noticeable part of the load to read.
    std::string text;
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    in.seekg(0, std::ios::beg);
    if (size > 0) {
        text.resize(size_t(size));
        in.read(text.data(), size);
        text.resize(size_t(in.gcount()));
    }
    // A file that grows meanwhile (or reports no size) is read to its end.
    text.append(std::istreambuf_iterator<char>(in), {});
    if (in.bad()) throw InputError(file + ": cannot read: " + std::strerror(errno));
    return text;
}

// Parses a JSON file. A key given twice in one object is an error: the parser
// would keep only the last value, silently dropping a setting the user wrote.
json parse_json_file(const std::string& file) {
    const std::string text = read_file_text(file);
    // The open objects and arrays: their key path for messages, and an object's keys so far.
    struct Open {
        bool object;
        std::string path;
        std::set<std::string> keys;
        std::string key;  // the latest key, whose value may be a nested object or array
    };
    std::vector<Open> open;
    const json::parser_callback_t check = [&](int, json::parse_event_t event, json& parsed) {
        switch (event) {
        case json::parse_event_t::object_start:
        case json::parse_event_t::array_start: {
            std::string path;
            if (!open.empty()) {
                const Open& outer = open.back();
                path = outer.object ? (outer.path.empty() ? "" : outer.path + ".") + outer.key : outer.path + "[]";
            }
            open.push_back({event == json::parse_event_t::object_start, path, {}, {}});
            break;
        }
        case json::parse_event_t::object_end:
        case json::parse_event_t::array_end:
            if (!open.empty()) open.pop_back();
            break;
        case json::parse_event_t::key: {
            Open& o = open.back();
            o.key = parsed.get<std::string>();
            if (!o.keys.insert(o.key).second)
                throw InputError(file + ": duplicate key '" + (o.path.empty() ? "" : o.path + ".") + o.key +
                                 "' (only one value can apply; remove the other)");
            break;
        }
        case json::parse_event_t::value:
            break;
        }
        return true;
    };
    try {
        return json::parse(text, check);
    } catch (const json::exception& e) {
        throw InputError(file + ": malformed JSON: " + e.what());
    }
}

// The side that keeps the aspect ratio `other_from` : `side_from` when the
// other side becomes `other_to` pixels: rounded to the nearest pixel, at least 1.
int aspect_side(long long other_to, long long other_from, long long side_from) {
    const double v = std::round(double(other_to) * double(side_from) / double(other_from));
    return int(std::clamp(v, 1.0, double(INT_MAX)));
}

// Shared camera files name the field of view fov_deg; the scene file's key is fov.
void rename_fov_deg(const std::string& file, const std::string& where, json& j) {
    if (!j.is_object() || !j.contains("fov_deg")) return;
    if (j.contains("fov")) fail(file, where + " gives both 'fov' and 'fov_deg'");
    j["fov"] = j["fov_deg"];
    j.erase("fov_deg");
}

// The scene file's "camera": a camera itself, or {"file": camera file, keys
// overriding the file's}. The camera file, if any, is appended to `inputs`.
CameraDesc parse_camera(const std::string& file, const json& j, std::vector<std::string>& inputs) {
    CameraDesc c;
    json src = j;
    if (j.is_object() && j.contains("file")) {
        const std::string cam = (fs::path(file).parent_path() / get_string(file, j["file"], "camera.file")).string();
        json base;
        try {
            base = parse_json_file(cam);
        } catch (const InputError& e) {
            fail(file, std::string("camera.file: ") + e.what());
        }
        inputs.push_back(cam);
        if (!base.is_object()) fail(cam, "a camera file must hold a JSON object");
        // Renamed before the overrides apply, so that an override's fov replaces the file's.
        rename_fov_deg(cam, "the camera file", base);
        base.erase("forward"), base.erase("note");  // target gives the direction; a note is a comment
        json over = j;
        over.erase("file");
        rename_fov_deg(file, "camera", over);
        // One side alone keeps the file's aspect ratio: with the file's other
        // side the image would be stretched, since the field of view is fixed
        // along one axis only. Both sides given are taken as they are. (A
        // camera without a file has no aspect ratio to keep: there a side not
        // given is the default 512.)
        const bool w = over.contains("width"), h = over.contains("height");
        if (w != h) {
            const CameraDesc defaults;
            const long long fw = base.contains("width") ? get_integer(cam, base["width"], "width", 1) : defaults.width;
            const long long fh = base.contains("height") ? get_integer(cam, base["height"], "height", 1) : defaults.height;
            if (w) over["height"] = aspect_side(get_integer(file, over["width"], "camera.width", 1), fw, fh);
            else over["width"] = aspect_side(get_integer(file, over["height"], "camera.height", 1), fh, fw);
        }
        for (auto it = over.begin(); it != over.end(); ++it) base[it.key()] = it.value();
        src = base;
    }
    check_keys(file, "camera", src, {"position", "target", "up", "fov", "fov_axis", "width", "height"});
    if (src.contains("position")) c.position = get_vec3(file, src["position"], "camera.position");
    if (src.contains("target")) c.target = get_vec3(file, src["target"], "camera.target");
    if (src.contains("up")) c.up = get_vec3(file, src["up"], "camera.up");
    if (src.contains("fov")) c.fov_deg = get_number(file, src["fov"], "camera.fov");
    if (src.contains("fov_axis")) {
        const std::string a = src["fov_axis"].is_string() ? src["fov_axis"].get<std::string>() : "";
        if (a != "x" && a != "y") fail(file, "'camera.fov_axis' must be \"x\" or \"y\"");
        c.fov_axis = a[0];
    }
    // Refused, not clamped: a clamped size would be a resolution nobody asked for.
    const auto side = [&](const char* key) {
        const long long v = get_integer(file, src[key], std::string("camera.") + key, 1);
        if (v > (1LL << 20))
            fail(file, std::string("'camera.") + key + "' must be at most 1048576 pixels, got " + src[key].dump());
        return int(v);
    };
    if (src.contains("width")) c.width = side("width");
    if (src.contains("height")) c.height = side("height");
    return c;
}

Mat4 parse_transform(const std::string& file, const json& j) {
    check_keys(file, "transform", j, {"matrix", "translate", "rotate", "scale"});
    if (j.contains("matrix")) {
        if (j.size() != 1) fail(file, "transform: 'matrix' cannot be combined with other keys");
        const json& m = j["matrix"];
        if (!m.is_array() || m.size() != 16) fail(file, "'transform.matrix' must be 16 numbers (row-major)");
        Mat4 r(1.f);
        for (int i = 0; i < 16; ++i) r[i % 4][i / 4] = get_number(file, m[i], "transform.matrix");
        return r;
    }
    Mat4 r(1.f);
    if (j.contains("translate")) r = glm::translate(r, get_vec3(file, j["translate"], "transform.translate"));
    if (j.contains("rotate")) {
        const json& a = j["rotate"];
        if (!a.is_array() || a.size() != 4) fail(file, "'transform.rotate' must be [axis x, y, z, degrees]");
        const Vec3 axis(get_number(file, a[0], "rotate"), get_number(file, a[1], "rotate"), get_number(file, a[2], "rotate"));
        if (!(glm::length(axis) > 0.f)) fail(file, "'transform.rotate' has a zero axis");
        r = glm::rotate(r, glm::radians(get_number(file, a[3], "rotate")), glm::normalize(axis));
    }
    if (j.contains("scale")) r = glm::scale(r, get_vec3(file, j["scale"], "transform.scale"));
    return r;
}

// Overrides of a material from the scene file, applied to the MTL description.
struct Override {
    std::string type = "auto";
    json fields;
};

MaterialDesc apply_override(const std::string& file, MaterialDesc m, const Override& o) {
    const json& j = o.fields;
    const std::string where = "materials." + m.name;
    check_keys(file, where, j, {"type", "kd", "ks", "ke", "alpha", "ns", "eta", "metal", "map_kd"});
    if (j.contains("kd")) m.kd = get_vec3(file, j["kd"], where + ".kd");
    if (j.contains("ks")) m.ks = get_vec3(file, j["ks"], where + ".ks");
    if (j.contains("ke")) m.ke = get_vec3(file, j["ke"], where + ".ke");
    // A negative alpha would be read as "no alpha given" (the MTL's Pr sentinel).
    if (j.contains("alpha")) {
        m.pr = get_number(file, j["alpha"], where + ".alpha");
        if (!(m.pr >= 0.f)) fail(file, "'" + where + ".alpha' must be >= 0 (0: a smooth mirror)");
    }
    if (j.contains("ns")) {
        m.ns = get_number(file, j["ns"], where + ".ns"), m.pr = j.contains("alpha") ? m.pr : -1.f;
        if (!(m.ns >= 0.f)) fail(file, "'" + where + ".ns' must be >= 0");
    }
    if (j.contains("eta")) {
        m.ni = get_number(file, j["eta"], where + ".eta");
        if (!(m.ni > 0.f)) fail(file, "'" + where + ".eta' must be positive");
    }
    if (j.contains("metal")) m.metal = get_bool(file, j["metal"], where + ".metal");
    if (j.contains("map_kd")) {
        const std::string t = get_string(file, j["map_kd"], where + ".map_kd");
        m.map_kd = t.empty() ? "" : (fs::path(file).parent_path() / t).string();
    }
    return m;
}

// "(r, g, b)" of a colour, for messages.
std::string colour_text(const Color& c) { return fmt::format("({}, {}, {})", c.r, c.g, c.b); }

// Rejects colours no physical material has: negative or non-finite
// components, and reflectances above 1, which create energy with every
// bounce (the estimators' variance then grows without bound with depth).
void check_material_colours(const MaterialDesc& d) {
    const auto bad = [](const Color& c, float hi) {
        for (int i = 0; i < 3; ++i)
            if (!(c[i] >= 0.f && c[i] <= hi)) return true;
        return false;
    };
    if (bad(d.kd, 1.f)) throw ParameterError("Kd must lie in [0, 1] per channel, got " + colour_text(d.kd));
    if (bad(d.ks, 1.f)) throw ParameterError("Ks must lie in [0, 1] per channel, got " + colour_text(d.ks));
    if (bad(d.ke, std::numeric_limits<float>::max()))
        throw ParameterError("Ke must be finite and >= 0 per channel, got " + colour_text(d.ke));
}

}  // namespace

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

// What the pre-pass of an OBJ found besides errors.
struct ObjLines {
    std::vector<std::string> libraries;  // mtllib names, relative to the OBJ's directory
    size_t triangles = 0;                // what the faces triangulate to: corners - 2 each
};

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
}  // namespace

// `mtl`: a material library read instead of the OBJ's own `mtllib` ("" = the
// OBJ's own); its textures are then relative to it. The files read are
// appended to `inputs` (if given).
void load_obj_impl(const std::string& path, const Mat4& xf, TriangleMesh& mesh, std::vector<Material>& materials,
                   const std::map<std::string, Override>* overrides, const std::string& scene_file,
                   std::set<std::string>* used_overrides, const std::string& mtl = "",
                   std::vector<std::string>* inputs = nullptr) {
    if (const std::string why = not_a_file(path); !why.empty()) throw InputError(path + why);
    const ObjLines lines = check_obj_lines(path);
    const std::vector<std::string>& libraries = lines.libraries;
    tinyobj::ObjReaderConfig cfg;
    cfg.triangulate = true;
    cfg.vertex_color = false;
    cfg.mtl_search_path = fs::path(path).parent_path().string();
    tinyobj::ObjReader reader;
    if (const std::string why = mtl.empty() ? "" : not_a_file(mtl); !why.empty())
        throw InputError(scene_file + ": meshes[].mtl: " + mtl + why);
    for (const std::string& lib : mtl.empty() ? libraries : std::vector<std::string>{mtl})
        check_material_lines(lib);
    // With a library of its own the OBJ is parsed from memory: tinyobjloader
    // then reads every `mtllib` from the given text instead of a file.
    bool parsed;
    if (mtl.empty()) {
        parsed = reader.ParseFromFile(path, cfg);
    } else {
        std::string obj = read_file_text(path);
        if (obj.find("mtllib") == std::string::npos) obj = "mtllib given\n" + obj;  // an OBJ without one gets it too
        parsed = reader.ParseFromString(obj, read_file_text(mtl), cfg);
    }
    if (!parsed) {
        std::string e = reader.Error();
        while (!e.empty() && (e.back() == '\n' || e.back() == '\r')) e.pop_back();
        throw InputError(path + ": cannot parse OBJ: " + (e.empty() ? "unknown error" : e));
    }
    // tinyobjloader reports problems such as a missing MTL only as warnings; a
    // missing material file would silently turn every surface grey, so it is an error.
    const std::string warn = reader.Warning();
    if (warn.find("not found") != std::string::npos && warn.find(".mtl") != std::string::npos)
        throw InputError(path + ": " + warn.substr(0, warn.find('\n')));
    if (inputs) {
        inputs->push_back(path);
        // A library named but absent is reported above; of several, the reader takes the first it finds.
        for (const std::string& lib : mtl.empty() ? libraries : std::vector<std::string>{mtl})
            if (not_a_file(lib).empty()) inputs->push_back(lib);
    }
    const auto& attrib = reader.GetAttrib();
    const auto& shapes = reader.GetShapes();
    const auto& mtls = reader.GetMaterials();
    // The reader also drops, with a warning at most, polygons its ear clipping
    // cannot cut and polygons using a vertex defined after the next g, o or
    // usemtl line (where it triangulates the faces so far).
    size_t triangles = 0;
    for (const auto& sh : shapes) triangles += sh.mesh.num_face_vertices.size();
    if (triangles != lines.triangles)
        throw InputError(path + ": its faces make " + std::to_string(lines.triangles) +
                         " triangles but the OBJ reader kept " + std::to_string(triangles) +
                         ": it drops polygons of over 3 corners that it cannot triangulate (e.g. self-intersecting)"
                         " or that use a vertex defined after a later g, o or usemtl line");

    const uint32_t base = uint32_t(materials.size());
    const fs::path dir = fs::path(mtl.empty() ? path : mtl).parent_path();  // textures are relative to the library
    for (const auto& mt : mtls) {
        MaterialDesc d;
        d.name = mt.name;
        d.kd = Color(mt.diffuse[0], mt.diffuse[1], mt.diffuse[2]);
        d.ks = Color(mt.specular[0], mt.specular[1], mt.specular[2]);
        d.ke = Color(mt.emission[0], mt.emission[1], mt.emission[2]);
        d.ns = float(mt.shininess);
        d.ni = float(mt.ior);
        d.pr = mt.roughness > 0 ? float(mt.roughness) : -1.f;
        d.metal = mt.metallic > 0.5;
        d.illum = mt.illum;
        if (!mt.diffuse_texname.empty()) d.map_kd = (dir / mt.diffuse_texname).string();
        std::string type = "auto";
        bool overridden = false;
        if (overrides) {
            auto it = overrides->find(mt.name);
            if (it != overrides->end()) {
                d = apply_override(scene_file, d, it->second);
                type = it->second.type;
                used_overrides->insert(mt.name);
                overridden = true;
            }
        }
        // Listed whenever it exists, even for materials that ignore Kd (mirrors,
        // glass) and never open it: an extra input only makes the hash stricter.
        if (inputs && !d.map_kd.empty() && not_a_file(d.map_kd).empty()) inputs->push_back(d.map_kd);
        Material m;
        m.name = d.name;
        m.emission = d.ke;
        try {
            check_material_colours(d);
            m.bsdf = type == "auto" ? bsdf_from_mtl(d) : bsdf_from_desc(d, type);
        } catch (const Error& e) {
            // An overridden material's values come (at least partly) from the scene file.
            const std::string where = overridden ? scene_file + ": materials." + d.name + " (a material of " + path + ")"
                                                 : path + ": material '" + d.name + "'";
            std::string what = e.what();
            const std::string prefix = "material '" + d.name + "': ";
            if (what.rfind(prefix, 0) == 0) what.erase(0, prefix.size());
            throw InputError(where + ": " + what);
        }
        materials.push_back(std::move(m));
    }
    // Faces without a material get a neutral grey diffuse one.
    uint32_t default_id = UINT32_MAX;

    const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(xf)));
    const bool flip = glm::determinant(glm::mat3(xf)) < 0.f;  // mirroring transforms reverse the winding
    const size_t nv = attrib.vertices.size() / 3;
    for (const auto& sh : shapes) {
        const auto& ind = sh.mesh.indices;
        for (size_t f = 0; f < sh.mesh.num_face_vertices.size(); ++f) {
            // Triangulated by the reader; anything else would misalign every later face's indices.
            if (sh.mesh.num_face_vertices[f] != 3)
                throw InputError(path + ": face " + std::to_string(f) + " of '" + sh.name + "' has " +
                                 std::to_string(sh.mesh.num_face_vertices[f]) + " corners after triangulation");
            const tinyobj::index_t* c = &ind[3 * f];
            bool has_n = true;
            Vec3 p[3], n[3];
            Vec2 uv[3];
            for (int k = 0; k < 3; ++k) {
                const int vi = c[k].vertex_index;
                if (vi < 0 || size_t(vi) >= nv)
                    throw InputError(path + ": face " + std::to_string(f) + " of '" + sh.name + "' references a missing vertex");
                const Vec3 v(attrib.vertices[3 * vi], attrib.vertices[3 * vi + 1], attrib.vertices[3 * vi + 2]);
                if (!is_finite(v))
                    throw InputError(path + ": vertex " + std::to_string(vi + 1) + " is not a finite number");
                p[k] = Vec3(xf * Vec4(v, 1.f));
                // An index past the end is a malformed face (a typo in f a/b/c), not an absent attribute.
                const int ni = c[k].normal_index, ti = c[k].texcoord_index;
                if (ni >= 0 && size_t(3 * ni + 2) >= attrib.normals.size())
                    throw InputError(path + ": face " + std::to_string(f) + " of '" + sh.name + "' references a missing normal");
                if (ti >= 0 && size_t(2 * ti + 1) >= attrib.texcoords.size())
                    throw InputError(path + ": face " + std::to_string(f) + " of '" + sh.name +
                                     "' references a missing texture coordinate");
                if (ni >= 0) {
                    const Vec3 vn(attrib.normals[3 * ni], attrib.normals[3 * ni + 1], attrib.normals[3 * ni + 2]);
                    if (!is_finite(vn)) throw InputError(path + ": normal " + std::to_string(ni + 1) + " is not a finite number");
                    n[k] = nxf * vn;
                } else {
                    has_n = false;
                }
                if (ti >= 0) {
                    uv[k] = Vec2(attrib.texcoords[2 * ti], attrib.texcoords[2 * ti + 1]);
                    if (!std::isfinite(uv[k].x) || !std::isfinite(uv[k].y))
                        throw InputError(path + ": texture coordinate " + std::to_string(ti + 1) + " is not a finite number");
                } else {
                    uv[k] = Vec2(0.f);
                }
            }
            if (flip) std::swap(p[1], p[2]), std::swap(n[1], n[2]), std::swap(uv[1], uv[2]);
            if (!has_n) {
                // Flat faces carry their face normal so one mesh can mix smooth and flat parts.
                const Vec3 fn = glm::cross(p[1] - p[0], p[2] - p[0]);
                n[0] = n[1] = n[2] = fn;
            }
            const int mid = sh.mesh.material_ids.empty() ? -1 : sh.mesh.material_ids[f];
            uint32_t id;
            if (mid >= 0 && size_t(mid) < mtls.size()) {
                id = base + uint32_t(mid);
            } else {
                if (default_id == UINT32_MAX) {
                    default_id = uint32_t(materials.size());
                    materials.push_back(Material{"(default)", make_lambertian(make_constant_texture(Color(0.5f))), Color(0.f)});
                }
                id = default_id;
            }
            for (int k = 0; k < 3; ++k) {
                mesh.positions.push_back(p[k]);
                mesh.normals.push_back(n[k]);
                mesh.uvs.push_back(uv[k]);
            }
            mesh.material_ids.push_back(id);
        }
    }
}

void load_obj(const std::string& path, const Mat4& transform, TriangleMesh& mesh, std::vector<Material>& materials) {
    load_obj_impl(path, transform, mesh, materials, nullptr, "", nullptr);
}

static SceneFile load_scene_file_impl(const std::string& path);

SceneFile load_scene_file(const std::string& path) {
    try {
        return load_scene_file_impl(path);
    } catch (const json::exception& e) {
        // Type errors (a string where a number belongs) surface here.
        throw InputError(path + ": " + e.what());
    }
}

static SceneFile load_scene_file_impl(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
        std::string hint;
        if (fs::is_regular_file(fs::path(path) / "scene.json", ec))
            hint = " (did you mean " + (fs::path(path) / "scene.json").string() + "?)";
        throw InputError(path + ": is a directory, not a scene file" + hint);
    }
    json j = parse_json_file(path);
    check_keys(path, "the scene", j, {"camera", "meshes", "materials", "render", "description"});
    if (!j.contains("camera")) fail(path, "missing 'camera'");
    if (!j.contains("meshes") || !j["meshes"].is_array() || j["meshes"].empty())
        fail(path, "'meshes' must be a non-empty array");

    SceneFile sf;
    sf.path = path;
    std::vector<std::string> inputs{path};
    const CameraDesc cd = parse_camera(path, j["camera"], inputs);
    Camera camera;
    try {
        camera = Camera(cd);
    } catch (const Error& e) {
        fail(path, e.what());
    }

    std::map<std::string, Override> overrides;
    if (j.contains("materials")) {
        if (!j["materials"].is_object()) fail(path, "'materials' must be an object keyed by material name");
        for (auto it = j["materials"].begin(); it != j["materials"].end(); ++it) {
            Override o;
            o.fields = it.value();
            if (o.fields.contains("type")) {
                if (!o.fields["type"].is_string()) fail(path, "materials." + it.key() + ".type must be a string");
                o.type = o.fields["type"].get<std::string>();
            }
            overrides[it.key()] = o;
        }
    }

    TriangleMesh mesh;
    std::vector<Material> materials;
    std::set<std::string> used;
    const fs::path dir = fs::path(path).parent_path();
    for (const auto& m : j["meshes"]) {
        const size_t first = mesh.size();
        std::string file;
        if (m.is_string()) {
            file = (dir / m.get<std::string>()).string();
            load_obj_impl(file, Mat4(1.f), mesh, materials, &overrides, path, &used, "", &inputs);
        } else {
            check_keys(path, "meshes[]", m, {"file", "transform", "mtl"});
            if (!m.contains("file") || !m["file"].is_string()) fail(path, "every mesh needs a 'file'");
            if (m.contains("mtl") && !m["mtl"].is_string()) fail(path, "'meshes[].mtl' must be a string");
            const Mat4 xf = m.contains("transform") ? parse_transform(path, m["transform"]) : Mat4(1.f);
            const std::string mtl = m.contains("mtl") ? (dir / m["mtl"].get<std::string>()).string() : std::string();
            file = (dir / m["file"].get<std::string>()).string();
            load_obj_impl(file, xf, mesh, materials, &overrides, path, &used, mtl, &inputs);
        }
        MeshStats ms{file, mesh.size() - first, 0};
        for (size_t t = first; t < mesh.size(); ++t) {
            const Vec3* p = &mesh.positions[3 * t];
            ms.degenerate_skipped += zero_area_triangle(p[0], p[1], p[2]);
        }
        sf.meshes.push_back(std::move(ms));
    }
    for (const auto& [name, o] : overrides)
        if (!used.count(name)) fail(path, "materials: no mesh has a material named '" + name + "'");

    if (j.contains("render")) {
        const json& r = j["render"];
        check_keys(path, "render", r, {"integrator", "spp", "seed", "params"});
        if (r.contains("integrator")) {
            if (!r["integrator"].is_string()) fail(path, "'render.integrator' must be a string");
            sf.defaults.integrator = r["integrator"].get<std::string>();
        }
        if (r.contains("spp")) sf.defaults.spp = get_integer(path, r["spp"], "render.spp", 1);
        if (r.contains("seed")) sf.defaults.seed = get_integer(path, r["seed"], "render.seed", 0);
        if (r.contains("params") && !r["params"].is_object()) fail(path, "'render.params' must be an object");
    }
    sf.defaults.params = Params(path);
    if (j.contains("render") && j["render"].contains("params")) {
        for (auto it = j["render"]["params"].begin(); it != j["render"]["params"].end(); ++it) {
            const json& v = it.value();
            if (v.is_boolean()) sf.defaults.params.set(it.key(), v.get<bool>());
            else if (v.is_number_integer()) sf.defaults.params.set(it.key(), v.get<long long>());
            else if (v.is_number()) sf.defaults.params.set(it.key(), v.get<double>());
            else if (v.is_string()) sf.defaults.params.set(it.key(), v.get<std::string>());
            else fail(path, "render.params." + it.key() + " must be a boolean, number or string");
        }
    }
    sf.scene = std::make_unique<Scene>(std::move(mesh), std::move(materials), camera, path);
    // A file used twice (one OBJ under two transforms, a shared texture) is hashed once.
    std::set<std::string> seen;
    for (std::string& f : inputs)
        if (seen.insert(f).second) sf.inputs.push_back(std::move(f));
    sf.content_hash = scene_content_hash(path, sf.inputs);
    return sf;
}

std::string scene_content_hash(const std::string& scene_path, const std::vector<std::string>& inputs) {
    uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a 64 offset basis
    const auto add = [&h](const void* data, size_t n) {
        const auto* b = static_cast<const unsigned char*>(data);
        for (size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 0x100000001b3ull;  // FNV-1a 64 prime
    };
    // Names relative to the scene, so that a copy of its folder elsewhere hashes the same.
    const fs::path base = fs::absolute(fs::path(scene_path)).parent_path().lexically_normal();
    for (const std::string& file : inputs) {
        const fs::path abs = fs::absolute(fs::path(file)).lexically_normal();
        fs::path rel = abs.lexically_relative(base);
        const std::string name = (rel.empty() ? abs : rel).generic_string();
        const std::string bytes = read_file_text(file);
        // The terminating zero and the size keep the boundaries between names and contents unambiguous.
        add(name.c_str(), name.size() + 1);
        unsigned char size[8];
        for (int i = 0; i < 8; ++i) size[i] = uint8_t(uint64_t(bytes.size()) >> (8 * i));
        add(size, 8);
        add(bytes.data(), bytes.size());
    }
    return fmt::format("{:016x}", h);
}

void set_resolution(SceneFile& sf, int width, int height) {
    if (!sf.scene) throw ParameterError("set_resolution: no scene is loaded");
    if (width < 0 || height < 0 || (width == 0 && height == 0))
        throw ParameterError(fmt::format("resolution {}x{}: give a positive width and height, or one of them and 0 "
                                         "for the other to keep the camera's aspect ratio",
                                         width, height));
    CameraDesc d = sf.scene->camera().desc();
    if (width == 0) width = aspect_side(height, d.height, d.width);
    if (height == 0) height = aspect_side(width, d.width, d.height);
    d.width = width, d.height = height;
    sf.scene->set_camera(Camera(d));
}

void set_fov(SceneFile& sf, float fov_deg, char axis) {
    if (!sf.scene) throw ParameterError("set_fov: no scene is loaded");
    if (axis != 0 && axis != 'x' && axis != 'y')
        throw ParameterError(std::string("fov axis '") + axis + "' must be 'x' (horizontal) or 'y' (vertical)");
    CameraDesc d = sf.scene->camera().desc();
    d.fov_deg = fov_deg;
    if (axis) d.fov_axis = axis;
    sf.scene->set_camera(Camera(d));  // rejects an angle outside (0, 180)
}

}  // namespace gdr
