// The Mitsuba XML importer's state and the declarations its source files
// share: mitsuba_xml.cpp (documents, values, sensor, shapes, emitters and the
// run) and mitsuba_bsdfs.cpp (BSDFs and textures). Private to the importer.
#pragma once

#include "gdr/io/mitsuba_xml.h"


#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cmath>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <utility>

#include <fmt/core.h>
#include <glm/gtc/matrix_transform.hpp>
#include <pugixml.hpp>
#include <tiny_obj_loader.h>

#include "gdr/core/error.h"
#include "gdr/scene/coordinates.h"
#include "gdr/io/exr.h"
#include "gdr/io/mitsuba_serialized.h"
#include "gdr/io/ply.h"
#include "gdr/io/png.h"
#include "gdr/scene/microfacet.h"
#include "gdr/scene/sky.h"
#include "gdr/io/texture_files.h"
#include "gdr/scene/texture.h"
#include "mitsuba_shapes.h"
#include "obj_lines.h"

namespace gdr::mitsuba_import {


namespace fs = std::filesystem;
using pugi::xml_node;

/// Mitsuba's named conductors: their RGB complex indices of refraction.
struct NamedConductor {
    const char* name;
    Vec3 eta, k;
};
constexpr NamedConductor kConductors[] = {
#include "conductor_data/conductor_ior.inc"
    {"none", {0.f, 0.f, 0.f}, {1.f, 1.f, 1.f}},  // reflects everything: eta 0, k 1, as Mitsuba defines it
};

/// Mitsuba's named indices of refraction of dielectrics.
struct NamedIor {
    const char* name;
    float ior;
};
constexpr NamedIor kIors[] = {
    {"vacuum", 1.0f},          {"helium", 1.00004f},       {"hydrogen", 1.00013f},   {"air", 1.00028f},
    {"carbon dioxide", 1.00045f}, {"water", 1.3330f},      {"acetone", 1.36f},       {"ethanol", 1.361f},
    {"carbon tetrachloride", 1.461f}, {"glycerol", 1.4729f}, {"benzene", 1.501f},    {"silicone oil", 1.52045f},
    {"bromine", 1.661f},       {"water ice", 1.31f},       {"fused quartz", 1.458f}, {"pyrex", 1.470f},
    {"acrylic glass", 1.49f},  {"polypropylene", 1.49f},   {"bk7", 1.5046f},         {"sodium chloride", 1.544f},
    {"amber", 1.55f},          {"pet", 1.5750f},           {"diamond", 2.419f},
};

/// GGX alpha that stands in for the delta coating of Mitsuba's smooth plastic.
constexpr float kSmoothPlasticAlpha = 0.01f;
/// Largest magnitude of a value read (all are stored as float).
constexpr double kMaxFloat = std::numeric_limits<float>::max();
/// Deepest element nesting, and longest chain of nested or referenced BSDFs and
/// textures, that a scene may have. The importer recurses over both, so a
/// hostile file (32,000 nested elements) would overflow the stack; real scenes
/// nest about ten deep.
constexpr int kMaxNesting = 100;
/// Triangulation of spheres (as the shared scenes' converted OBJs) and disks.
constexpr int kSphereSegments = 64, kSphereRings = 32, kDiskSegments = 64;
/// Quads around a cylinder: its chords lie within r (1 - cos(pi / 128)) =
/// 3.0e-4 r of the true surface; its vertex normals are exact.
constexpr int kCylinderSegments = 128;

/// 0.6's camelCase names in 3.x's snake_case: toWorld -> to_world, intIOR -> int_ior.
inline std::string snake_case(const std::string& s) {
    std::string r;
    const auto up = [&](size_t i) { return i < s.size() && std::isupper(static_cast<unsigned char>(s[i])); };
    const auto low = [&](size_t i) {
        return i < s.size() && (std::islower(static_cast<unsigned char>(s[i])) || std::isdigit(static_cast<unsigned char>(s[i])));
    };
    for (size_t i = 0; i < s.size(); ++i) {
        if (up(i)) {
            if (i > 0 && (low(i - 1) || (up(i - 1) && low(i + 1)))) r += '_';
            r += char(std::tolower(static_cast<unsigned char>(s[i])));
        } else {
            r += s[i];
        }
    }
    return r;
}

/// One file of XML: the scene's or an included one.
struct Doc {
    std::string file, dir;
    std::vector<size_t> line_starts;  // byte offset of each line
    pugi::xml_document xml;
};

/// A BSDF element as built: its BSDF, the mask that cuts holes in it, and the
/// material of it once a shape used it.
struct BuiltBsdf {
    std::shared_ptr<Bsdf> bsdf;
    std::shared_ptr<Texture> opacity;
    std::shared_ptr<Texture> bump;        // Material::bump
    std::shared_ptr<Texture> normal_map;  // Material::normal_map
    std::string name;
    int material = -1;
};

/// The children of a plugin element: properties by (snake_case) name, and
/// unnamed nested objects, with a record of which ones were read.
struct Props {
    xml_node owner;
    std::map<std::string, xml_node> named;
    std::vector<xml_node> objects;
    std::set<const void*> used;
};

class Importer {
public:
    Importer(const std::string& path, const SceneFileOptions& options) : path_(path), opt_(options) {}

