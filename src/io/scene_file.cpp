#include "gdr/io/scene_file.h"
#include "gdr/io/texture_files.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <vector>

#include <fmt/core.h>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <tiny_obj_loader.h>

#include "gdr/core/error.h"
#include "gdr/scene/coordinates.h"
#include "gdr/io/exr.h"
#include "gdr/io/mitsuba_xml.h"
#include "obj_lines.h"

namespace gdr {

using detail::check_material_lines;
using detail::check_obj_lines;
using detail::not_a_file;
using detail::ObjLines;
using detail::read_file_text;

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

[[noreturn]] void fail(const std::string& file, const std::string& what) { throw InputError(file + ": " + what); }

constexpr std::string_view kScenesPrefix = "$GDR_SCENES/";

// A path named in the scene file `file`: relative to that file, or, when it
// starts with "$GDR_SCENES/", inside the folder of the larger public scenes
// (scenes_dir()). Such a file that is absent is an error saying how to
// provide the folder, since it is not part of the repository.
std::string resolve_path(const std::string& file, const std::string& rel, const std::string& key) {
    if (rel.rfind(kScenesPrefix, 0) != 0) return (fs::path(file).parent_path() / rel).string();
    const std::string dir = scenes_dir();
    const std::string full = (fs::path(dir) / rel.substr(kScenesPrefix.size())).string();
    if (!fs::exists(full))
        fail(file, key + ": " + rel + " (" + full + "): file not found. $GDR_SCENES is the folder of the larger "
                   "public scenes, " + dir + " here; set the environment variable GDR_SCENES (or the CMake "
                   "setting GDR_SCENES) to where they are; docs/scenes.md says where to download each");
    return full;
}

void check_keys(const std::string& file, const std::string& where, const json& obj, const std::set<std::string>& allowed) {
    if (!obj.is_object()) fail(file, where + " must be an object");
    for (auto it = obj.begin(); it != obj.end(); ++it)
        if (!allowed.count(it.key())) {
            std::string list;
            for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
            fail(file, "unknown key '" + it.key() + "' in " + where + " (expected: " + list + ")");
        }
}

// True if the JSON number `j` is finite in float: 1e39 would be read as Inf.
bool float_range(const json& j) { return std::abs(j.get<double>()) <= double(std::numeric_limits<float>::max()); }

float get_number(const std::string& file, const json& j, const std::string& key) {
    if (!j.is_number()) fail(file, "'" + key + "' must be a number");
    if (!float_range(j)) fail(file, "'" + key + "' must be a finite number within float range (|x| <= 3.4e38), got " + j.dump());
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
    if (j.is_number()) return Vec3(get_number(file, j, key));
    if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
        fail(file, "'" + key + "' must be an array of 3 numbers");
    for (const json& x : j)
        if (!float_range(x))
            fail(file, "'" + key + "' must hold finite numbers within float range (|x| <= 3.4e38), got " + j.dump());
    return Vec3(j[0].get<float>(), j[1].get<float>(), j[2].get<float>());
}


/// Deepest nesting of objects and arrays a JSON scene, camera or animation file may have.
constexpr size_t kMaxJsonDepth = 100;

// Parses a JSON file. A key given twice in one object is an error: the parser
// would keep only the last value, silently dropping a setting the user wrote.
json parse_json_text(const std::string& file, const std::string& text);

json parse_json_file(const std::string& file) { return parse_json_text(file, read_file_text(file)); }

// Parses JSON `text`, named `file` in messages (duplicate keys refused as in parse_json_file).
json parse_json_text(const std::string& file, const std::string& text) {
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
            // Each level keeps its key path, so a hostile depth (10^6 nested arrays) would take
            // time and memory quadratic in it; no scene nests more than a few levels.
            if (open.size() >= kMaxJsonDepth)
                throw InputError(file + ": objects and arrays nest more than " + std::to_string(kMaxJsonDepth) +
                                 " deep" + (open.back().path.empty() ? "" : " (in '" + open.back().path.substr(0, 60) + "...')"));
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
        const std::string cam = resolve_path(file, get_string(file, j["file"], "camera.file"), "camera.file");
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

// A key's frame: a finite number, fractional allowed.
double key_frame(const std::string& file, const std::string& where, const json& k) {
    if (!k.contains("frame")) fail(file, where + " needs a 'frame'");
    if (!k["frame"].is_number() || !std::isfinite(k["frame"].get<double>()))
        fail(file, "'" + where + ".frame' must be a finite number, got " + k["frame"].dump());
    return k["frame"].get<double>();
}

// The "keys" array at `where`: an array of objects whose frames strictly increase.
void check_key_list(const std::string& file, const std::string& where, const json& keys) {
    if (!keys.is_array() || keys.empty()) fail(file, "'" + where + "' must be a non-empty array of keys");
    double prev = 0.0;
    for (size_t i = 0; i < keys.size(); ++i) {
        const std::string at = where + "[" + std::to_string(i) + "]";
        if (!keys[i].is_object()) fail(file, "'" + at + "' must be an object");
        const double f = key_frame(file, at, keys[i]);
        if (i > 0 && !(f > prev))
            fail(file, "'" + at + ".frame' is " + keys[i]["frame"].dump() + ", not after the previous key's " +
                           json(prev).dump() + " (keys must be in strictly increasing frame order)");
        prev = f;
    }
}

// A numeric array of exactly n finite numbers at `where`.
std::vector<double> finite_numbers(const std::string& file, const std::string& where, const json& j, size_t n,
                                   const std::string& shape) {
    if (!j.is_array() || j.size() != n) fail(file, "'" + where + "' must be " + shape);
    std::vector<double> v;
    for (const json& x : j) {
        if (!x.is_number() || !std::isfinite(x.get<double>())) fail(file, "'" + where + "' must be " + shape);
        v.push_back(x.get<double>());
    }
    return v;
}

// A mesh entry's "keys": its motion, applied after the entry's fixed transform.
TransformTrack parse_object_keys(const std::string& file, const std::string& where, const json& keys) {
    check_key_list(file, where, keys);
    TransformTrack track;
    for (size_t i = 0; i < keys.size(); ++i) {
        const std::string at = where + "[" + std::to_string(i) + "]";
        const json& k = keys[i];
        check_keys(file, at, k, {"frame", "translate", "rotate", "quaternion", "scale"});
        TransformKey key;
        key.frame = key_frame(file, at, k);
        if (k.contains("translate")) {
            const auto v = finite_numbers(file, at + ".translate", k["translate"], 3, "an array of 3 finite numbers");
            key.value.translate = Vec3(float(v[0]), float(v[1]), float(v[2]));
        }
        if (k.contains("scale")) {
            const json& sj = k["scale"];
            std::vector<double> v;
            if (sj.is_number()) v.assign(3, sj.get<double>());
            else v = finite_numbers(file, at + ".scale", sj, 3, "a number or an array of 3 numbers");
            for (double x : v)
                if (!std::isfinite(x) || x == 0.0)
                    fail(file, "'" + at + ".scale' must be finite and non-zero, got " + sj.dump());
            key.value.scale = Vec3(float(v[0]), float(v[1]), float(v[2]));
        }
        if (k.contains("rotate") && k.contains("quaternion"))
            fail(file, "'" + at + "' gives both 'rotate' and 'quaternion'; give one rotation");
        if (k.contains("rotate")) {
            const auto v = finite_numbers(file, at + ".rotate", k["rotate"], 4, "[axis x, y, z, degrees]");
            const glm::dvec3 axis(v[0], v[1], v[2]);
            if (!(glm::length(axis) > 0.0)) fail(file, "'" + at + ".rotate' has a zero axis");
            key.value.rotate = Quat(glm::angleAxis(glm::radians(v[3]), glm::normalize(axis)));
        }
        if (k.contains("quaternion")) {
            const auto v = finite_numbers(file, at + ".quaternion", k["quaternion"], 4, "[w, x, y, z], 4 finite numbers");
            const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
            // A far-from-unit quaternion is a typing error, not a rotation with a scale.
            if (!(std::abs(norm - 1.0) <= 1e-3))
                fail(file, "'" + at + ".quaternion' " + k["quaternion"].dump() + " has norm " + json(norm).dump() +
                               ", not 1 (a rotation is a unit quaternion [w, x, y, z])");
            key.value.rotate = glm::normalize(Quat(float(v[0]), float(v[1]), float(v[2]), float(v[3])));
        }
        track.keys.push_back(key);
    }
    return track;
}

// The camera's "keys": look-at poses or camera-to-world matrices.
CameraTrack parse_camera_keys(const std::string& file, const json& keys) {
    const std::string where = "camera.keys";
    check_key_list(file, where, keys);
    CameraTrack track;
    for (size_t i = 0; i < keys.size(); ++i) {
        const std::string at = where + "[" + std::to_string(i) + "]";
        const json& k = keys[i];
        check_keys(file, at, k, {"frame", "position", "target", "up", "matrix"});
        CameraKey key;
        key.frame = key_frame(file, at, k);
        if (k.contains("matrix")) {
            if (k.contains("position") || k.contains("target") || k.contains("up"))
                fail(file, "'" + at + "': 'matrix' cannot be combined with position, target or up");
            const auto v = finite_numbers(file, at + ".matrix", k["matrix"], 16, "16 finite numbers (row-major)");
            glm::dmat3 r;
            for (int row = 0; row < 3; ++row)
                for (int col = 0; col < 3; ++col) r[col][row] = v[size_t(4 * row + col)];
            if (v[12] != 0.0 || v[13] != 0.0 || v[14] != 0.0 || v[15] != 1.0)
                fail(file, "'" + at + ".matrix' must end in the row 0 0 0 1");
            const glm::dmat3 e = glm::transpose(r) * r;
            double off = 0.0;
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) off = std::max(off, std::abs(e[a][b] - (a == b ? 1.0 : 0.0)));
            if (off > 1e-3 || glm::determinant(r) < 0.0)
                fail(file, "'" + at + ".matrix' must be a rotation (orthonormal columns right, up, backwards, "
                               "determinant 1) and a translation");
            key.pose.position = Vec3(float(v[3]), float(v[7]), float(v[11]));
            key.pose.orientation = glm::normalize(Quat(glm::quat_cast(glm::mat3(r))));
        } else {
            if (!k.contains("position") || !k.contains("target"))
                fail(file, "'" + at + "' needs 'position' and 'target' (and optionally 'up'), or a 'matrix'");
            const auto p = finite_numbers(file, at + ".position", k["position"], 3, "an array of 3 finite numbers");
            const auto t = finite_numbers(file, at + ".target", k["target"], 3, "an array of 3 finite numbers");
            Vec3 up(0.f, 1.f, 0.f);
            if (k.contains("up")) {
                const auto u = finite_numbers(file, at + ".up", k["up"], 3, "an array of 3 finite numbers");
                up = Vec3(float(u[0]), float(u[1]), float(u[2]));
            }
            try {
                key.pose = CameraPose::look_at(Vec3(float(p[0]), float(p[1]), float(p[2])),
                                               Vec3(float(t[0]), float(t[1]), float(t[2])), up);
            } catch (const Error& e) {
                fail(file, "'" + at + "': " + e.what());
            }
        }
        track.keys.push_back(key);
    }
    return track;
}

// The scene file's "animation": its frame range and rate.
AnimationRange parse_animation(const std::string& file, const json& j) {
    check_keys(file, "animation", j, {"first", "last", "fps"});
    AnimationRange r;
    const auto frame = [&](const char* key) {
        if (!j.contains(key)) fail(file, std::string("'animation' needs '") + key + "'");
        const json& v = j[key];
        if (!v.is_number_integer() || v.get<long long>() < -(1LL << 30) || v.get<long long>() > (1LL << 30))
            fail(file, std::string("'animation.") + key + "' must be an integer frame number, got " + v.dump());
        return int(v.get<long long>());
    };
    r.first = frame("first"), r.last = frame("last");
    if (r.last < r.first)
        fail(file, "'animation.last' (" + std::to_string(r.last) + ") comes before 'animation.first' (" +
                       std::to_string(r.first) + ")");
    if (j.contains("fps")) {
        r.fps = get_number(file, j["fps"], "animation.fps");
        if (!(r.fps > 0.0) || !std::isfinite(r.fps)) fail(file, "'animation.fps' must be positive");
    }
    return r;
}

// The scene file's "environment": a constant radiance or a lat-long EXR map
// (environment.h), with a scale and, for a map, a rotation.
std::shared_ptr<Environment> parse_environment(const std::string& file, const json& j,
                                               std::vector<std::string>& inputs) {
    check_keys(file, "environment", j, {"type", "radiance", "file", "scale", "transform"});
    if (!j.contains("type") || !j["type"].is_string()) fail(file, "'environment.type' must be \"constant\" or \"envmap\"");
    const std::string type = j["type"].get<std::string>();
    const float scale = j.contains("scale") ? get_number(file, j["scale"], "environment.scale") : 1.f;
    if (!(scale >= 0.f) || !std::isfinite(scale)) fail(file, "'environment.scale' must be finite and non-negative");
    if (type == "constant") {
        check_keys(file, "environment (constant)", j, {"type", "radiance", "scale"});
        if (!j.contains("radiance")) fail(file, "a constant environment needs 'environment.radiance'");
        const Color l = get_vec3(file, j["radiance"], "environment.radiance") * scale;
        if (!is_finite(l) || l.r < 0.f || l.g < 0.f || l.b < 0.f)
            fail(file, "'environment.radiance' must be finite and non-negative");
        return Environment::constant(l);
    }
    if (type != "envmap") fail(file, "'environment.type' must be \"constant\" or \"envmap\", got '" + type + "'");
    check_keys(file, "environment (envmap)", j, {"type", "file", "scale", "transform"});
    if (!j.contains("file") || !j["file"].is_string()) fail(file, "an envmap environment needs 'environment.file'");
    const std::string map = resolve_path(file, j["file"].get<std::string>(), "environment.file");
    const Mat4 xf = j.contains("transform") ? parse_transform(file, j["transform"]) : Mat4(1.f);
    inputs.push_back(map);
    try {
        return Environment::from_map(read_exr_rgb(map), glm::mat3(xf), scale, map);
    } catch (const InputError& e) {
        fail(file, std::string("environment: ") + e.what());
    }
}

// The scene file's "lights": delta lights (delta_light.h). A point or spot
// light gives its radiant intensity in W/sr ("intensity"), a directional
// light its irradiance on a perpendicular surface in W/m^2 ("irradiance");
// a spot's angles are in degrees, from its axis.
std::vector<DeltaLight> parse_lights(const std::string& file, const json& j) {
    if (!j.is_array()) fail(file, "'lights' must be an array");
    std::vector<DeltaLight> out;
    for (size_t i = 0; i < j.size(); ++i) {
        const json& e = j[i];
        const std::string where = "lights[" + std::to_string(i) + "]";
        if (!e.is_object() || !e.contains("type") || !e["type"].is_string())
            fail(file, "'" + where + ".type' must be \"point\", \"spot\" or \"directional\"");
        const std::string type = e["type"].get<std::string>();
        DeltaLight l;
        const auto colour = [&](const char* key) {
            if (!e.contains(key)) fail(file, "'" + where + "' (" + type + ") needs '" + key + "'");
            const Color c = get_vec3(file, e[key], where + "." + key);
            if (!is_finite(c) || c.r < 0.f || c.g < 0.f || c.b < 0.f)
                fail(file, "'" + where + "." + key + "' must be finite and non-negative");
            return c;
        };
        if (type == "point") {
            check_keys(file, where + " (point)", e, {"type", "position", "intensity"});
            l.kind = DeltaLight::Kind::Point;
            if (!e.contains("position")) fail(file, "'" + where + "' (point) needs 'position'");
            l.position = get_vec3(file, e["position"], where + ".position");
            l.intensity = colour("intensity");
        } else if (type == "spot") {
            check_keys(file, where + " (spot)", e,
                       {"type", "position", "target", "direction", "intensity", "cutoff_angle", "beam_width"});
            l.kind = DeltaLight::Kind::Spot;
            if (!e.contains("position")) fail(file, "'" + where + "' (spot) needs 'position'");
            l.position = get_vec3(file, e["position"], where + ".position");
            if (e.contains("target") == e.contains("direction"))
                fail(file, "'" + where + "' (spot) needs exactly one of 'target' and 'direction'");
            l.direction = e.contains("target") ? get_vec3(file, e["target"], where + ".target") - l.position
                                               : get_vec3(file, e["direction"], where + ".direction");
            l.intensity = colour("intensity");
            const float cutoff = e.contains("cutoff_angle") ? get_number(file, e["cutoff_angle"], where + ".cutoff_angle") : 20.f;
            const float beam = e.contains("beam_width") ? get_number(file, e["beam_width"], where + ".beam_width") : 0.75f * cutoff;
            if (!(cutoff > 0.f && cutoff <= 180.f)) fail(file, "'" + where + ".cutoff_angle' must be in (0, 180] degrees");
            if (!(beam > 0.f && beam <= cutoff)) fail(file, "'" + where + ".beam_width' must be in (0, cutoff_angle] degrees");
            l.cutoff = glm::radians(cutoff), l.beam_width = glm::radians(beam);
        } else if (type == "directional") {
            check_keys(file, where + " (directional)", e, {"type", "direction", "irradiance"});
            l.kind = DeltaLight::Kind::Directional;
            if (!e.contains("direction")) fail(file, "'" + where + "' (directional) needs 'direction' (where light travels)");
            l.direction = get_vec3(file, e["direction"], where + ".direction");
            l.intensity = colour("irradiance");
        } else {
            fail(file, "'" + where + ".type' must be \"point\", \"spot\" or \"directional\", got '" + type + "'");
        }
        if (l.kind != DeltaLight::Kind::Point && !(glm::length(l.direction) > 0.f))
            fail(file, "'" + where + "': the direction must not be zero");
        out.push_back(l);
    }
    return out;
}

// Overrides of a material from the scene file, applied to the MTL description.
struct Override {
    std::string type = "auto";
    json fields;
};

MaterialDesc apply_override(const std::string& file, MaterialDesc m, const Override& o) {
    const json& j = o.fields;
    const std::string where = "materials." + m.name;
    check_keys(file, where, j,
               {"type", "kd", "ks", "ke", "alpha", "ns", "eta", "metal", "map_kd", "conductor_eta", "conductor_k"});
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
    if (j.contains("conductor_eta") != j.contains("conductor_k"))
        fail(file, "'" + where + "': give both 'conductor_eta' and 'conductor_k' (a conductor's complex index of refraction)");
    if (j.contains("conductor_eta")) {
        // The exact Fresnel term replaces Ks as the reflectance, which becomes a tint (1 unless given here).
        ConductorIor ior{get_vec3(file, j["conductor_eta"], where + ".conductor_eta"),
                         get_vec3(file, j["conductor_k"], where + ".conductor_k")};
        try {
            check_conductor_ior(ior, "'" + where + "'");
        } catch (const ParameterError& e) {
            fail(file, e.what());
        }
        m.conductor_ior = ior, m.metal = j.contains("metal") ? m.metal : true;
        if (!j.contains("ks")) m.ks = Color(1.f);
    }
    if (j.contains("map_kd")) {
        const std::string t = get_string(file, j["map_kd"], where + ".map_kd");
        m.map_kd = t.empty() ? "" : resolve_path(file, t, where + ".map_kd");
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

// A material library for an OBJ that names none, made of the scene file's
// overrides: every `usemtl` name of `obj` (its text) that `overrides` holds
// starts as grey diffuse (Kd 0.5, as a face without a material) and then takes
// the override's keys. "" if the OBJ uses none of them. This lets a first
// scene be one OBJ and one scene file, without an MTL written beside it.
std::string library_of_overrides(const std::string& obj, const std::map<std::string, Override>& overrides) {
    std::string lib;
    std::set<std::string> named;
    std::istringstream in(obj);
    for (std::string line; std::getline(in, line);) {
        const size_t b = line.find_first_not_of(" \t");
        if (b == std::string::npos || line.compare(b, 6, "usemtl") != 0 || b + 6 >= line.size() ||
            (line[b + 6] != ' ' && line[b + 6] != '\t'))
            continue;
        const size_t s = line.find_first_not_of(" \t", b + 6);
        const size_t e = line.find_last_not_of(" \t\r");
        if (s == std::string::npos || e < s) continue;
        const std::string name = line.substr(s, e - s + 1);
        if (overrides.count(name) && named.insert(name).second) lib += "newmtl " + name + "\nKd 0.5 0.5 0.5\nillum 2\n";
    }
    return lib;
}

}  // namespace

// What editing a loaded scene in place needs (SceneFile::edit).
struct SceneEditState {
    // One material the scene file's `materials` overrides: Scene material
    // `index`, described by `base` before the override.
    struct MaterialRecord {
        uint32_t index;
        MaterialDesc base;
    };
    std::map<std::string, std::vector<MaterialRecord>> materials;  // by the overriding name
    // A mesh entry's triangles before its transform, as read (OBJ order,
    // before a mirroring transform's swap of corners): 3 corners per triangle.
    struct Object {
        std::vector<Vec3> positions;
        std::vector<Vec3> normals;         // vertex normals as read, where has_normals
        std::vector<uint8_t> has_normals;  // per triangle: the file gave vertex normals (else the face normal)
        Mat4 transform{1.f};               // the transform it is placed with now
    };
    std::vector<Object> objects;
};

namespace {

// World-space corners and raw vertex normals of object `o` under transform
// `xf`, triangle for triangle as load_obj_impl and load_inline_mesh place them
// (the same operations, so the same bits).
void place_object(const SceneEditState::Object& o, const Mat4& xf, std::vector<Vec3>& positions, std::vector<Vec3>& normals) {
    const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(xf)));
    const bool flip = glm::determinant(glm::mat3(xf)) < 0.f;
    positions.resize(o.positions.size());
    normals.resize(o.positions.size());
    for (size_t t = 0; 3 * t < o.positions.size(); ++t) {
        Vec3 p[3], n[3];
        for (int k = 0; k < 3; ++k) {
            p[k] = Vec3(xf * Vec4(o.positions[3 * t + k], 1.f));
            if (o.has_normals[t]) n[k] = nxf * o.normals[3 * t + k];
        }
        if (flip) std::swap(p[1], p[2]), std::swap(n[1], n[2]);
        if (!o.has_normals[t]) n[0] = n[1] = n[2] = glm::cross(p[1] - p[0], p[2] - p[0]);
        for (int k = 0; k < 3; ++k) positions[3 * t + k] = p[k], normals[3 * t + k] = n[k];
    }
}

// A mesh given by its arrays (meshes[i] = {"vertices": [[x, y, z], ...], "triangles":
// [[i, j, k], ...] (0-based), "material": NAME of a `materials` entry, which then
// defines it from scratch, "transform"}), as the OBJ reader stores one: flat faces, no
// texture coordinates, winding reversed under a mirroring transform.
void load_inline_mesh(const std::string& file, const std::string& where, const json& m, const Mat4& xf,
                      const std::map<std::string, Override>& overrides, std::set<std::string>& used,
                      TriangleMesh& mesh, std::vector<Material>& materials, SceneEditState* edit) {
    const json& v = m["vertices"];
    if (!v.is_array() || v.empty()) fail(file, "'" + where + ".vertices' must be a non-empty array of [x, y, z]");
    std::vector<Vec3> vs, local;
    for (size_t i = 0; i < v.size(); ++i) {
        const std::string at = where + ".vertices[" + std::to_string(i) + "]";
        const std::vector<double> x = finite_numbers(file, at, v[i], 3, "[x, y, z]");
        local.push_back(Vec3(float(x[0]), float(x[1]), float(x[2])));
        vs.push_back(Vec3(xf * Vec4(local.back(), 1.f)));
    }
    if (!m.contains("triangles") || !m["triangles"].is_array() || m["triangles"].empty())
        fail(file, "'" + where + ".triangles' must be a non-empty array of [i, j, k] (0-based vertex indices)");
    uint32_t id;
    if (m.contains("material")) {
        const std::string name = get_string(file, m["material"], where + ".material");
        const auto it = overrides.find(name);
        if (it == overrides.end())
            fail(file, "'" + where + ".material' names '" + name + "', which 'materials' does not define");
        used.insert(name);
        MaterialDesc d;
        d.name = name;
        if (edit) edit->materials[name].push_back({uint32_t(materials.size()), d});
        d = apply_override(file, d, it->second);
        Material mat;
        mat.name = name;
        mat.emission = d.ke;
        try {
            check_material_colours(d);
            read_material_textures(d);
            mat.bsdf = it->second.type == "auto" ? bsdf_from_mtl(d) : bsdf_from_desc(d, it->second.type);
        } catch (const Error& e) {
            fail(file, "materials." + name + ": " + e.what());
        }
        id = uint32_t(materials.size());
        materials.push_back(std::move(mat));
    } else {
        id = uint32_t(materials.size());
        materials.push_back(Material{"(default)", make_lambertian(make_constant_texture(Color(0.5f))), Color(0.f)});
    }
    const bool flip = glm::determinant(glm::mat3(xf)) < 0.f;
    const json& t = m["triangles"];
    for (size_t f = 0; f < t.size(); ++f) {
        const std::string at = where + ".triangles[" + std::to_string(f) + "]";
        if (!t[f].is_array() || t[f].size() != 3) fail(file, "'" + at + "' must be [i, j, k]");
        Vec3 p[3];
        for (int k = 0; k < 3; ++k) {
            const json& x = t[f][k];
            if (!x.is_number_integer() || x.get<long long>() < 0 || x.get<long long>() >= (long long)vs.size())
                fail(file, "'" + at + "' holds " + x.dump() + ", not a vertex index in [0, " +
                           std::to_string(vs.size() - 1) + "]");
            p[k] = vs[size_t(x.get<long long>())];
            if (edit) edit->objects.back().positions.push_back(local[size_t(x.get<long long>())]);
        }
        if (edit) {
            edit->objects.back().normals.resize(edit->objects.back().positions.size());
            edit->objects.back().has_normals.push_back(0);
        }
        if (flip) std::swap(p[1], p[2]);
        const Vec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
        for (int k = 0; k < 3; ++k) {
            mesh.positions.push_back(p[k]);
            mesh.normals.push_back(n);
            mesh.uvs.push_back(Vec2(0.f));
        }
        mesh.material_ids.push_back(id);
    }
}

}  // namespace

