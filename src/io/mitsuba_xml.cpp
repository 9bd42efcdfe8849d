// Mitsuba XML scenes (0.6 and 3.x) as gdr scenes, through pugixml. The
// importer walks the scene's top-level elements in order (an <include> is
// spliced in where it stands, a <default> sets a $parameter unless -D did),
// builds each plugin from its properties, and reports every property it did
// not use: nothing is dropped silently. BSDFs and textures are built once per
// element, so a <ref> shares them. Shapes become triangles of one mesh.
#include "gdr/io/mitsuba_xml.h"

#include "mitsuba_importer.h"

namespace gdr {

namespace mitsuba_import {

// ---------------------------------------------------------------- documents

void Importer::load_doc(const std::string& file, xml_node from) {
    std::string text;
    // The scene's own text may be given instead of its file (SceneFileOptions::text).
    const bool given = docs_.empty() && !opt_.text.empty();
    try {
        text = given ? opt_.text : detail::read_file_text(file);
    } catch (const InputError& e) {
        if (from) fail(from, e.what());
        throw;
    }
    Doc& d = docs_.emplace_back();
    d.file = file;
    d.dir = fs::path(file).parent_path().string();
    d.line_starts.push_back(0);
    for (size_t i = 0; i < text.size(); ++i)
        if (text[i] == '\n') d.line_starts.push_back(i + 1);
    const pugi::xml_parse_result r = d.xml.load_buffer(text.data(), text.size(), pugi::parse_default);
    if (!r) {
        const size_t off = size_t(std::max<ptrdiff_t>(0, r.offset));
        const int line = int(std::upper_bound(d.line_starts.begin(), d.line_starts.end(), off) - d.line_starts.begin());
        throw InputError(fmt::format("{}:{}: malformed XML: {}", file, line, r.description()));
    }
    // Depth first without recursion: the importer's own walks recurse, so the depth is bounded here first.
    std::vector<std::pair<xml_node, int>> stack{{d.xml.document_element(), 1}};
    while (!stack.empty()) {
        const auto [e, depth] = stack.back();
        stack.pop_back();
        if (depth > kMaxNesting)
            throw InputError(fmt::format("{}:{}: <{}> is nested {} elements deep, more than the {} gdr reads", file,
                                         line_of(e), e.name(), depth, kMaxNesting));
        for (xml_node c = e.first_child(); c; c = c.next_sibling())
            if (c.type() == pugi::node_element) stack.emplace_back(c, depth + 1);
    }
    if (!given) inputs_.push_back(file);
    const xml_node scene = d.xml.document_element();
    if (std::string(scene.name()) != "scene")
        throw InputError(fmt::format("{}:{}: the root element is <{}>, not <scene>: not a Mitsuba scene file", file,
                                     line_of(scene), scene.name()));
}

void Importer::collect(xml_node scene, int depth, std::vector<xml_node>& out) {
    for (xml_node c : scene.children()) {
        if (c.type() != pugi::node_element) continue;
        const std::string tag = c.name();
        if (tag == "default") {
            const std::string name = need_attr(c, "name");
            if (!c.attribute("value")) fail(c, "missing attribute 'value'");
            if (!opt_.defines.count(name) && !params_.count(name)) params_[name] = attr(c, "value");
            declared_.insert(name);
        } else if (tag == "include") {
            if (depth >= 16) fail(c, "includes nest more than 16 deep (does a file include itself?)");
            const std::string file = file_path(c, need_attr(c, "filename"));
            load_doc(file, c);
            collect(docs_.back().xml.document_element(), depth + 1, out);
        } else {
            out.push_back(c);
        }
    }
}

void Importer::index_ids(xml_node n) {
    for (xml_node c : n.children()) {
        if (c.type() != pugi::node_element) continue;
        if (std::string(c.name()) != "ref" && c.attribute("id")) {
            const std::string id = attr(c, "id");
            const auto [it, fresh] = ids_.emplace(id, c);
            if (!fresh) fail(c, fmt::format("id '{}' is given twice (also at line {})", id, line_of(it->second)));
        }
        index_ids(c);
    }
}

Props Importer::props(xml_node owner) {
    static const std::set<std::string> kTags = {"float", "integer", "boolean", "string", "rgb", "srgb", "spectrum",
                                                "blackbody", "point", "vector", "transform", "texture", "ref", "bsdf",
                                                "emitter", "sampler", "film", "rfilter", "shape", "medium", "phase",
                                                "integrator", "sensor", "volume", "subsurface"};
    Props p;
    p.owner = owner;
    for (xml_node c : owner.children()) {
        if (c.type() != pugi::node_element) continue;
        const std::string tag = c.name();
        if (!kTags.count(tag)) fail(c, "unknown element <" + tag + ">");
        const bool value_tag = tag != "bsdf" && tag != "emitter" && tag != "sampler" && tag != "film" &&
                               tag != "rfilter" && tag != "shape" && tag != "medium" && tag != "phase" &&
                               tag != "integrator" && tag != "sensor" && tag != "ref" && tag != "texture" &&
                               tag != "subsurface";
        if (c.attribute("name")) {
            const std::string name = snake_case(attr(c, "name"));
            const auto [it, fresh] = p.named.emplace(name, c);
            if (!fresh) fail(c, fmt::format("property '{}' is given twice (also at line {})", name, line_of(it->second)));
        } else if (value_tag) {
            fail(c, "a property needs a 'name'");
        } else {
            p.objects.push_back(c);
        }
    }
    return p;
}

// ---------------------------------------------------------------- values

Color Importer::colour_of(xml_node n) {
    const std::string tag = n.name();
    if (tag == "float" || tag == "integer") return Color(float(number(n, need_attr(n, "value"), "'value'")));
    if (tag == "rgb" || tag == "srgb") {
        const std::string v = need_attr(n, "value");
        std::vector<double> c;
        if (!v.empty() && v[0] == '#') {
            if (v.size() != 7) fail(n, "a hexadecimal colour needs 6 digits (#rrggbb), got '" + v + "'");
            for (int k = 0; k < 3; ++k) {
                unsigned x = 0;
                const auto r = std::from_chars(v.data() + 1 + 2 * k, v.data() + 3 + 2 * k, x, 16);
                if (r.ec != std::errc() || r.ptr != v.data() + 3 + 2 * k) fail(n, "malformed colour '" + v + "'");
                c.push_back(srgb_to_linear(float(x) / 255.f));
            }
            return Color(float(c[0]), float(c[1]), float(c[2]));
        }
        c = numbers(n, v, "'value'");
        if (c.size() == 1) c = {c[0], c[0], c[0]};
        if (c.size() != 3) fail(n, "'value' must hold 1 or 3 numbers, got '" + v + "'");
        Color r = Color(float(c[0]), float(c[1]), float(c[2]));
        if (tag == "srgb")
            for (int k = 0; k < 3; ++k) r[k] = srgb_to_linear(r[k]);
        return r;
    }
    if (tag == "spectrum") {
        if (n.attribute("filename")) {
            unsupported(n, "spectra from files", "uses grey 0.5");
            return Color(0.5f);
        }
        const std::string v = need_attr(n, "value");
        if (v.find(':') != std::string::npos) {
            unsupported(n, "wavelength:value spectra (gdr renders RGB; give <rgb>)", "uses their mean value");
            double sum = 0.0;
            int count = 0;
            std::stringstream in(v);
            std::string pair;
            while (std::getline(in, pair, ',')) {
                const size_t colon = pair.find(':');
                if (colon == std::string::npos) fail(n, "malformed spectrum '" + v + "'");
                sum += number(n, pair.substr(colon + 1), "a spectrum value"), ++count;
            }
            return Color(count ? float(sum / count) : 0.f);
        }
        const auto c = numbers(n, v, "'value'");
        if (c.size() == 1) return Color(float(c[0]));
        if (c.size() == 3) return Color(float(c[0]), float(c[1]), float(c[2]));
        fail(n, "'value' must hold 1 number (or wavelength:value pairs), got '" + v + "'");
    }
    if (tag == "blackbody") {
        unsupported(n, "blackbody spectra (gdr renders RGB; give <rgb>)", "uses white 1");
        return Color(1.f);
    }
    fail(n, "expected a colour (<rgb>, <srgb>, <spectrum> or <float>)");
}

std::shared_ptr<Texture> Importer::get_texture(Props& p, const std::string& name, const Color& def) {
    const xml_node n = take(p, name);
    if (!n) return make_constant_texture(def);
    const std::string tag = n.name();
    if (tag == "texture") return texture(n);
    if (tag == "ref") {
        const xml_node t = resolve(n);
        if (std::string(t.name()) != "texture") fail(n, "refers to " + describe(t) + ", not a <texture>");
        return texture(t);
    }
    return make_constant_texture(colour_of(n));
}

Mat4 Importer::transform_of(xml_node t, bool* nine) {
    Mat4 m(1.f);
    if (nine) *nine = false;
    for (xml_node c : t.children()) {
        if (c.type() != pugi::node_element) continue;
        const std::string tag = c.name();
        Mat4 op(1.f);
        if (tag == "translate") {
            op = glm::translate(Mat4(1.f), xyz(c, 0.f));
        } else if (tag == "scale") {
            op = glm::scale(Mat4(1.f), xyz(c, 1.f));
        } else if (tag == "rotate") {
            Vec3 axis;
            if (c.attribute("value")) {
                const auto v = numbers(c, attr(c, "value"), "'value'");
                if (v.size() != 3) fail(c, "'value' must be the rotation axis (3 numbers)");
                axis = Vec3(float(v[0]), float(v[1]), float(v[2]));
            } else {
                axis = xyz(c, 0.f);
            }
            if (!(glm::length(axis) > 0.f)) fail(c, "the rotation axis is zero");
            const float angle = float(number(c, need_attr(c, "angle"), "'angle'"));
            op = glm::rotate(Mat4(1.f), glm::radians(angle), glm::normalize(axis));
        } else if (tag == "matrix") {
            const auto v = numbers(c, need_attr(c, "value"), "'value'");
            if (v.size() == 9) {
                // A 3x3 matrix (row-major): embedded so that its third row and column act on (x, y, 1) of uv.
                for (int r = 0; r < 3; ++r)
                    for (int k = 0; k < 3; ++k) op[k == 2 ? 3 : k][r == 2 ? 3 : r] = float(v[3 * r + k]);
                if (nine) *nine = true;
            } else if (v.size() == 16) {
                for (int i = 0; i < 16; ++i) op[i % 4][i / 4] = float(v[i]);
            } else {
                fail(c, "'value' must hold 16 numbers (4x4, row-major) or 9 (3x3), got " + std::to_string(v.size()));
            }
        } else if (tag == "lookat") {
            const auto vec = [&](const char* a, bool need) {
                if (!c.attribute(a)) {
                    if (need) fail(c, std::string("missing attribute '") + a + "'");
                    return glm::dvec3(0.0, 1.0, 0.0);
                }
                const auto v = numbers(c, attr(c, a), std::string("'") + a + "'");
                if (v.size() != 3) fail(c, std::string("'") + a + "' must hold 3 numbers");
                return glm::dvec3(v[0], v[1], v[2]);
            };
            // In double precision: a randomised camera may give an up vector
            // within 1e-7 of the viewing axis whose small remainder still
            // decides the roll (as it does in Mitsuba's own cross product).
            const glm::dvec3 o = vec("origin", true), target = vec("target", true), up = vec("up", false);
            // Farther, |target - origin| overflows and the message below would blame the up vector.
            for (const auto& [a, v] : {std::pair<const char*, glm::dvec3>{"origin", o}, {"target", target}})
                if (!within_coordinate_range(Vec3(v)))
                    fail(c, fmt::format("'{}' ({}, {}, {}) is beyond +-{:g} on an axis", a, v.x, v.y, v.z, kMaxCoordinate));
            if (!(glm::length(target - o) > 0.0)) fail(c, "origin and target coincide");
            const glm::dvec3 dir = glm::normalize(target - o);
            const glm::dvec3 l = glm::cross(up, dir);
            if (!(glm::length(l) > 1e-12 * glm::length(up))) fail(c, "up is parallel to the viewing direction");
            const glm::dvec3 left = glm::normalize(l), new_up = glm::cross(dir, left);
            op = Mat4(Vec4(Vec3(left), 0.f), Vec4(Vec3(new_up), 0.f), Vec4(Vec3(dir), 0.f), Vec4(Vec3(o), 1.f));
        } else {
            fail(c, "unknown transform operation <" + tag + "> (expected translate, rotate, scale, matrix, lookat)");
        }
        m = op * m;  // each operation applies after the ones before it
    }
    return m;
}

glm::mat3 Importer::get_uv_transform(Props& p) {
    glm::mat3 m(1.f);
    if (const xml_node n = take(p, "to_uv")) {
        expect_tag(n, {"transform"});
        const Mat4 t = transform_of(n);
        // The 2D affine part: x and y rows, the x, y and translation columns.
        m = glm::mat3(Vec3(t[0][0], t[0][1], 0.f), Vec3(t[1][0], t[1][1], 0.f), Vec3(t[3][0], t[3][1], 1.f));
    }
    // Mitsuba 0.6's offsets and scales: uv * scale + offset.
    bool given[4];
    const float us = get_float(p, "uscale", 1.f, &given[0]), vs = get_float(p, "vscale", 1.f, &given[1]);
    const float uo = get_float(p, "uoffset", 0.f, &given[2]), vo = get_float(p, "voffset", 0.f, &given[3]);
    if (given[0] || given[1] || given[2] || given[3])
        m = glm::mat3(Vec3(us, 0.f, 0.f), Vec3(0.f, vs, 0.f), Vec3(uo, vo, 1.f)) * m;
    return m;
}

float Importer::ior(Props& p, const std::string& name, float def) {
    const xml_node n = take(p, name);
    if (!n) return def;
    if (std::string(n.name()) == "string") {
        std::string v = need_attr(n, "value");
        for (char& ch : v) ch = char(std::tolower(static_cast<unsigned char>(ch)));
        for (const NamedIor& k : kIors)
            if (v == k.name) return k.ior;
        std::string list;
        for (const NamedIor& k : kIors) list += (list.empty() ? "" : ", ") + std::string(k.name);
        fail(n, "unknown index of refraction '" + v + "' (known: " + list + ")");
    }
    expect_tag(n, {"float", "integer"});
    const float v = float(number(n, need_attr(n, "value"), "'value'"));
    if (!(v > 0.f)) fail(n, "an index of refraction must be positive");
    return v;
}

/// A conductor's complex index of refraction relative to the medium outside
/// (`ext_eta`): from `eta` and `k`, else from the named `material`.
ConductorIor Importer::conductor_ior(Props& p, xml_node n) {
    const xml_node eta_n = take(p, "eta"), k_n = take(p, "k");
    const std::string def_material = version_major_ < 2 ? "Cu" : "none";
    const std::string material = get_string(p, "material", def_material);
    const float ext = ior(p, "ext_eta", 1.f);
    ConductorIor c;
    if (eta_n || k_n) {
        if (!eta_n || !k_n) fail(n, "give both 'eta' and 'k' (or a 'material')");
        c = {colour_of(eta_n), colour_of(k_n)};
    } else if (!named_conductor_ior(material, c)) {
        std::string list;
        for (const NamedConductor& nc : kConductors) list += (list.empty() ? "" : ", ") + std::string(nc.name);
        fail(n, "unknown conductor material '" + material + "' (known: " + list + ")");
    }
    c.eta /= ext, c.k /= ext;
    try {
        check_conductor_ior(c, "conductor");
    } catch (const ParameterError& e) {
        fail(n, e.what());
    }
    return c;
}

// ---------------------------------------------------------------- sensor, integrator

void Importer::sensor(xml_node n) {
    if (have_sensor_) {
        unsupported(n, "a second <sensor>", "renders with the first");
        return;
    }
    have_sensor_ = true;
    const std::string type = need_attr(n, "type");
    if (type != "perspective") unsupported(n, "sensor type '" + type + "'", "renders it as a perspective pinhole");
    Props p = props(n);
    bool fov_given = false;
    float fov = get_float(p, "fov", 45.f, &fov_given);
    const bool axis_given = p.named.count("fov_axis") != 0;
    std::string axis = get_string(p, "fov_axis", "x");
    if (axis != "x" && axis != "y" && axis != "diagonal" && axis != "smaller" && axis != "larger")
        fail(p.named.at("fov_axis"), "unknown fov_axis '" + axis + "' (expected x, y, diagonal, smaller or larger)");
    if (axis_given && !fov_given) warn(p.named.at("fov_axis"), "fov_axis applies to fov only, and there is no fov");
    const xml_node f = take(p, "focal_length");
    if (f && fov_given) fail(f, "give either fov or focal_length");
    if (!fov_given) {
        // A focal length on 35 mm film (36 x 24 mm) gives the diagonal's field
        // of view; Mitsuba's default is 50 mm.
        std::string v = "50";
        if (f) {
            expect_tag(f, {"string", "float"});
            v = need_attr(f, "value");
            if (v.size() > 2 && v.substr(v.size() - 2) == "mm") v.resize(v.size() - 2);
        }
        const float mm = float(number(f ? f : n, v, "focal_length"));
        if (!(mm > 0.f)) fail(f ? f : n, "focal_length must be positive");
        fov = 2.f * std::atan(std::sqrt(36.f * 36.f + 24.f * 24.f) / (2.f * mm)) * 180.f / kPi;
        axis = "diagonal";
    }
    const Mat4 m = get_transform(p, "to_world");
    ignore(p, {"near_clip", "far_clip", "shutter_open", "shutter_close", "shutter_open_time", "focus_distance",
               "aperture_radius"});
    if (type != "perspective")
        for (auto& [name, c] : p.named) p.used.insert(c.internal_object());
    int width = 768, height = 576;
    for (xml_node c : p.objects) {
        const std::string tag = c.name();
        if (tag == "sampler") {
            p.used.insert(c.internal_object());
            Props sp = props(c);
            bool given = false;
            const long long spp = get_int(sp, "sample_count", 0, &given);
            if (given) {
                if (spp < 1) fail(sp.named.at("sample_count"), "sample_count must be at least 1");
                defaults_.spp = spp;
            }
            // gdr's own sampler replaces Mitsuba's; its other settings do not apply.
            for (auto& [name, x] : sp.named) sp.used.insert(x.internal_object());
            finish(sp);
        } else if (tag == "film") {
            p.used.insert(c.internal_object());
            Props fp = props(c);
            const long long w = get_int(fp, "width", 768), h = get_int(fp, "height", 576);
            if (w < 1 || h < 1 || w > 65536 || h > 65536)
                fail(c, fmt::format("film size {}x{} must lie in 1..65536 per side", w, h));
            width = int(w), height = int(h);
            // How Mitsuba would write its image: not gdr's concern.
            ignore(fp, {"file_format", "pixel_format", "component_format", "banner", "gamma", "high_quality_edges",
                        "attach_log", "dithering", "exposure", "tonemap_method", "key", "burn", "sample_border",
                        "label", "compensate", "metadata"});
            for (xml_node r : fp.objects) {
                if (std::string(r.name()) != "rfilter") continue;
                fp.used.insert(r.internal_object());
                const std::string rt = need_attr(r, "type");
                if (rt != "box")
                    warn(r, "reconstruction filter '" + rt + "' is replaced by gdr's box filter (each sample counts "
                             "for the pixel it falls in)");
                Props rp = props(r);
                for (auto& [name, x] : rp.named) rp.used.insert(x.internal_object());
                finish(rp);
            }
            finish(fp);
        }
    }
    finish(p);

    const Vec3 pos = Vec3(m * Vec4(0.f, 0.f, 0.f, 1.f));
    const Vec3 fwd = Vec3(m * Vec4(0.f, 0.f, 1.f, 0.f)), up = Vec3(m * Vec4(0.f, 1.f, 0.f, 0.f));
    const Vec3 left = Vec3(m * Vec4(1.f, 0.f, 0.f, 0.f));
    if (!(glm::length(fwd) > 0.f) || !(glm::length(up) > 0.f) || !is_finite(pos))
        fail(n, "to_world is degenerate");
    if (!within_coordinate_range(pos))
        fail(n, fmt::format("to_world places the camera at ({}, {}, {}), beyond +-{:g} on an axis", pos.x, pos.y, pos.z,
                            kMaxCoordinate));
    // Mitsuba's camera x axis points left in the image; gdr's right is
    // cross(forward, up). A to_world that mirrors the image is rendered as
    // the mirror image of the world through the unmirrored camera: the
    // world is reflected in the plane of the camera's forward and up axes
    // (mirror_world()), which projects every point where the mirrored
    // camera would.
    if (glm::dot(left, glm::cross(fwd, up)) > 0.f) {
        const Vec3 r = glm::normalize(glm::cross(fwd, up));
        mirror_ = Mat4(glm::mat3(1.f) - 2.f * glm::outerProduct(r, r));
        mirror_[3] = Vec4(2.f * glm::dot(pos, r) * r, 1.f);
        mirrored_ = true;
    }
    if (!(fov > 0.f && fov < 180.f)) fail(n, fmt::format("fov must lie in (0, 180) degrees, got {}", fov));
    const float aspect = float(width) / float(height);
    const float t = std::tan(0.5f * fov * kPi / 180.f);
    char fov_axis = 'x';
    if (axis == "x" || axis == "y") {
        fov_axis = axis[0];
    } else if (axis == "diagonal") {
        fov = 2.f * std::atan(t * aspect / std::sqrt(aspect * aspect + 1.f)) * 180.f / kPi;
    } else if (axis == "smaller" || axis == "larger") {
        fov_axis = (axis == "smaller") == (width <= height) ? 'x' : 'y';
    } else {
        fail(n, "unknown fov_axis '" + axis + "' (expected x, y, diagonal, smaller or larger)");
    }
    camera_.position = pos;
    camera_.target = pos + glm::normalize(fwd);
    camera_.up = glm::normalize(up);
    camera_.fov_deg = fov;
    camera_.fov_axis = fov_axis;
    camera_.width = width, camera_.height = height;
}

void Importer::integrator(xml_node n) {
    if (have_integrator_) {
        unsupported(n, "a second <integrator>", "uses the first");
        return;
    }
    have_integrator_ = true;
    // gdr's estimator is chosen by --integrator; what it shares with the
    // scene's is the path length (max_depth, counted in segments as gdr's)
    // and where Russian roulette starts. A wrapper (adaptive, irrcache, ...)
    // passes them on from its nested integrator.
    xml_node at = n;
    std::string type = need_attr(n, "type");
    Props p = props(n);
    for (xml_node c : p.objects)
        if (std::string(c.name()) == "integrator" && !p.named.count("max_depth")) {
            at = c;
            type = need_attr(c, "type");
            p.used.insert(c.internal_object());
            Props inner = props(c);
            for (auto& [name, x] : p.named) inner.named.emplace(name, x);  // the wrapper's own, for the note
            for (xml_node o : p.objects) if (o != c) inner.objects.push_back(o);
            p = std::move(inner);
            break;
        }
    bool depth_given = false, rr_given = false;
    const long long depth = get_int(p, "max_depth", -1, &depth_given);
    const long long rr = get_int(p, "rr_depth", 5, &rr_given);
    if (depth_given && (depth < -1 || depth == 0)) fail(p.named.at("max_depth"), "max_depth must be -1 (unlimited) or positive");
    if (rr_given && rr < 1) fail(p.named.at("rr_depth"), "rr_depth must be positive");
    // Hiding the emitters from the camera changes the image: gdr cannot.
    if (const xml_node h = p.named.count("hide_emitters") ? p.named.at("hide_emitters") : xml_node())
        if (get_bool(p, "hide_emitters", false))
            unsupported(h, "unsupported property 'hide_emitters' (gdr's integrators show the emitters)", "shows them");
    static const std::map<std::string, std::string> kKnown = {
        {"path", "pt"}, {"volpath", "pt"}, {"volpath_simple", "pt"}, {"bdpt", "bdpt"}, {"gpt", "gpt"}};
    const auto it = kKnown.find(type);
    if (it != kKnown.end()) defaults_.integrator = it->second;
    // Everything else is the other renderer's business: one note names it all.
    std::string rest;
    for (auto& [name, c] : p.named)
        if (!p.used.count(c.internal_object())) rest += (rest.empty() ? "" : ", ") + name;
    for (xml_node c : p.objects)
        if (!p.used.count(c.internal_object())) rest += (rest.empty() ? "<" : ", <") + std::string(c.name()) + ">";
    if (it == kKnown.end())
        warn(at, "integrator '" + type + "' is rendered with gdr's " + defaults_.integrator +
                     " (choose another with --integrator)" + (rest.empty() ? "" : "; its " + rest + " do not apply"));
    else if (!rest.empty())
        warn(at, "integrator '" + type + "': " + rest + " do not apply to gdr's " + it->second + " and are ignored");
    if (depth_given) int_params_.push_back({"max_depth", depth});
    if (rr_given) int_params_.push_back({"rr_depth", rr});
}

// ---------------------------------------------------------------- shapes

uint32_t Importer::material_for(const std::shared_ptr<BuiltBsdf>& b, const Color& emission,
                                const std::string& shape_name, xml_node at) {
    if (is_black(emission)) {
        if (b->material < 0) {
            b->material = int(materials_.size());
            Material m;
            m.name = b->name;
            m.bsdf = b->bsdf;
            m.opacity = b->opacity;
            m.bump = b->bump;
            m.normal_map = b->normal_map;
            materials_.push_back(std::move(m));
        }
        return uint32_t(b->material);
    }
    if (b->opacity) unsupported(at, "an area emitter with a mask BSDF", "renders the emitter opaque");
    // Light samples on an emitter take its geometric normal as their frame,
    // so a perturbed frame there would differ between a hit and a sample.
    if (b->bump || b->normal_map) unsupported(at, "an area emitter with a bump or normal map", "renders the emitter unperturbed");
    Material m;
    m.name = shape_name;
    m.bsdf = b->bsdf;
    m.emission = emission;
    materials_.push_back(std::move(m));
    return uint32_t(materials_.size() - 1);
}

void Importer::add_triangles(const std::vector<Vec3>& p, std::vector<Vec3> nrm, const std::vector<Vec2>& uv,
                             const Mat4& xf, bool flip, uint32_t material, const std::string& file) {
    const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(xf)));
    // A mirroring transform reverses the winding; swapping two corners keeps
    // the front (emitting) side on the side the transformed normals point to.
    const bool swap = (glm::determinant(glm::mat3(xf)) < 0.f) != flip;
    MeshStats ms{file, p.size() / 3, 0};
    for (size_t t = 0; t + 2 < p.size(); t += 3) {
        Vec3 q[3], n[3];
        Vec2 w[3];
        for (int k = 0; k < 3; ++k) {
            q[k] = Vec3(xf * Vec4(p[t + k], 1.f));
            if (!within_coordinate_range(q[k]))
                throw InputError(fmt::format("{}: shape {}: vertex {} lies at ({}, {}, {}) after to_world, beyond "
                                             "+-{:g} on an axis", path_, file, t + k, q[k].x, q[k].y, q[k].z,
                                             kMaxCoordinate));
            n[k] = nrm.empty() ? Vec3(0.f) : nxf * nrm[t + k] * (flip ? -1.f : 1.f);
            w[k] = uv.empty() ? Vec2(0.f) : uv[t + k];
        }
        if (swap) std::swap(q[1], q[2]), std::swap(n[1], n[2]), std::swap(w[1], w[2]);
        if (nrm.empty()) n[0] = n[1] = n[2] = glm::cross(q[1] - q[0], q[2] - q[0]);
        ms.degenerate_skipped += zero_area_triangle(q[0], q[1], q[2]);
        for (int k = 0; k < 3; ++k) {
            mesh_.positions.push_back(q[k]);
            mesh_.normals.push_back(n[k]);
            mesh_.uvs.push_back(w[k]);
        }
        mesh_.material_ids.push_back(material);
    }
    stats_.push_back(std::move(ms));
}