    SceneFile run();

private:
    // ---- locations, errors, warnings
    const Doc& doc_of(xml_node n) const {
        const xml_node root = n.root();
        for (const Doc& d : docs_)
            if (root == d.xml) return d;
        return docs_.front();
    }
    int line_of(xml_node n) const {
        const Doc& d = doc_of(n);
        const ptrdiff_t off = n.offset_debug();
        if (off < 0) return 0;
        return int(std::upper_bound(d.line_starts.begin(), d.line_starts.end(), size_t(off)) - d.line_starts.begin());
    }
    std::string raw(xml_node n, const char* a) const { return n.attribute(a).value(); }
    // <tag type="t" id="i" name="n">, naming the id (or its absence) of plugin elements.
    std::string describe(xml_node n) const {
        std::string s = std::string("<") + n.name();
        for (const char* a : {"type", "id", "name"})
            if (n.attribute(a)) s += fmt::format(" {}=\"{}\"", a, raw(n, a));
        s += ">";
        if (n.attribute("type") && !n.attribute("id")) s += " (no id)";
        return s;
    }
    std::string where(xml_node n) const {
        std::string s = fmt::format("{}:{}: {}", doc_of(n).file, line_of(n), describe(n));
        const xml_node p = n.parent();
        if (p && p.type() == pugi::node_element && std::string(p.name()) != "scene" &&
            (n.attribute("name") || !n.attribute("type")))
            s += " in " + describe(p);
        return s;
    }
    // An error that stops the load; the unsupported elements met before it follow its message.
    [[noreturn]] void fail(xml_node n, const std::string& msg) const {
        std::string m = where(n) + ": " + msg;
        if (!strict_errors_.empty()) m += "\nbefore it:\n" + grouped_report(strict_errors_, true);
        throw InputError(m);
    }
    void warn(xml_node n, const std::string& msg) { warnings_.push_back({where(n), msg}); }
    // An element gdr does not support: an error, or with --lenient one warning
    // saying what happens instead. Either way the caller then does that, so
    // that a strict load goes on and reports every such element at once.
    void unsupported(xml_node n, const std::string& msg, const std::string& instead) {
        dropped(n, msg + " (--lenient " + instead + " with a warning)", msg + "; " + instead + " (--lenient)");
    }
    // The same with the whole message of each mode.
    void dropped(xml_node n, const std::string& strict_msg, const std::string& lenient_msg) {
        if (!opt_.lenient) strict_errors_.push_back({where(n), strict_msg});
        else warn(n, lenient_msg);
    }
    std::string grouped_report(const std::vector<std::pair<std::string, std::string>>& items, bool errors) const;

