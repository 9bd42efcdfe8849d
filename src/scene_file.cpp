#include "gdr/io/scene_file.h"

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
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
        fail(file, "'" + key + "' must be an integer");
    const double v = j.get<double>();
    if (v < double(min) || v > 9.0e15) fail(file, "'" + key + "' must be an integer >= " + std::to_string(min));
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

CameraDesc parse_camera(const std::string& file, const json& j) {
    CameraDesc c;
    json src = j;
    if (j.contains("file")) {
        const fs::path cam = fs::path(file).parent_path() / get_string(file, j["file"], "camera.file");
        std::ifstream in(cam);
        if (!in) fail(file, "camera file '" + cam.string() + "' not found");
        json base;
        try {
            base = json::parse(in);
        } catch (const json::exception& e) {
            fail(file, "camera file '" + cam.string() + "' is malformed JSON: " + e.what());
        }
        for (auto it = j.begin(); it != j.end(); ++it)
            if (it.key() != "file") base[it.key()] = it.value();
        src = base;
        if (src.contains("fov_deg")) src["fov"] = src["fov_deg"], src.erase("fov_deg");
        src.erase("forward"), src.erase("note");
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
    if (src.contains("width")) c.width = int(std::min(get_integer(file, src["width"], "camera.width", 1), 1LL << 20));
    if (src.contains("height")) c.height = int(std::min(get_integer(file, src["height"], "camera.height", 1), 1LL << 20));
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

// tinyobjloader reads an MTL number it cannot parse ("Kd nan 0 0", "Ns x")
// as 0 too, which would silently turn a colour black or a lobe rough; so the
// numeric lines of a material library are checked first.
void check_material_lines(const std::string& lib) {
    static const std::map<std::string, int> kNumbers = {{"Kd", 3}, {"Ks", 3}, {"Ke", 3}, {"Ka", 3}, {"Ns", 1},
                                                        {"Ni", 1}, {"Pr", 1}, {"Pm", 1}, {"d", 1},  {"Tr", 1},
                                                        {"illum", 1}};
    std::ifstream in(lib, std::ios::binary);
    if (!in) return;  // the reader reports a missing library
    std::string line;
    size_t line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        std::istringstream words(line);
        std::string key, t;
        words >> key;
        const auto it = kNumbers.find(key);
        if (it == kNumbers.end()) continue;
        for (int k = 0; k < it->second && words >> t; ++k) {
            if (t[0] == '#' || (k == 0 && (t == "spectral" || t == "xyz"))) break;  // a comment; a non-RGB colour
            if (!finite_number(t, false))
                throw InputError(lib + ": line " + std::to_string(line_no) + ": " + key + " value '" + t +
                                 "' is not a finite number");
        }
    }
}

// tinyobjloader reads a coordinate it cannot parse ("nan", "1,5", "x") as 0,
// which would silently move a vertex or tilt a normal; so the vertex,
// normal and texture-coordinate lines are checked first. Returns the material
// libraries the OBJ names (mtllib lines, relative to its directory), collected
// in the same pass, for check_material_lines().
std::vector<std::string> check_vertex_lines(const std::string& path) {
    std::vector<std::string> libraries;
    std::ifstream in(path, std::ios::binary);
    if (!in) return libraries;  // the reader reports unreadable files
    std::string line;
    size_t line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        if (line.rfind("mtllib", 0) == 0 && line.size() > 6 && (line[6] == ' ' || line[6] == '\t')) {
            std::istringstream words(line.substr(6));
            for (std::string name; words >> name;) libraries.push_back((fs::path(path).parent_path() / name).string());
            continue;
        }
        // v x y z [colour], vn x y z, vt u [v [w]]: how many numbers are checked, and how many are required.
        int start, count, required;
        const char* kind;   // what the line describes
        const char* value;  // what one of its numbers is called
        const auto blank = [&](size_t i) { return i < line.size() && (line[i] == ' ' || line[i] == '\t'); };
        if (line.size() >= 2 && line[0] == 'v' && blank(1))
            start = 1, count = 3, required = 3, kind = "vertex", value = "vertex coordinate";
        else if (line.size() >= 3 && line[0] == 'v' && line[1] == 'n' && blank(2))
            start = 2, count = 3, required = 3, kind = "normal", value = "normal component";
        else if (line.size() >= 3 && line[0] == 'v' && line[1] == 't' && blank(2))
            start = 2, count = 3, required = 1, kind = "texture coordinate line", value = "texture coordinate";
        else
            continue;
        const char* c = line.data() + start;
        const char* end = line.data() + line.size();
        for (int k = 0; k < count; ++k) {
            while (c < end && (*c == ' ' || *c == '\t')) ++c;
            if (c == end || *c == '\r' || *c == '#') {
                if (k >= required) break;
                throw InputError(path + ": line " + std::to_string(line_no) + ": a " + kind + " needs " +
                                 std::to_string(required) + (required == 1 ? " number" : " numbers"));
            }
            const char* tok = c;
            while (c < end && *c != ' ' && *c != '\t' && *c != '\r') ++c;
            const std::string t(tok, c);
            // Out-of-range values (1e39) parse to inf below; the loader reports those with the element's number.
            if (!finite_number(t, true))
                throw InputError(path + ": line " + std::to_string(line_no) + ": " + value + " '" + t +
                                 "' is not a finite number");
        }
    }
    return libraries;
}