// Per-corner vertex normals that Mitsuba computes for a mesh without any:
// each vertex's normal is the area-weighted mean of its faces' normals.
std::vector<Vec3> smooth_normals(const std::vector<Vec3>& pos, const std::vector<uint32_t>& idx) {
    const std::vector<Vec3> vn = detail::angle_weighted_normals(pos, idx);  // Mitsuba's weights
    std::vector<Vec3> out(idx.size());
    for (size_t i = 0; i < idx.size(); ++i) out[i] = vn[idx[i]];
    return out;
}

void Importer::load_obj_shape(xml_node n, const std::string& file, bool face_normals, bool flip_uv, const Mat4& xf,
                              bool flip, uint32_t material) {
    detail::ObjLines lines;
    std::string text;
    tinyobj::ObjReader reader;
    try {
        lines = detail::check_obj_lines(file);
        text = detail::read_file_text(file);
    } catch (const InputError& e) {
        fail(n, e.what());
    }
    tinyobj::ObjReaderConfig cfg;
    cfg.triangulate = true;
    cfg.vertex_color = false;
    // Mitsuba ignores the OBJ's materials: its BSDF comes from the scene.
    if (!reader.ParseFromString(text, "", cfg)) {
        std::string e = reader.Error();
        while (!e.empty() && (e.back() == '\n' || e.back() == '\r')) e.pop_back();
        fail(n, file + ": cannot parse OBJ: " + (e.empty() ? "unknown error" : e));
    }
    inputs_.push_back(file);
    const auto& a = reader.GetAttrib();
    size_t tris = 0;
    for (const auto& sh : reader.GetShapes()) tris += sh.mesh.num_face_vertices.size();
    if (tris != lines.triangles)
        fail(n, fmt::format("{}: its faces make {} triangles but the OBJ reader kept {} (polygons it cannot "
                            "triangulate?)",
                            file, lines.triangles, tris));
    const size_t nv = a.vertices.size() / 3;
    std::vector<Vec3> pos(nv), p, nrm;
    std::vector<Vec2> uv;
    for (size_t i = 0; i < nv; ++i) pos[i] = Vec3(a.vertices[3 * i], a.vertices[3 * i + 1], a.vertices[3 * i + 2]);
    bool all_n = !face_normals;
    for (const auto& sh : reader.GetShapes())
        for (const tinyobj::index_t& c : sh.mesh.indices) {
            if (c.vertex_index < 0 || size_t(c.vertex_index) >= nv) fail(n, file + ": a face references a missing vertex");
            if (!is_finite(pos[c.vertex_index]))
                fail(n, fmt::format("{}: vertex {} is not a finite number", file, c.vertex_index + 1));
            p.push_back(pos[c.vertex_index]);
            if (c.normal_index >= 0 && size_t(3 * c.normal_index + 2) < a.normals.size())
                nrm.emplace_back(a.normals[3 * c.normal_index], a.normals[3 * c.normal_index + 1],
                                 a.normals[3 * c.normal_index + 2]);
            else
                all_n = false, nrm.emplace_back(0.f);
            if (c.texcoord_index >= 0 && size_t(2 * c.texcoord_index + 1) < a.texcoords.size()) {
                const float u = a.texcoords[2 * c.texcoord_index], v = a.texcoords[2 * c.texcoord_index + 1];
                // Mitsuba flips OBJ's v by default (flip_tex_coords), which is gdr's convention already.
                uv.emplace_back(u, flip_uv ? v : 1.f - v);
            } else {
                uv.emplace_back(0.f);
            }
        }
    if (face_normals) {
        nrm.clear();
    } else if (!all_n) {
        // As Mitsuba, when some corner has none: its OBJ vertices are the
        // distinct (position, uv) values, so a uv seam splits the normals.
        std::map<std::array<float, 5>, uint32_t> ids;
        std::vector<Vec3> kp;
        std::vector<uint32_t> kidx;
        for (size_t c = 0; c < p.size(); ++c) {
            const auto [it, fresh] = ids.emplace(std::array<float, 5>{p[c].x, p[c].y, p[c].z, uv[c].x, uv[c].y},
                                                 uint32_t(kp.size()));
            if (fresh) kp.push_back(p[c]);
            kidx.push_back(it->second);
        }
        nrm = smooth_normals(kp, kidx);
    }
    add_triangles(p, std::move(nrm), uv, xf, flip, material, file);
}