// `mtl`: a material library read instead of the OBJ's own `mtllib` ("" = the
// OBJ's own); its textures are then relative to it. The files read are
// appended to `inputs` (if given).
void load_obj_impl(const std::string& path, const Mat4& xf, TriangleMesh& mesh, std::vector<Material>& materials,
                   const std::map<std::string, Override>* overrides, const std::string& scene_file,
                   std::set<std::string>* used_overrides, const std::string& mtl = "",
                   std::vector<std::string>* inputs = nullptr, SceneEditState* edit = nullptr) {
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
    for (const std::string& lib : mtl.empty() ? libraries : std::vector<std::string>{mtl}) {
        // The reader would open a FIFO or device itself and block, or read /dev/zero until memory runs out.
        std::error_code ec;
        if (fs::exists(lib, ec))
            if (const std::string why = not_a_file(lib); !why.empty()) throw InputError(path + ": mtllib " + lib + why);
        check_material_lines(lib);
    }
    // An OBJ without a library of its own takes its materials from the scene file's overrides.
    const std::string from_overrides =
        mtl.empty() && libraries.empty() && overrides ? library_of_overrides(read_file_text(path), *overrides) : "";
    // With a library of its own the OBJ is parsed from memory: tinyobjloader
    // then reads every `mtllib` from the given text instead of a file.
    bool parsed;
    if (mtl.empty() && from_overrides.empty()) {
        parsed = reader.ParseFromFile(path, cfg);
    } else {
        std::string obj = read_file_text(path);
        if (obj.find("mtllib") == std::string::npos) obj = "mtllib given\n" + obj;  // an OBJ without one gets it too
        parsed = reader.ParseFromString(obj, from_overrides.empty() ? read_file_text(mtl) : from_overrides, cfg);
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
        throw InputError(path + ": " + warn.substr(0, warn.find('\n')) +
                         (mtl.empty() && libraries.empty()
                              ? " (the OBJ names no material library: give each material it uses in the scene "
                                "file's \"materials\", or a library in the mesh's \"mtl\")"
                              : ""));
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
                if (edit) edit->materials[mt.name].push_back({uint32_t(materials.size()), d});
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
            read_material_textures(d);
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
                if (!within_coordinate_range(p[k]))  // Embree would refuse rays from it (see kMaxCoordinate)
                    throw InputError(fmt::format("{}{}: vertex {} lies at ({}, {}, {}) after the transform, beyond "
                                                 "+-{:g} on an axis", scene_file.empty() ? "" : scene_file + ": meshes[] ",
                                                 path, vi + 1, p[k].x, p[k].y, p[k].z, kMaxCoordinate));
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
            if (edit) {
                SceneEditState::Object& o = edit->objects.back();
                for (int k = 0; k < 3; ++k) {
                    const int vi = c[k].vertex_index;
                    o.positions.push_back(Vec3(attrib.vertices[3 * vi], attrib.vertices[3 * vi + 1], attrib.vertices[3 * vi + 2]));
                    const int ni = c[k].normal_index;
                    o.normals.push_back(has_n ? Vec3(attrib.normals[3 * ni], attrib.normals[3 * ni + 1], attrib.normals[3 * ni + 2])
                                              : Vec3(0.f));
                }
                o.has_normals.push_back(has_n ? 1 : 0);
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

std::string scenes_dir() {
    if (const char* e = std::getenv("GDR_SCENES"); e && *e) return e;
    return GDR_SCENES_DEFAULT;
}

void load_obj(const std::string& path, const Mat4& transform, TriangleMesh& mesh, std::vector<Material>& materials) {
    load_obj_impl(path, transform, mesh, materials, nullptr, "", nullptr);
}

static SceneFile load_scene_file_impl(const std::string& path, bool editable);
static SceneFile load_scene_json(json j, const std::string& path, const fs::path& dir, bool is_file, bool editable);

// Mitsuba XML: by the name, or by a first character no JSON file starts with.
static bool is_mitsuba_xml(const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".xml") return true;
    std::ifstream in(path, std::ios::binary);
    char c = 0;
    while (in.get(c))
        if (!std::isspace(static_cast<unsigned char>(c))) return c == '<';
    return false;
}

SceneFile load_scene_file(const std::string& path, const SceneFileOptions& options) {
    // Before the format sniffing below opens it: a FIFO would block it.
    if (const std::string why = not_a_file(path); !why.empty()) throw InputError(path + why);
    std::error_code ec;
    if (!fs::is_directory(path, ec) && is_mitsuba_xml(path)) return load_mitsuba_scene(path, options);
    if (!options.defines.empty())
        throw InputError(path + ": -D " + options.defines.begin()->first +
                         "=...: parameters apply to Mitsuba XML scenes only, not to JSON scene files");
    try {
        return load_scene_file_impl(path, options.editable);
    } catch (const json::exception& e) {
        throw InputError(path + ": " + e.what());
    }
}

SceneFile load_scene_file(const std::string& path) {
    std::error_code ec;
    if (!fs::is_directory(path, ec) && is_mitsuba_xml(path)) return load_mitsuba_scene(path, {});
    try {
        return load_scene_file_impl(path, false);
    } catch (const json::exception& e) {
        // Type errors (a string where a number belongs) surface here.
        throw InputError(path + ": " + e.what());
    }
}

static SceneFile load_scene_file_impl(const std::string& path, bool editable) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
        std::string hint;
        if (fs::is_regular_file(fs::path(path) / "scene.json", ec))
            hint = " (did you mean " + (fs::path(path) / "scene.json").string() + "?)";
        throw InputError(path + ": is a directory, not a scene file" + hint);
    }
    return load_scene_json(parse_json_file(path), path, fs::path(path).parent_path(), true, editable);
}