// Why `file` cannot be read as a file (": file not found", ": not a file"), or "" if it can.
std::string not_a_file(const std::string& file) {
    if (fs::is_regular_file(file)) return "";
    return fs::exists(file) ? ": not a file" : ": file not found";
}
}  // namespace

// `mtl`: a material library read instead of the OBJ's own `mtllib` ("" = the
// OBJ's own); its textures are then relative to it.
void load_obj_impl(const std::string& path, const Mat4& xf, TriangleMesh& mesh, std::vector<Material>& materials,
                   const std::map<std::string, Override>* overrides, const std::string& scene_file,
                   std::set<std::string>* used_overrides, const std::string& mtl = "") {
    if (const std::string why = not_a_file(path); !why.empty()) throw InputError(path + why);
    const std::vector<std::string> libraries = check_vertex_lines(path);
    tinyobj::ObjReaderConfig cfg;
    cfg.triangulate = true;
    cfg.vertex_color = false;
    cfg.mtl_search_path = fs::path(path).parent_path().string();
    tinyobj::ObjReader reader;
    const auto read_text = [](const std::string& file) {
        std::ifstream in(file, std::ios::binary);
        std::string text(std::istreambuf_iterator<char>(in), {});
        if (!in && !in.eof()) throw InputError(file + ": cannot read");
        return text;
    };
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
        std::string obj = read_text(path);
        if (obj.find("mtllib") == std::string::npos) obj = "mtllib given\n" + obj;  // an OBJ without one gets it too
        parsed = reader.ParseFromString(obj, read_text(mtl), cfg);
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
    const auto& attrib = reader.GetAttrib();
    const auto& shapes = reader.GetShapes();
    const auto& mtls = reader.GetMaterials();

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
            if (sh.mesh.num_face_vertices[f] != 3) continue;  // triangulated by the reader
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
    std::ifstream in(path);
    if (!in) throw InputError(path + ": file not found");
    json j;
    try {
        j = json::parse(in);
    } catch (const json::exception& e) {
        throw InputError(path + ": malformed JSON: " + e.what());
    }
    check_keys(path, "the scene", j, {"camera", "meshes", "materials", "render", "description"});
    if (!j.contains("camera")) fail(path, "missing 'camera'");
    if (!j.contains("meshes") || !j["meshes"].is_array() || j["meshes"].empty())
        fail(path, "'meshes' must be a non-empty array");

    SceneFile sf;
    sf.path = path;
    const CameraDesc cd = parse_camera(path, j["camera"]);
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
        if (m.is_string()) {
            load_obj_impl((dir / m.get<std::string>()).string(), Mat4(1.f), mesh, materials, &overrides, path, &used);
            continue;
        }
        check_keys(path, "meshes[]", m, {"file", "transform", "mtl"});
        if (!m.contains("file") || !m["file"].is_string()) fail(path, "every mesh needs a 'file'");
        if (m.contains("mtl") && !m["mtl"].is_string()) fail(path, "'meshes[].mtl' must be a string");
        const Mat4 xf = m.contains("transform") ? parse_transform(path, m["transform"]) : Mat4(1.f);
        const std::string mtl = m.contains("mtl") ? (dir / m["mtl"].get<std::string>()).string() : std::string();
        load_obj_impl((dir / m["file"].get<std::string>()).string(), xf, mesh, materials, &overrides, path, &used, mtl);
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
    return sf;
}

}  // namespace gdr