void Importer::load_ply_shape(xml_node n, const std::string& file, bool face_normals, const Mat4& xf, bool flip,
                              uint32_t material) {
    PlyMesh m;
    try {
        m = read_ply(file);
    } catch (const InputError& e) {
        fail(n, e.what());
    }
    inputs_.push_back(file);
    std::vector<Vec3> p, nrm;
    std::vector<Vec2> uv;
    for (uint32_t i : m.indices) {
        p.push_back(m.positions[i]);
        if (!m.normals.empty() && !face_normals) nrm.push_back(m.normals[i]);
        // PLY stores Mitsuba's uv (v = 0 at the top of an image): gdr's is (u, 1 - v).
        if (!m.uvs.empty()) uv.emplace_back(m.uvs[i].x, 1.f - m.uvs[i].y);
    }
    if (m.normals.empty() && !face_normals) nrm = smooth_normals(m.positions, m.indices);
    add_triangles(p, std::move(nrm), uv, xf, flip, material, file);
}

// Mitsuba's max_smooth_angle on the triangles from `first` on, in world space
// as Mitsuba rebuilds a loaded mesh: their normals are replaced by those of
// the crease-angle rebuild (corners of one position and uv are one vertex).
void Importer::crease_normals(size_t first, float max_smooth_angle) {
    detail::IndexedMesh m;
    m.positions.assign(mesh_.positions.begin() + std::ptrdiff_t(3 * first), mesh_.positions.end());
    if (!mesh_.uvs.empty()) m.uvs.assign(mesh_.uvs.begin() + std::ptrdiff_t(3 * first), mesh_.uvs.end());
    m.indices.resize(m.positions.size());
    for (size_t i = 0; i < m.indices.size(); ++i) m.indices[i] = uint32_t(i);
    detail::rebuild_with_crease_angle(m, max_smooth_angle);
    mesh_.normals.resize(mesh_.positions.size());
    for (size_t c = 0; c < m.indices.size(); ++c) mesh_.normals[3 * first + c] = m.normals[m.indices[c]];
}