    // ---- attributes and values
    std::string attr(xml_node n, const char* a) {
        const std::string v = raw(n, a);
        if (v.find('$') == std::string::npos) return v;
        std::string r;
        for (size_t i = 0; i < v.size();) {
            if (v[i] != '$') {
                r += v[i++];
                continue;
            }
            size_t j = i + 1;
            while (j < v.size() && (std::isalnum(static_cast<unsigned char>(v[j])) || v[j] == '_')) ++j;
            if (j == i + 1) {
                r += v[i++];
                continue;
            }
            const std::string name = v.substr(i + 1, j - i - 1);
            const auto it = params_.find(name);
            if (it == params_.end())
                fail(n, "parameter $" + name + " has no value: give it with -D " + name + "=VALUE or declare <default name=\"" +
                            name + "\" value=\"...\"/>");
            used_params_.insert(name);
            r += it->second;
            i = j;
        }
        return r;
    }
    std::string need_attr(xml_node n, const char* a) {
        if (!n.attribute(a)) fail(n, std::string("missing attribute '") + a + "'");
        return attr(n, a);
    }
    double number(xml_node n, const std::string& text, const std::string& what) const {
        const char* first = text.data();
        const char* last = first + text.size();
        while (first < last && std::isspace(static_cast<unsigned char>(*first))) ++first;
        while (last > first && std::isspace(static_cast<unsigned char>(last[-1]))) --last;
        if (first < last && *first == '+') ++first;
        double v = 0.0;
        const auto r = std::from_chars(first, last, v);
        // Every value is stored as a float: 1e39 would become Inf.
        if (first == last || r.ec != std::errc() || r.ptr != last || !(std::abs(v) <= kMaxFloat))
            fail(n, what + " must be a finite number within float range (|x| <= 3.4e38), got '" + text + "'");
        return v;
    }
    std::vector<double> numbers(xml_node n, const std::string& text, const std::string& what) const {
        std::vector<double> v;
        std::string tok;
        for (size_t i = 0; i <= text.size(); ++i) {
            const char c = i < text.size() ? text[i] : ' ';
            if (c == ',' || std::isspace(static_cast<unsigned char>(c))) {
                if (!tok.empty()) v.push_back(number(n, tok, what)), tok.clear();
            } else {
                tok += c;
            }
        }
        return v;
    }
    Vec3 xyz(xml_node n, float def) {
        if (n.attribute("value")) {
            const auto v = numbers(n, attr(n, "value"), "'value'");
            if (v.size() == 1) return Vec3(float(v[0]));
            if (v.size() != 3) fail(n, "'value' must hold 1 or 3 numbers");
            return Vec3(float(v[0]), float(v[1]), float(v[2]));
        }
        Vec3 r(def);
        for (int k = 0; k < 3; ++k) {
            const char* a = k == 0 ? "x" : k == 1 ? "y" : "z";
            if (n.attribute(a)) r[k] = float(number(n, attr(n, a), std::string("'") + a + "'"));
        }
        return r;
    }