// A scene from its JSON value: `path` names it in messages and in SceneFile::path,
// relative files are found in `dir`; `is_file`: `path` is a file, hashed first of its inputs.
// The content_hash of a scene described by `j` that is no file and read `inputs`:
// its JSON text stands first, then the files it read.
static std::string description_hash(const json& j, const std::string& path, const std::vector<std::string>& inputs) {
    uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a 64, as scene_content_hash
    for (const std::string& part : {j.dump(), scene_content_hash(path, inputs)})
        for (unsigned char b : part + '\0') h = (h ^ b) * 0x100000001b3ull;
    return fmt::format("{:016x}", h);
}

static SceneFile load_scene_json(json j, const std::string& path, const fs::path& dir, bool is_file, bool editable) {
    check_keys(path, "the scene", j,
               {"camera", "meshes", "materials", "render", "description", "environment", "lights", "animation"});
    if (!j.contains("camera")) fail(path, "missing 'camera'");
    if (!j.contains("meshes") || !j["meshes"].is_array() || j["meshes"].empty())
        fail(path, "'meshes' must be a non-empty array");

    SceneFile sf;
    sf.path = path;
    std::vector<std::string> inputs;
    if (is_file) inputs.push_back(path);
    // Keyframes (animation.h) come apart from the camera's fixed description.
    std::optional<AnimationRange> range;
    if (j.contains("animation")) range = parse_animation(path, j["animation"]);
    json camera_json = j["camera"];
    CameraTrack camera_track;
    if (camera_json.is_object() && camera_json.contains("keys")) {
        // The keys set the pose; a pose beside them would be silently ignored.
        for (const char* k : {"position", "target", "up"})
            if (camera_json.contains(k))
                fail(path, std::string("'camera.") + k + "' is ignored when 'camera.keys' give the pose; remove it or "
                           "put it into the keys");
        camera_track = parse_camera_keys(path, camera_json["keys"]);
        camera_json.erase("keys");
    }
    const CameraDesc cd = parse_camera(path, camera_json, inputs);
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
    auto edit = editable ? std::make_shared<SceneEditState>() : nullptr;
    std::vector<TransformTrack> tracks;
    bool any_keys = !camera_track.empty();
    for (const auto& m : j["meshes"]) {
        const size_t first = mesh.size();
        const std::string where = "meshes[" + std::to_string(tracks.size()) + "]";
        std::string file;
        if (edit) edit->objects.emplace_back();
        if (m.is_string()) {
            file = resolve_path(path, m.get<std::string>(), where);
            load_obj_impl(file, Mat4(1.f), mesh, materials, &overrides, path, &used, "", &inputs, edit.get());
        } else if (m.is_object() && m.contains("vertices")) {
            check_keys(path, where, m, {"vertices", "triangles", "material", "transform"});
            const Mat4 xf = m.contains("transform") ? parse_transform(path, m["transform"]) : Mat4(1.f);
            file = where;
            if (edit) edit->objects.back().transform = xf;
            load_inline_mesh(path, where, m, xf, overrides, used, mesh, materials, edit.get());
        } else {
            check_keys(path, "meshes[]", m, {"file", "transform", "mtl", "keys"});
            if (m.contains("keys")) {
                tracks.push_back(parse_object_keys(path, where + ".keys", m["keys"]));
                any_keys = true;
            }
            if (!m.contains("file") || !m["file"].is_string()) fail(path, "every mesh needs a 'file'");
            if (m.contains("mtl") && !m["mtl"].is_string()) fail(path, "'meshes[].mtl' must be a string");
            const Mat4 xf = m.contains("transform") ? parse_transform(path, m["transform"]) : Mat4(1.f);
            const std::string mtl = m.contains("mtl") ? resolve_path(path, m["mtl"].get<std::string>(), where + ".mtl")
                                                      : std::string();
            file = resolve_path(path, m["file"].get<std::string>(), where + ".file");
            if (edit) edit->objects.back().transform = xf;
            load_obj_impl(file, xf, mesh, materials, &overrides, path, &used, mtl, &inputs, edit.get());
        }
        if (tracks.size() == sf.meshes.size()) tracks.emplace_back();
        mesh.object_ids.resize(mesh.size(), uint32_t(sf.meshes.size()));
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
    std::shared_ptr<Environment> env;
    if (j.contains("environment")) env = parse_environment(path, j["environment"], inputs);
    std::vector<DeltaLight> lights;
    if (j.contains("lights")) lights = parse_lights(path, j["lights"]);
    if (any_keys && !range)
        fail(path, "the scene has keys but no 'animation' block giving its frames ({\"first\": 0, \"last\": 47, "
                   "\"fps\": 24})");
    if (range) {
        // Every entry becomes an object of its own, with its motion.
        std::vector<AnimatedObject> objects;
        size_t t0 = 0;
        for (size_t i = 0; i < sf.meshes.size(); ++i) {
            AnimatedObject o;
            o.name = sf.meshes[i].file;
            o.track = std::move(tracks[i]);
            const size_t n = sf.meshes[i].triangles;
            o.mesh.positions.assign(mesh.positions.begin() + 3 * t0, mesh.positions.begin() + 3 * (t0 + n));
            o.mesh.normals.assign(mesh.normals.begin() + 3 * t0, mesh.normals.begin() + 3 * (t0 + n));
            o.mesh.uvs.assign(mesh.uvs.begin() + 3 * t0, mesh.uvs.begin() + 3 * (t0 + n));
            o.mesh.material_ids.assign(mesh.material_ids.begin() + t0, mesh.material_ids.begin() + (t0 + n));
            objects.push_back(std::move(o));
            t0 += n;
        }
        sf.animation = std::make_shared<AnimatedScene>(std::move(objects), std::move(materials), cd,
                                                       std::move(camera_track), env, *range, path);
        if (!lights.empty()) sf.animation->set_delta_lights(std::move(lights));
        sf.scene = sf.animation->scene_at(range->first);
        sf.frame = range->first;
    } else {
        sf.scene = std::make_unique<Scene>(std::move(mesh), std::move(materials), camera, path);
        sf.edit = std::move(edit);  // an animation's frames are rebuilt from its objects: not editable in place
        if (env) sf.scene->set_environment(std::move(env));
        if (!lights.empty()) sf.scene->set_delta_lights(std::move(lights), path);
    }
    // A file used twice (one OBJ under two transforms, a shared texture) is hashed once.
    std::set<std::string> seen;
    for (std::string& f : inputs)
        if (seen.insert(f).second) sf.inputs.push_back(std::move(f));
    if (is_file) {
        sf.content_hash = scene_content_hash(path, sf.inputs);
    } else {
        sf.content_hash = description_hash(j, path, sf.inputs);
    }
    return sf;
}

SceneFile load_scene_text(const std::string& text, const std::string& name, bool editable) {
    try {
        return load_scene_json(parse_json_text(name, text), name, fs::path(name).parent_path(), false, editable);
    } catch (const json::exception& e) {
        throw InputError(name + ": " + e.what());
    }
}

std::string scene_text_hash(const std::string& text, const std::string& name, const std::vector<std::string>& inputs) {
    return description_hash(parse_json_text(name, text), name, inputs);
}

// The edit state of `sf`; ParameterError naming `what` where it has none.
static SceneEditState& edit_state(SceneFile& sf, const std::string& what) {
    if (!sf.scene) throw ParameterError(what + ": no scene is loaded");
    if (sf.animation) throw ParameterError(sf.path + ": " + what + ": an animated scene is edited in its file (its frames are built from it)");
    if (!sf.edit) throw ParameterError(sf.path + ": " + what + ": the scene was not loaded editable (a JSON scene loaded with SceneFileOptions::editable)");
    return *sf.edit;
}

// `text` parsed as the JSON value of key `where` of an edit of `sf`;
// InputError naming the file and the key where it is not JSON.
static json parse_edit(const SceneFile& sf, const std::string& where, const std::string& text) {
    try {
        return parse_json_text(sf.path, text);
    } catch (const json::exception& e) {
        throw InputError(sf.path + ": " + where + ": " + e.what());
    }
}

// The scene-file values `fields_json` of material `name` as an Override, and the materials of that name.
static std::pair<Override, const std::vector<SceneEditState::MaterialRecord>*> material_override(
    SceneFile& sf, const std::string& name, const std::string& fields_json) {
    const std::string where = "materials." + name;
    SceneEditState& st = edit_state(sf, where);
    const auto it = st.materials.find(name);
    if (it == st.materials.end()) throw ParameterError(sf.path + ": " + where + ": the scene file overrides no material of that name");
    Override o;
    o.fields = parse_edit(sf, where, fields_json);
    if (!o.fields.is_object()) fail(sf.path, "'" + where + "' must be an object");
    if (o.fields.contains("type")) {
        if (!o.fields["type"].is_string()) fail(sf.path, where + ".type must be a string");
        o.type = o.fields["type"].get<std::string>();
    }
    return {std::move(o), &it->second};
}

MaterialDesc material_description(SceneFile& sf, const std::string& name, const std::string& fields_json) {
    const auto [o, records] = material_override(sf, name, fields_json);
    return apply_override(sf.path, records->front().base, o);
}

void edit_material(SceneFile& sf, const std::string& name, const std::string& fields_json) {
    const std::string where = "materials." + name;
    const auto [o, records] = material_override(sf, name, fields_json);
    // Every material of the name is rebuilt before any is installed: a refused value changes nothing.
    std::vector<std::pair<uint32_t, Material>> built;
    for (const SceneEditState::MaterialRecord& r : *records) {
        MaterialDesc d = apply_override(sf.path, r.base, o);
        Material m;
        m.emission = d.ke;
        try {
            check_material_colours(d);
            read_material_textures(d);
            m.bsdf = o.type == "auto" ? bsdf_from_mtl(d) : bsdf_from_desc(d, o.type);
        } catch (const Error& e) {
            // check_material_colours speaks of MTL's names: the message names the key.
            const std::string what = e.what();
            std::string key = where;
            for (const auto& [mtl, field] : {std::pair<const char*, const char*>{"Kd ", "kd"}, {"Ks ", "ks"}, {"Ke ", "ke"}})
                if (what.rfind(mtl, 0) == 0) key += std::string(".") + field;
            throw InputError(sf.path + ": '" + key + "': " + what);
        }
        built.emplace_back(r.index, std::move(m));
    }
    for (auto& [index, m] : built) sf.scene->set_material(index, std::move(m.bsdf), m.emission);
}

void edit_mesh_transform(SceneFile& sf, size_t index, const std::string& transform_json) {
    const std::string where = "meshes[" + std::to_string(index) + "].transform";
    SceneEditState& st = edit_state(sf, where);
    if (index >= st.objects.size())
        throw ParameterError(fmt::format("{}: {}: the scene has {} mesh entries", sf.path, where, st.objects.size()));
    SceneEditState::Object& o = st.objects[index];
    Mat4 xf(1.f);
    if (const json j = parse_edit(sf, where, transform_json); !j.is_null()) {
        try {
            xf = parse_transform(sf.path + ": " + where, j);
        } catch (const json::exception& e) {
            throw InputError(sf.path + ": " + where + ": " + e.what());
        }
    }
    if ((glm::determinant(glm::mat3(xf)) < 0.f) != (glm::determinant(glm::mat3(o.transform)) < 0.f))
        throw ParameterError(sf.path + ": " + where + ": a change between a mirroring and a non-mirroring transform "
                             "reorders the triangles' corners; load the edited scene instead");
    std::vector<Vec3> now_p, now_n, new_p, new_n;
    place_object(o, o.transform, now_p, now_n);
    place_object(o, xf, new_p, new_n);
    // Loading drops zero-area triangles: the edit must keep the same ones.
    std::vector<Vec3> kept_p, kept_n;
    for (size_t t = 0; 3 * t < new_p.size(); ++t) {
        const bool was = zero_area_triangle(now_p[3 * t], now_p[3 * t + 1], now_p[3 * t + 2]);
        const bool is = zero_area_triangle(new_p[3 * t], new_p[3 * t + 1], new_p[3 * t + 2]);
        if (was != is)
            throw ParameterError(fmt::format("{}: {}: the transform makes triangle {} of the mesh {}; load the edited "
                                             "scene instead", sf.path, where, t, is ? "zero-area (it would be dropped)"
                                                                                   : "non-degenerate (it was dropped)"));
        if (is) continue;
        for (int k = 0; k < 3; ++k) kept_p.push_back(new_p[3 * t + k]), kept_n.push_back(new_n[3 * t + k]);
    }
    try {
        sf.scene->set_object_geometry(uint32_t(index), kept_p, sf.scene->mesh().normals.empty() ? std::vector<Vec3>{} : kept_n);
    } catch (const ParameterError& e) {
        throw ParameterError(sf.path + ": " + where + ": " + e.what());
    }
    o.transform = xf;
}

void edit_environment(SceneFile& sf, const std::string& environment_json) {
    edit_state(sf, "environment");
    std::vector<std::string> inputs;  // the files it reads are among the scene's already
    const json j = parse_edit(sf, "environment", environment_json);
    sf.scene->set_environment(j.is_null() ? nullptr : parse_environment(sf.path, j, inputs));
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
    if (sf.animation) sf.animation->set_camera_optics(d);  // every later frame too
}

void set_frame(SceneFile& sf, int frame) {
    if (!sf.scene) throw ParameterError("set_frame: no scene is loaded");
    if (!sf.animation)
        throw InputError(sf.path + ": has no 'animation' block, so it has no frame " + std::to_string(frame));
    const AnimationRange& r = sf.animation->range();
    if (frame < r.first || frame > r.last)
        throw ParameterError(fmt::format("frame {} is outside the animation of {} (frames {} to {})", frame, sf.path,
                                         r.first, r.last));
    // The optics chosen after loading (--resolution, --set fov) carry over.
    sf.animation->set_camera_optics(sf.scene->camera().desc());
    sf.scene = sf.animation->scene_at(frame);
    sf.frame = frame;
}

void set_fov(SceneFile& sf, float fov_deg, char axis) {
    if (!sf.scene) throw ParameterError("set_fov: no scene is loaded");
    if (axis != 0 && axis != 'x' && axis != 'y')
        throw ParameterError(std::string("fov axis '") + axis + "' must be 'x' (horizontal) or 'y' (vertical)");
    CameraDesc d = sf.scene->camera().desc();
    d.fov_deg = fov_deg;
    if (axis) d.fov_axis = axis;
    sf.scene->set_camera(Camera(d));  // rejects an angle outside (0, 180)
    if (sf.animation) sf.animation->set_camera_optics(d);  // every later frame too
}

}  // namespace gdr