// ---------------------------------------------------------------- the mirrored sensor

// The triangles reflected by mirror_, each with two corners swapped so that
// its winding's normal stays the reflection of the original's (the front,
// emitting side is kept); the normals and the delta lights are reflected
// too. The environment was reflected where it was built.
void Importer::mirror_world() {
    const glm::mat3 w(mirror_);
    for (Vec3& q : mesh_.positions) q = Vec3(mirror_ * Vec4(q, 1.f));
    for (Vec3& nn : mesh_.normals) nn = w * nn;
    for (size_t t = 0; t < mesh_.size(); ++t) {
        std::swap(mesh_.positions[3 * t + 1], mesh_.positions[3 * t + 2]);
        if (!mesh_.normals.empty()) std::swap(mesh_.normals[3 * t + 1], mesh_.normals[3 * t + 2]);
        if (!mesh_.uvs.empty()) std::swap(mesh_.uvs[3 * t + 1], mesh_.uvs[3 * t + 2]);
    }
    for (DeltaLight& l : delta_lights_) {
        l.position = Vec3(mirror_ * Vec4(l.position, 1.f));
        l.direction = glm::normalize(w * l.direction);
    }
}

// ---------------------------------------------------------------- instances, serialized meshes, cylinders

// Mitsuba's instance: the shapes of a shapegroup, placed by the instance's to_world.
void Importer::instance(xml_node n, const Mat4& outer) {
    Props p = props(n);
    const Mat4 xf = outer * get_transform(p, "to_world");
    xml_node group;
    for (xml_node c : p.objects) {
        if (std::string(c.name()) != "ref") continue;
        p.used.insert(c.internal_object());
        if (group) fail(c, "an instance refers to one shapegroup");
        group = resolve(c);
        if (std::string(group.name()) != "shape" || raw(group, "type") != "shapegroup")
            fail(c, "refers to " + describe(group) + ", not a <shape type=\"shapegroup\">");
    }
    if (!group) fail(n, "an instance needs a <ref id=\"...\"/> to a shapegroup");
    finish(p);
    if (!building_.insert(group.internal_object()).second) fail(n, "a shapegroup instances itself");
    for (xml_node c : group.children())
        if (c.type() == pugi::node_element) shape(c, xf);
    building_.erase(group.internal_object());
}