    // ---- properties of a plugin element
    Props props(xml_node owner);
    xml_node take(Props& p, const std::string& name) {
        const auto it = p.named.find(name);
        if (it == p.named.end()) return {};
        p.used.insert(it->second.internal_object());
        return it->second;
    }
    void ignore(Props& p, std::initializer_list<const char*> names) {
        for (const char* n : names) take(p, n);
    }
    void expect_tag(xml_node n, std::initializer_list<const char*> tags) {
        for (const char* t : tags)
            if (std::string(n.name()) == t) return;
        std::string list;
        for (const char* t : tags) list += (list.empty() ? "<" : ", <") + std::string(t) + ">";
        fail(n, "expected " + list);
    }
    float get_float(Props& p, const std::string& name, float def, bool* given = nullptr) {
        const xml_node n = take(p, name);
        if (given) *given = bool(n);
        if (!n) return def;
        expect_tag(n, {"float", "integer"});
        return float(number(n, need_attr(n, "value"), "'value'"));
    }
    long long get_int(Props& p, const std::string& name, long long def, bool* given = nullptr) {
        const xml_node n = take(p, name);
        if (given) *given = bool(n);
        if (!n) return def;
        expect_tag(n, {"integer"});
        const std::string v = need_attr(n, "value");
        long long r = 0;
        const auto res = std::from_chars(v.data(), v.data() + v.size(), r);
        if (v.empty() || res.ec != std::errc() || res.ptr != v.data() + v.size())
            fail(n, "'value' must be an integer, got '" + v + "'");
        return r;
    }
    bool get_bool(Props& p, const std::string& name, bool def) {
        const xml_node n = take(p, name);
        if (!n) return def;
        expect_tag(n, {"boolean"});
        const std::string v = need_attr(n, "value");
        if (v == "true" || v == "1") return true;
        if (v == "false" || v == "0") return false;
        fail(n, "'value' must be true or false, got '" + v + "'");
    }
    std::string get_string(Props& p, const std::string& name, const std::string& def) {
        const xml_node n = take(p, name);
        if (!n) return def;
        expect_tag(n, {"string"});
        return need_attr(n, "value");
    }
    Color colour_of(xml_node n);
    Color get_colour(Props& p, const std::string& name, const Color& def) {
        const xml_node n = take(p, name);
        if (!n) return def;
        if (std::string(n.name()) == "texture" || std::string(n.name()) == "ref") {
            unsupported(n, "a texture for '" + name + "' (gdr takes a colour here)",
                        fmt::format("uses the default ({}, {}, {})", def.r, def.g, def.b));
            return def;
        }
        return colour_of(n);
    }
    std::shared_ptr<Texture> get_texture(Props& p, const std::string& name, const Color& def);
    Vec3 get_point(Props& p, const std::string& name, const Vec3& def) {
        const xml_node n = take(p, name);
        if (!n) return def;
        expect_tag(n, {"point", "vector"});
        return xyz(n, 0.f);
    }
    Mat4 transform_of(xml_node n, bool* nine = nullptr);
    Mat4 get_transform(Props& p, const std::string& name) {
        const xml_node n = take(p, name);
        if (!n) return Mat4(1.f);
        expect_tag(n, {"transform"});
        return transform_of(n);
    }
    glm::mat3 get_uv_transform(Props& p);
    // Every property and object of `p` that was not read is unsupported.
    void finish(Props& p) {
        for (const auto& [name, n] : p.named)
            if (!p.used.count(n.internal_object())) unsupported(n, "unsupported property '" + name + "'", "ignores it");
        for (xml_node n : p.objects)
            if (!p.used.count(n.internal_object())) unsupported(n, "unsupported nested element", "ignores it");
    }
    float ior(Props& p, const std::string& name, float def);
    xml_node resolve(xml_node ref) {
        const std::string id = need_attr(ref, "id");
        const auto it = ids_.find(id);
        if (it == ids_.end()) fail(ref, "no element has id '" + id + "'");
        return it->second;
    }
    std::string file_path(xml_node n, std::string name) {
        std::replace(name.begin(), name.end(), '\\', '/');  // scenes written on Windows
        const fs::path f(name);
        if (f.is_absolute()) return f.string();
        const fs::path own = fs::path(doc_of(n).dir) / f;
        std::error_code ec;
        if (fs::exists(own, ec) || docs_.empty()) return own.string();
        const fs::path root = fs::path(docs_.front().dir) / f;
        if (fs::exists(root, ec)) return root.string();
        // Scenes written on a case-insensitive file system name files in
        // another case than they have on disk: such a file is used, with a warning.
        for (const fs::path& base : {fs::path(doc_of(n).dir), fs::path(docs_.front().dir)}) {
            fs::path found;
            if (find_any_case(base, f, found)) {
                if (case_warned_.insert(found.string()).second)
                    warn(n, fmt::format("{} is not on disk with this case; using {}", (base / f).string(), found.string()));
                return found.string();
            }
        }
        return own.string();
    }
    // `rel` under `dir`, each of its components matched ignoring ASCII case
    // where no exact match exists; false if some component has no match.
    static bool find_any_case(const fs::path& dir, const fs::path& rel, fs::path& out) {
        const auto lower = [](std::string x) {
            for (char& c : x) c = char(std::tolower(static_cast<unsigned char>(c)));
            return x;
        };
        fs::path cur = dir;
        std::error_code ec;
        for (const fs::path& comp : rel) {
            if (comp == "." || comp == ".." || fs::exists(cur / comp, ec)) {
                cur /= comp;
                continue;
            }
            const std::string want = lower(comp.string());
            std::vector<fs::path> hits;
            for (fs::directory_iterator it(cur, ec), end; !ec && it != end; it.increment(ec))
                if (lower(it->path().filename().string()) == want) hits.push_back(it->path());
            if (hits.empty()) return false;
            std::sort(hits.begin(), hits.end());  // the same choice on every run
            cur = hits.front();
        }
        out = cur;
        return fs::exists(cur, ec);
    }