const SerializedFile& Importer::serialized_file(const std::string& file) {
    auto& f = serialized_[file];
    if (!f) {
        f = std::make_shared<SerializedFile>(file);  // read once: scenes take many meshes of one file
        inputs_.push_back(file);
    }
    return *f;
}

// An indexed mesh in the order Mitsuba 0.5/0.6 builds it: positions and
// normals to world space (normals by the inverse transpose, normalised), the
// winding reversed by a mirroring transform, the crease-angle rebuild, then
// angle-weighted normals where there are none (unless face normals are asked
// for); flip_normals last, as add_triangles() does for every shape. A
// negative max_smooth_angle means none was given.
void Importer::add_indexed(detail::IndexedMesh m, const Mat4& xf, bool flip, bool face_normals, float max_smooth_angle,
                           uint32_t material, const std::string& label) {
    const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(xf)));
    for (Vec3& q : m.positions) q = Vec3(xf * Vec4(q, 1.f));
    for (Vec3& nn : m.normals) {
        nn = nxf * nn;
        const float len = glm::length(nn);
        if (len > 0.f) nn /= len;
    }
    if (glm::determinant(glm::mat3(xf)) < 0.f)
        for (size_t t = 0; t + 2 < m.indices.size(); t += 3) std::swap(m.indices[t], m.indices[t + 1]);
    if (max_smooth_angle >= 0.f && !face_normals) detail::rebuild_with_crease_angle(m, max_smooth_angle);
    if (face_normals) m.normals.clear();
    else if (m.normals.empty()) m.normals = detail::angle_weighted_normals(m.positions, m.indices);
    std::vector<Vec3> p, nrm;
    std::vector<Vec2> uv;
    p.reserve(m.indices.size());
    for (uint32_t i : m.indices) {
        p.push_back(m.positions[i]);
        if (!m.normals.empty()) nrm.push_back(m.normals[i]);
        // Mitsuba's uv has v = 0 at the top of an image: gdr's is (u, 1 - v).
        if (!m.uvs.empty()) uv.emplace_back(m.uvs[i].x, 1.f - m.uvs[i].y);
    }
    add_triangles(p, std::move(nrm), uv, Mat4(1.f), flip, material, label);
}

void Importer::shape(xml_node n, const Mat4& outer) {
    const std::string type = need_attr(n, "type");
    shape_elements_ += type != "shapegroup";
    static const std::set<std::string> kTypes = {"obj", "ply", "serialized", "rectangle", "cube", "sphere", "disk",
                                                 "cylinder"};
    if (type == "shapegroup") {
        // Its shapes are rendered only where an instance places them.
        if (std::string(n.parent().name()) != "scene") fail(n, "a shapegroup must be a top-level element");
        if (!n.attribute("id")) fail(n, "a shapegroup needs an id for its instances to refer to");
        for (xml_node c : n.children())
            if (c.type() == pugi::node_element && std::string(c.name()) != "shape")
                fail(c, "a shapegroup holds only <shape> elements");
        return;
    }
    if (type == "instance") return instance(n, outer);
    if (!kTypes.count(type)) {
        unsupported(n, "unsupported shape type '" + type + "'", "skips it");
        for (xml_node c : n.children()) emitter_elements_ += std::string(c.name()) == "emitter";  // dropped with it
        return;
    }
    Props p = props(n);
    const Mat4 xf = outer * get_transform(p, "to_world");
    const bool flip = get_bool(p, "flip_normals", false);
    const std::string id = n.attribute("id") ? attr(n, "id") : fmt::format("{} (line {})", type, line_of(n));
    // Its BSDF and emitter.
    std::shared_ptr<BuiltBsdf> b;
    Color radiance(0.f);
    const auto take_bsdf = [&](xml_node c) {
        p.used.insert(c.internal_object());
        if (b) fail(c, "a shape takes one BSDF");
        b = bsdf(c);
    };
    if (p.named.count("bsdf")) take_bsdf(take(p, "bsdf"));
    for (xml_node c : p.objects) {
        const std::string tag = c.name();
        if (tag == "bsdf") {
            take_bsdf(c);
        } else if (tag == "ref") {
            const xml_node r = resolve(c);
            if (std::string(r.name()) == "bsdf") take_bsdf(c);
            else if (std::string(r.name()) == "texture") fail(c, "a shape cannot take a texture");
            // Other references (media) are reported by finish().
        } else if (tag == "emitter") {
            p.used.insert(c.internal_object());
            ++emitter_elements_;
            const std::string et = need_attr(c, "type");
            if (et != "area") {
                unsupported(c, "emitter type '" + et + "' on a shape (gdr's shapes emit as area lights)", "skips it");
                continue;
            }
            if (!is_black(radiance)) fail(c, "a shape takes one area emitter");
            Props ep = props(c);
            radiance = get_colour(ep, "radiance", Color(1.f));
            ignore(ep, {"sampling_weight"});
            finish(ep);
            if (!(radiance.r >= 0.f && radiance.g >= 0.f && radiance.b >= 0.f))
                fail(c, "radiance must be >= 0 per channel");
        }
    }
    if (!b) {
        if (!default_bsdf_) {
            default_bsdf_ = std::make_shared<BuiltBsdf>();
            default_bsdf_->bsdf = make_lambertian(make_constant_texture(Color(0.5f)));
            default_bsdf_->name = "(default diffuse 0.5)";
        }
        b = default_bsdf_;
    }
    const auto label = [&](const std::string& what) { return what + " '" + id + "'"; };
    // Mesh files (obj, ply, serialized): max_smooth_angle in degrees, checked as Mitsuba does.
    const auto smooth_angle = [&](bool face_normals, bool& given) {
        const float angle = get_float(p, "max_smooth_angle", 0.f, &given);
        if (given && face_normals) fail(n, "give either face_normals or max_smooth_angle, not both (as Mitsuba)");
        if (given && !(angle >= 0.f && angle <= 180.f))
            fail(p.named.at("max_smooth_angle"), "max_smooth_angle must lie in [0, 180] degrees");
        return angle;
    };
    // Published scenes are sometimes shipped without their largest meshes:
    // true when the mesh file is missing and the shape was dropped.
    const auto missing = [&](const std::string& file) {
        const std::string why = detail::not_a_file(file);
        if (why.empty()) return false;
        dropped(n, file + why + " (--lenient skips the shape with a warning)",
                file + why + "; the shape is skipped (--lenient)");
        return true;
    };
    if (type == "obj" || type == "ply") {
        const std::string name = get_string(p, "filename", "");
        if (name.empty()) fail(n, "needs a 'filename'");
        const bool face_normals = get_bool(p, "face_normals", false);
        const bool flip_uv = type == "obj" ? get_bool(p, "flip_tex_coords", true) : true;
        ignore(p, {"collapse"});
        bool angle_given = false;
        const float angle = smooth_angle(face_normals, angle_given);
        finish(p);
        const std::string file = file_path(n, name);
        if (missing(file)) return;
        const uint32_t mat = material_for(b, radiance, id, n);
        const size_t first = mesh_.size();
        if (type == "obj") load_obj_shape(n, file, face_normals, flip_uv, xf, flip, mat);
        else load_ply_shape(n, file, face_normals, xf, flip, mat);
        if (angle_given) crease_normals(first, angle);
        return;
    }
    if (type == "serialized") {
        const std::string name = get_string(p, "filename", "");
        if (name.empty()) fail(n, "needs a 'filename'");
        const long long index = get_int(p, "shape_index", 0);
        if (index < 0) fail(p.named.at("shape_index"), "shape_index must be >= 0");
        const bool face_normals = get_bool(p, "face_normals", false);
        bool angle_given = false;
        const float angle = smooth_angle(face_normals, angle_given);
        finish(p);
        const std::string file = file_path(n, name);
        if (missing(file)) return;
        SerializedMesh sm;
        try {
            sm = serialized_file(file).mesh(size_t(index));
        } catch (const InputError& e) {
            serialized_.erase(file);
            const std::string what = e.what();
            fail(n, what.find("shape index") == std::string::npos ? fmt::format("{} (reading shape index {})", what, index)
                                                                  : what);
        }
        // Vertex colours are read but unused: gdr has no per-vertex colour
        // (Mitsuba shows them only through a vertexcolors texture).
        detail::IndexedMesh m{std::move(sm.positions), std::move(sm.normals), std::move(sm.uvs), std::move(sm.colors),
                              std::move(sm.indices)};
        const uint32_t mat = material_for(b, radiance, id, n);
        add_indexed(std::move(m), xf, flip, face_normals || sm.face_normals, angle_given ? angle : -1.f, mat,
                    fmt::format("{}@{}", file, index));
        return;
    }
    if (type == "cylinder") {
        const Vec3 p0 = get_point(p, "p0", Vec3(0.f)), p1 = get_point(p, "p1", Vec3(0.f, 0.f, 1.f));
        const float r = get_float(p, "radius", 1.f);
        if (!(r > 0.f)) fail(n, "radius must be positive");
        if (!(glm::length(p1 - p0) > 0.f)) fail(n, "p0 and p1 coincide");
        finish(p);
        const uint32_t mat = material_for(b, radiance, id, n);
        add_indexed(detail::cylinder_mesh(p0, p1, r, kCylinderSegments), xf, flip, false, -1.f, mat, label(type));
        return;
    }
    std::vector<Vec3> pos, nrm;
    std::vector<Vec2> uv;  // gdr's convention: (u, 1 - v) of Mitsuba's
    const auto corner = [&](const Vec3& q, const Vec3& nn, const Vec2& muv) {
        pos.push_back(q), nrm.push_back(nn), uv.emplace_back(muv.x, 1.f - muv.y);
    };
    Mat4 shape_xf = xf;
    if (type == "rectangle") {
        const Vec3 c[4] = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
        const Vec2 t[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        for (int k : {0, 1, 2, 0, 2, 3}) corner(c[k], Vec3(0, 0, 1), t[k]);
    } else if (type == "cube") {
        for (int axis = 0; axis < 3; ++axis)
            for (float s : {-1.f, 1.f}) {
                Vec3 nn(0.f), t1(0.f), t2(0.f);
                nn[axis] = s, t1[(axis + 1) % 3] = s, t2[(axis + 2) % 3] = 1.f;
                const Vec3 c[4] = {nn - t1 - t2, nn + t1 - t2, nn + t1 + t2, nn - t1 + t2};
                const Vec2 t[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
                for (int k : {0, 1, 2, 0, 2, 3}) corner(c[k], nn, t[k]);
            }
    } else if (type == "sphere") {
        const Vec3 center = get_point(p, "center", Vec3(0.f));
        const float r = get_float(p, "radius", 1.f);
        if (!(r > 0.f)) fail(n, "radius must be positive");
        shape_xf = xf * glm::translate(Mat4(1.f), center) * glm::scale(Mat4(1.f), Vec3(r));
        // A UV sphere with its poles on the local y axis, as the shared scenes' conversions.
        const auto at = [](int i, int j) {
            const float th = kPi * float(j) / float(kSphereRings), ph = 2.f * kPi * float(i) / float(kSphereSegments);
            return Vec3(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
        };
        const auto tex = [](int i, int j) { return Vec2(float(i) / kSphereSegments, float(j) / kSphereRings); };
        for (int j = 0; j < kSphereRings; ++j)
            for (int i = 0; i < kSphereSegments; ++i) {
                const int a[2] = {i, j}, b2[2] = {i, j + 1}, c[2] = {i + 1, j + 1}, d[2] = {i + 1, j};
                if (j + 1 < kSphereRings)  // below the south pole's ring this triangle is degenerate
                    for (const int* v : {a, c, b2}) corner(at(v[0], v[1]), at(v[0], v[1]), tex(v[0], v[1]));
                if (j > 0)  // at the north pole likewise
                    for (const int* v : {a, d, c}) corner(at(v[0], v[1]), at(v[0], v[1]), tex(v[0], v[1]));
            }
    } else {  // disk
        for (int i = 0; i < kDiskSegments; ++i) {
            const float p0 = 2.f * kPi * float(i) / kDiskSegments, p1 = 2.f * kPi * float(i + 1) / kDiskSegments;
            const float mid = (float(i) + 0.5f) / kDiskSegments;
            corner(Vec3(0.f), Vec3(0, 0, 1), Vec2(0.f, mid));
            corner(Vec3(std::cos(p0), std::sin(p0), 0.f), Vec3(0, 0, 1), Vec2(1.f, float(i) / kDiskSegments));
            corner(Vec3(std::cos(p1), std::sin(p1), 0.f), Vec3(0, 0, 1), Vec2(1.f, float(i + 1) / kDiskSegments));
        }
    }
    finish(p);
    const uint32_t mat = material_for(b, radiance, id, n);
    add_triangles(pos, std::move(nrm), uv, shape_xf, flip, mat, label(type));
}

void Importer::emitter(xml_node n) {
    ++emitter_elements_;
    const std::string type = need_attr(n, "type");
    if (type == "constant" || type == "envmap") {
        if (environment_) fail(n, "a scene takes one environment emitter (constant or envmap)");
        Props p = props(n);
        // The sampling weight changes only how often the light is sampled, not the image.
        ignore(p, {"sampling_weight"});
        const float scale = get_float(p, "scale", 1.f);
        if (!std::isfinite(scale) || scale < 0.f) fail(n, "'scale' must be finite and non-negative");
        try {
            if (type == "constant") {
                const Color l = get_colour(p, "radiance", Color(1.f)) * scale;
                if (!is_finite(l)) fail(n, "radiance times scale is beyond float range");
                finish(p);
                environment_ = Environment::constant(l);
            } else {
                const std::string name = get_string(p, "filename", "");
                if (name.empty()) fail(n, "an envmap needs a 'filename'");
                const std::string file = file_path(n, name);
                std::string ext = fs::path(file).extension().string();
                for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
                // Mitsuba reads any bitmap: float files (EXR, Radiance .hdr)
                // are linear; 8-bit ones sRGB unless `gamma` says otherwise
                // (1 linear, -1 sRGB, else a power law), as for bitmap textures.
                const bool exr = ext == ".exr";
                bool gamma_given = false;
                const float gamma = get_float(p, "gamma", -1.f, &gamma_given);
                ImageTextureOptions io;
                if (gamma_given && gamma == 1.f) {
                    io.srgb = false;
                } else if (gamma_given && gamma != -1.f) {
                    if (!(gamma > 0.f) || !std::isfinite(gamma))
                        fail(p.named.at("gamma"), "gamma must be positive, or -1 for sRGB");
                    io.gamma = gamma;
                }
                if (exr && gamma_given && gamma != 1.f)
                    warn(n, fmt::format("gamma {} is ignored: an EXR map is read as linear radiance", gamma));
                ignore(p, {"cache", "filter_type", "mis_compensation"});
                const Mat4 xf = get_transform(p, "to_world");
                finish(p);
                inputs_.push_back(file);
                environment_ = Environment::from_map(exr ? read_exr_rgb(file) : read_image_rgb(file, io),
                                                     glm::mat3(mirror_ * xf), scale, file);
            }
        } catch (const InputError& e) {
            // Errors of the map or its values, placed at the element.
            if (std::string(e.what()).rfind(doc_of(n).file, 0) == 0) throw;
            fail(n, e.what());
        }
        return;
    }
    if (type == "sunsky" || type == "sky" || type == "sun") {
        if (environment_) fail(n, "a scene takes one environment emitter (constant, envmap, sky, sun or sunsky)");
        Props p = props(n);
        SkyParams sp;
        sp.turbidity = get_float(p, "turbidity", 3.f);
        // Mitsuba 0.6's sky reads a default ground albedo of 0.2 (its
        // documentation says 0.15); its renders are the reference.
        if (type != "sun") sp.albedo = get_colour(p, "albedo", Color(0.2f));
        const long long res = get_int(p, "resolution", 512);
        sp.resolution = int(std::clamp<long long>(res, -1, 1 << 20));
        const float scale = get_float(p, "scale", 1.f);
        if (!std::isfinite(scale) || scale < 0.f) fail(n, "'scale' must be finite and non-negative");
        if (type == "sunsky") {
            sp.sky_scale = get_float(p, "sky_scale", 1.f) * scale;
            sp.sun_scale = get_float(p, "sun_scale", 1.f) * scale;
        } else {
            sp.sky_scale = type == "sky" ? scale : 0.f;
            sp.sun_scale = type == "sun" ? scale : 0.f;
        }
        if (type != "sky") sp.sun_radius_scale = get_float(p, "sun_radius_scale", 1.f);
        sp.stretch = get_float(p, "stretch", 1.f);
        if (!(sp.stretch >= 1.f && sp.stretch <= 2.f)) fail(n, fmt::format("'stretch' {} must be in [1, 2]", sp.stretch));
        if (type != "sun") sp.extend = get_bool(p, "extend", false);
        ignore(p, {"sampling_weight"});
        const glm::mat3 xf = glm::mat3(mirror_ * get_transform(p, "to_world"));
        const xml_node sun_node = take(p, "sun_direction");
        if (sun_node) {
            expect_tag(sun_node, {"vector", "point"});
            // A world direction, taken to the emitter's frame.
            sp.sun_dir = glm::transpose(xf) * xyz(sun_node, 0.f);
            for (const char* k : {"year", "month", "day", "hour", "minute", "second", "latitude", "longitude", "timezone"})
                if (xml_node t = take(p, k))
                    fail(t, std::string("'") + k + "' and 'sunDirection' are both given: give one or the other");
        } else {
            const auto num = [&](const char* k, double def) { return double(get_float(p, k, float(def))); };
            // Mitsuba's defaults: 10 July 2010, 15:00, Tokyo (UTC+9).
            const int year = int(num("year", 2010)), month = int(num("month", 7)), day = int(num("day", 10));
            if (month < 1 || month > 12 || day < 1 || day > 31)
                fail(n, fmt::format("date {}-{}-{} is not a calendar date", year, month, day));
            sp.sun_dir = sun_direction_at(year, month, day, num("hour", 15), num("minute", 0), num("second", 0),
                                          num("latitude", 35.6894), num("longitude", 139.6917), num("timezone", 9));
        }
        finish(p);
        try {
            // sunRadiusScale 0: the sun is a directional light, as in Mitsuba.
            if (sp.sun_radius_scale == 0.f && sp.sun_scale > 0.f) {
                DeltaLight l;
                l.kind = DeltaLight::Kind::Directional;
                l.direction = -glm::normalize(xf * drawn_sun_direction(sp));
                l.intensity = sun_irradiance(sp);
                delta_lights_.push_back(l);
            }
            if (sp.sky_scale > 0.f || sp.sun_radius_scale > 0.f)
                environment_ = Environment::from_map(bake_sky(sp), xf, 1.f, doc_of(n).file + ": " + type);
        } catch (const Error& e) {
            fail(n, e.what());
        }
        return;
    }
    if (type == "point" || type == "spot" || type == "directional") {
        delta_emitter(n, type);
        return;
    }
    if (type == "area") fail(n, "an area emitter belongs inside a <shape>");
    unsupported(n, "emitter type '" + type + "' (gdr renders area, environment, point, spot and directional lights)",
                "skips it");
}

// Mitsuba's delta emitters (its documentation of `point`, `spot` and
// `directional`): a point or spot light sits at to_world's origin (or
// `position`), a spot looks along to_world's +z with `cutoff_angle` (20
// degrees) and `beam_width` (3/4 of the cutoff) in degrees, its radiant
// `intensity` in W/sr; a directional light travels along to_world's +z (or
// `direction`), its `irradiance` in W/m^2.
void Importer::delta_emitter(xml_node n, const std::string& type) {
    Props p = props(n);
    ignore(p, {"sampling_weight"});  // how often it is sampled, not the image
    const Mat4 xf = get_transform(p, "to_world");
    DeltaLight l;
    const auto colour = [&](const char* name) {
        if (xml_node t = take(p, name); t) {
            const std::string tag = t.name();
            if (tag == "texture" || tag == "ref")
                fail(t, "a texture for the " + type + " emitter's '" + name + "' is not supported (give a colour)");
            const Color c = colour_of(t);
            if (!is_finite(c) || c.r < 0.f || c.g < 0.f || c.b < 0.f)
                fail(t, std::string("'") + name + "' must be finite and non-negative");
            return c;
        }
        return Color(1.f);
    };
    if (type == "directional") {
        l.kind = DeltaLight::Kind::Directional;
        l.direction = get_point(p, "direction", Vec3(xf * glm::vec4(0.f, 0.f, 1.f, 0.f)));
        l.intensity = colour("irradiance");
    } else {
        l.kind = type == "point" ? DeltaLight::Kind::Point : DeltaLight::Kind::Spot;
        l.position = get_point(p, "position", Vec3(xf * glm::vec4(0.f, 0.f, 0.f, 1.f)));
        l.intensity = colour("intensity");
        if (type == "spot") {
            if (p.named.count("texture")) {
                auto t = get_texture(p, "texture", Color(1.f));
                if (!t->is_constant()) l.texture = std::move(t);  // Mitsuba too ignores a constant one
            }
            l.direction = Vec3(xf * glm::vec4(0.f, 0.f, 1.f, 0.f));
            l.axis_x = Vec3(xf * glm::vec4(1.f, 0.f, 0.f, 0.f)), l.axis_y = Vec3(xf * glm::vec4(0.f, 1.f, 0.f, 0.f));
            const float cutoff = get_float(p, "cutoff_angle", 20.f);
            const float beam = get_float(p, "beam_width", 0.75f * cutoff);
            if (!(cutoff > 0.f && cutoff <= 180.f)) fail(n, "the spot's 'cutoff_angle' must be in (0, 180] degrees");
            if (!(beam > 0.f)) fail(n, "the spot's 'beam_width' must be positive");
            // Mitsuba's falloff is full intensity wherever the beam is at least as wide as the cutoff.
            l.cutoff = glm::radians(cutoff), l.beam_width = glm::radians(std::min(beam, cutoff));
        }
    }
    finish(p);
    if (l.kind != DeltaLight::Kind::Point && !(glm::length(l.direction) > 0.f))
        fail(n, "the " + type + " emitter's direction is zero");
    delta_lights_.push_back(l);
}

SceneFile Importer::run() {
    params_ = opt_.defines;
    load_doc(path_, {});
    const xml_node scene = docs_.front().xml.document_element();
    if (scene.attribute("version")) {
        const std::string v = raw(scene, "version");
        int major = 0;
        const auto r = std::from_chars(v.data(), v.data() + v.size(), major);
        if (r.ec != std::errc() || major < 0 || major > 3)
            fail(scene, "unsupported scene version '" + v + "' (gdr reads Mitsuba 0.6 to 3.x)");
        version_major_ = major;
    }
    std::vector<xml_node> top;
    collect(scene, 0, top);
    for (xml_node n : top) {
        if (n.attribute("id") && std::string(n.name()) != "ref") {
            const std::string id = attr(n, "id");
            const auto [it, fresh] = ids_.emplace(id, n);
            if (!fresh) fail(n, fmt::format("id '{}' is given twice (also at line {})", id, line_of(it->second)));
        }
        index_ids(n);
    }
    // The sensor first: a mirroring one reflects everything after it.
    for (xml_node n : top)
        if (std::string(n.name()) == "sensor") sensor(n);
    for (xml_node n : top) {
        const std::string tag = n.name();
        if (tag == "sensor") continue;
        else if (tag == "integrator") integrator(n);
        else if (tag == "shape") shape(n);
        else if (tag == "bsdf") bsdf(n);
        else if (tag == "texture") texture(n);
        else if (tag == "emitter") emitter(n);
        else if (tag == "medium" || tag == "phase" || tag == "volume" || tag == "subsurface" || tag == "alias" ||
                 tag == "path" || tag == "null")
            unsupported(n, "unsupported element <" + tag + ">", "skips it");
        else fail(n, "unknown element <" + tag + ">");
    }
    for (const auto& [name, value] : opt_.defines)
        if (!used_params_.count(name))
            throw InputError(path_ + ": -D " + name + "=" + value +
                             (declared_.count(name) ? ": the scene declares $" + name + " but uses it nowhere"
                                                    : ": the scene has no parameter $" + name));
    if (!strict_errors_.empty()) throw InputError(grouped_report(strict_errors_, true));
    if (!have_sensor_) throw InputError(path_ + ": the scene has no <sensor> (gdr needs a perspective camera)");
    if (mesh_.size() == 0) {
        if (shape_elements_ == 0) throw InputError(path_ + ": the scene has no shapes");
        throw InputError(fmt::format("{}: every shape was dropped ({} <shape> element{}), nothing is left to render:\n{}",
                                     path_, shape_elements_, shape_elements_ == 1 ? "" : "s",
                                     grouped_report(warnings_, false)));
    }

    if (mirrored_) mirror_world();
    SceneFile sf;
    sf.path = path_;
    Camera camera;
    try {
        camera = Camera(camera_);
    } catch (const Error& e) {
        throw InputError(path_ + ": <sensor>: " + e.what());
    }
    sf.defaults = defaults_;
    sf.defaults.params = Params(path_);
    for (const auto& [k, v] : int_params_) sf.defaults.params.set(k, v);
    sf.meshes = std::move(stats_);
    sf.scene = std::make_unique<Scene>(std::move(mesh_), std::move(materials_), camera, path_);
    if (environment_) sf.scene->set_environment(std::move(environment_));
    if (!delta_lights_.empty()) sf.scene->set_delta_lights(std::move(delta_lights_), path_);
    // A scene whose lights were all dropped renders black: not a result.
    if (emitter_elements_ > 0 && !sf.scene->has_lights())
        throw InputError(fmt::format("{}: every emitter was dropped ({} <emitter> element{}), the image would be "
                                     "black:\n{}",
                                     path_, emitter_elements_, emitter_elements_ == 1 ? "" : "s",
                                     grouped_report(warnings_, false)));
    std::set<std::string> seen;
    for (std::string& f : inputs_)
        if (seen.insert(f).second) sf.inputs.push_back(std::move(f));
    sf.content_hash = scene_content_hash(path_, sf.inputs);
    if (!opt_.text.empty()) {
        // No file holds the scene: its text is hashed with the files it read (FNV-1a 64).
        uint64_t h = 0xcbf29ce484222325ull;
        for (const unsigned char c : opt_.text + '\0' + sf.content_hash) h = (h ^ c) * 0x100000001b3ull;
        sf.content_hash = fmt::format("{:016x}", h);
    }
    if (!opt_.defines.empty()) {
        // -D values make another scene of the same files: they are hashed too (FNV-1a 64).
        std::string key = sf.content_hash;
        for (const auto& [name, value] : opt_.defines) key += '\0' + name + '=' + value;
        uint64_t h = 0xcbf29ce484222325ull;
        for (const unsigned char c : key) h = (h ^ c) * 0x100000001b3ull;
        sf.content_hash = fmt::format("{:016x}", h);
    }
    // Repeated warnings once each, with their count and places.
    const std::string report = grouped_report(warnings_, false);
    for (size_t b = 0; b < report.size();) {
        size_t e = report.find('\n', b);
        if (e == std::string::npos) e = report.size();
        sf.warnings.push_back(report.substr(b, e - b));
        b = e + 1;
    }
    return sf;
}

// Warnings: one line per distinct message, "where: what" when it occurs
// once, else the first place, the message and the count, then up to 8 more
// places. Errors (the strict mode's unsupported elements): headed by their
// count, one line each.
std::string Importer::grouped_report(const std::vector<std::pair<std::string, std::string>>& items, bool errors) const {
    if (errors && items.size() == 1) return items[0].first + ": " + items[0].second;
    if (errors) {
        std::set<std::string> distinct;
        for (const auto& it : items) distinct.insert(it.second);
        std::string out = fmt::format("{}: {} unsupported elements and properties ({} distinct), each an error without "
                                      "--lenient:",
                                      path_, items.size(), distinct.size());
        for (const auto& [at, what] : items) out += "\n  " + at + ": " + what;
        return out;
    }
    std::vector<std::string> order;
    std::map<std::string, std::vector<std::string>> places;
    for (const auto& [at, what] : items) {
        auto& v = places[what];
        if (v.empty()) order.push_back(what);
        v.push_back(at);
    }
    std::string out;
    const size_t shown = 9;
    for (const std::string& what : order) {
        const auto& v = places.at(what);
        std::string line = v[0] + ": " + what;
        if (v.size() > 1) {
            line += fmt::format(" [{} times; also at ", v.size());
            for (size_t i = 1; i < v.size() && i < shown; ++i) {
                // The place without the element text after the line number: "file:line".
                const size_t colon = v[i].find(':', v[i].rfind('/') == std::string::npos ? 0 : v[i].rfind('/'));
                const size_t end = colon == std::string::npos ? std::string::npos : v[i].find(':', colon + 1);
                line += (i > 1 ? ", " : "") + (end == std::string::npos ? v[i] : v[i].substr(0, end));
            }
            if (v.size() > shown) line += fmt::format(", and {} more", v.size() - shown);
            line += "]";
        }
        if (!out.empty()) out += '\n';
        out += line;
    }
    return out;
}

}  // namespace mitsuba_import

using namespace mitsuba_import;

Color conductor_reflectance(const Color& eta, const Color& k) {
    Color f;
    for (int i = 0; i < 3; ++i) {
        const float e = eta[i], kk = k[i];
        f[i] = ((e - 1.f) * (e - 1.f) + kk * kk) / ((e + 1.f) * (e + 1.f) + kk * kk);
    }
    return f;
}

bool named_conductor_ior(const std::string& name, ConductorIor& ior) {
    for (const NamedConductor& c : kConductors)
        if (name == c.name) return ior = {Color(c.eta), Color(c.k)}, true;
    return false;
}

bool named_conductor_reflectance(const std::string& name, Color& f0) {
    ConductorIor c;
    if (!named_conductor_ior(name, c)) return false;
    f0 = conductor_reflectance(c.eta, c.k);
    return true;
}

SceneFile load_mitsuba_scene(const std::string& path, const SceneFileOptions& options) {
    Importer imp(path, options);
    try {
        return imp.run();
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        // Nothing else should escape, but a malformed file must never end the process.
        throw InputError(path + ": " + e.what());
    }
}

}  // namespace gdr