    // ---- scene elements
    void load_doc(const std::string& file, xml_node from);
    void collect(xml_node scene, int depth, std::vector<xml_node>& out);
    void index_ids(xml_node n);
    std::shared_ptr<BuiltBsdf> bsdf(xml_node n);
    std::shared_ptr<BuiltBsdf> build_bsdf(xml_node n);
    std::shared_ptr<Texture> texture(xml_node n);
    std::shared_ptr<Texture> build_texture(xml_node n);
    std::shared_ptr<Texture> opacity_texture(xml_node t);
    std::shared_ptr<Texture> bitmap(xml_node n, Props& p, bool opacity);
    std::shared_ptr<Texture> scale_texture(xml_node n, Props& p);
    ConductorIor conductor_ior(Props& p, xml_node n);
    MicrofacetType microfacet_type(Props& p, const std::string& def);
    std::shared_ptr<Texture> tint_texture(Props& p, const std::string& name);
    std::shared_ptr<Bsdf> build_phong(Props& p);
    std::shared_ptr<Bsdf> build_ward(Props& p, float alpha);
    std::shared_ptr<Bsdf> build_rough_diffuse(Props& p, std::shared_ptr<Texture> kd);
    float scalar_param(Props& p, const std::string& name, float def);
    void ignore_smooth_roughness(xml_node n, Props& p);
    void sensor(xml_node n);
    void integrator(xml_node n);
    // `outer` places the shape: an instance's transform, else the identity.
    void shape(xml_node n, const Mat4& outer = Mat4(1.f));
    void instance(xml_node n, const Mat4& outer);
    void emitter(xml_node n);
    void delta_emitter(xml_node n, const std::string& type);
    uint32_t material_for(const std::shared_ptr<BuiltBsdf>& b, const Color& emission, const std::string& shape_name,
                          xml_node at);
    void add_triangles(const std::vector<Vec3>& p, std::vector<Vec3> nrm, const std::vector<Vec2>& uv, const Mat4& xf,
                       bool flip, uint32_t material, const std::string& file);
    void load_obj_shape(xml_node n, const std::string& file, bool face_normals, bool flip_uv, const Mat4& xf,
                        bool flip, uint32_t material);
    void load_ply_shape(xml_node n, const std::string& file, bool face_normals, const Mat4& xf, bool flip,
                        uint32_t material);
    // ---- serialized meshes and the cylinder (mitsuba_shapes.cpp has their geometry)
    const SerializedFile& serialized_file(const std::string& file);
    void crease_normals(size_t first_triangle, float max_smooth_angle);
    void add_indexed(detail::IndexedMesh m, const Mat4& xf, bool flip, bool face_normals, float max_smooth_angle,
                     uint32_t material, const std::string& label);

    std::string path_;
    const SceneFileOptions& opt_;
    std::deque<Doc> docs_;
    int version_major_ = 3;
    std::map<std::string, std::string> params_;
    std::set<std::string> used_params_;
    std::set<std::string> declared_;  // parameters with a <default>
    std::map<std::string, xml_node> ids_;
    std::map<const void*, std::shared_ptr<BuiltBsdf>> bsdfs_;
    std::map<const void*, std::shared_ptr<Texture>> textures_;
    std::map<const void*, std::shared_ptr<Texture>> opacities_;  // of a <texture> used as a mask's opacity
    std::set<const void*> building_;  // BSDFs and textures being built (a ref cycle guard)
    // Marks n as being built: an error if it is already (a cycle of refs) or the chain is too deep.
    void begin_building(xml_node n);
    std::vector<std::pair<std::string, std::string>> warnings_;       // (where, what) of each warning
    std::vector<std::pair<std::string, std::string>> strict_errors_;  // (where, what) of each unsupported element
    int shape_elements_ = 0, emitter_elements_ = 0;                   // as written in the scene
    std::vector<std::string> inputs_;
    std::shared_ptr<Environment> environment_;  // a constant or envmap emitter, if any
    std::vector<DeltaLight> delta_lights_;      // point, spot and directional emitters
    TriangleMesh mesh_;
    std::vector<Material> materials_;
    std::vector<MeshStats> stats_;
    std::shared_ptr<BuiltBsdf> default_bsdf_;
    bool have_sensor_ = false, have_integrator_ = false;
    CameraDesc camera_;
    // The reflection that a mirroring sensor to_world puts on the world (see sensor()).
    Mat4 mirror_{1.f};
    bool mirrored_ = false;
    void mirror_world();
    RenderDefaults defaults_;
    std::vector<std::pair<std::string, long long>> int_params_;
    std::map<std::string, std::shared_ptr<SerializedFile>> serialized_;  // by path: a file is read once
    std::set<std::string> case_warned_;  // files found only with another case, warned about once
};

}  // namespace gdr::mitsuba_import
