// The Mitsuba importer's BSDFs and textures: each <bsdf> and <texture>
// element built once (a <ref> shares it) from its properties, as Mitsuba
// 0.5/0.6 and 3.x define the plugins (docs/scenes.md lists them).
#include "mitsuba_importer.h"

namespace gdr::mitsuba_import {

// ---------------------------------------------------------------- BSDFs and textures

/// A microfacet BSDF's distribution: GGX and Beckmann as Mitsuba defines
/// them; Mitsuba's Phong microfacet distribution (a near-twin of Beckmann)
/// and Ashikhmin-Shirley are rendered as Beckmann of the same alpha.
MicrofacetType Importer::microfacet_type(Props& p, const std::string& def) {
    const xml_node dn = p.named.count("distribution") ? p.named.at("distribution") : xml_node();
    const std::string d = get_string(p, "distribution", def);
    if (d == "ggx") return MicrofacetType::GGX;
    if (d == "beckmann") return MicrofacetType::Beckmann;
    if (d == "phong" || d == "as") {
        warn(dn ? dn : p.owner, "microfacet distribution '" + d + "' is rendered as Beckmann of the same alpha");
        return MicrofacetType::Beckmann;
    }
    fail(dn ? dn : p.owner, "unknown microfacet distribution '" + d + "' (expected ggx or beckmann)");
}

/// A dielectric's specular_reflectance or specular_transmittance: null when
/// absent or white, so the BSDF skips the lookup.
std::shared_ptr<Texture> Importer::tint_texture(Props& p, const std::string& name) {
    if (!p.named.count(name)) return nullptr;
    auto t = get_texture(p, name, Color(1.f));
    if (t->is_constant() && t->mean() == Color(1.f)) return nullptr;
    return t;
}

/// A scalar property that Mitsuba also accepts as a texture (a roughness, an
/// exponent): a texture that varies over the surface is taken at its mean,
/// with a note, since gdr's shift mappings classify a BSDF by one roughness.
float Importer::scalar_param(Props& p, const std::string& name, float def) {
    const xml_node e = p.named.count(name) ? p.named.at(name) : xml_node();
    const auto t = get_texture(p, name, Color(def));
    const float v = t->mean().r;
    if (!t->is_constant()) unsupported(e, "a texture for '" + name + "'", fmt::format("uses its mean {}", v));
    if (!(v >= 0.f)) fail(e ? e : p.owner, "'" + name + "' must be >= 0");
    return v;
}

/// Roughness properties on a smooth BSDF: Mitsuba 0.5/0.6 never reads them
/// (it only warns of unqueried properties) and renders the surface smooth, so
/// gdr does the same with a warning; Mitsuba 3 refuses them, and so do
/// strict loads of 3.x files here (finish() reports them).
void Importer::ignore_smooth_roughness(xml_node n, Props& p) {
    if (version_major_ >= 2) return;
    for (const char* k : {"alpha", "alpha_u", "alpha_v", "distribution", "sample_visible"}) {
        if (const xml_node c = take(p, k))
            warn(c, std::string("'") + k + "' on a smooth " + attr(n, "type") +
                        " is ignored, as Mitsuba 0.6 ignores it: the surface is smooth");
    }
}

/// Mitsuba's modified Phong: diffuse_reflectance (0.5), specular_reflectance
/// (0.2), exponent (30).
std::shared_ptr<Bsdf> Importer::build_phong(Props& p) {
    auto kd = get_texture(p, "diffuse_reflectance", Color(0.5f));
    auto ks = get_texture(p, "specular_reflectance", Color(0.2f));
    return make_phong(std::move(kd), std::move(ks), scalar_param(p, "exponent", 30.f));
}

/// Mitsuba's Ward: variant (balanced; ward, ward-duer), diffuse_reflectance
/// (0.5), specular_reflectance (0.2), roughness alpha_u = alpha_v (0.1).
std::shared_ptr<Bsdf> Importer::build_ward(Props& p, float alpha) {
    const xml_node vn = p.named.count("variant") ? p.named.at("variant") : xml_node();
    const std::string v = get_string(p, "variant", "balanced");
    WardVariant variant = WardVariant::Balanced;
    if (v == "ward") variant = WardVariant::Ward;
    else if (v == "ward-duer") variant = WardVariant::WardDuer;
    else if (v != "balanced") fail(vn, "unknown Ward variant '" + v + "' (expected ward, ward-duer or balanced)");
    auto kd = get_texture(p, "diffuse_reflectance", Color(0.5f));
    auto ks = get_texture(p, "specular_reflectance", Color(0.2f));
    if (!(alpha > 0.f)) fail(p.owner, "Ward's roughness must be positive");
    return make_ward(std::move(kd), std::move(ks), alpha, variant);
}

/// Mitsuba's roughdiffuse (Oren-Nayar): alpha (0.2), use_fast_approx (false).
std::shared_ptr<Bsdf> Importer::build_rough_diffuse(Props& p, std::shared_ptr<Texture> kd) {
    const float alpha = scalar_param(p, "alpha", 0.2f);
    const bool fast = get_bool(p, "use_fast_approx", false);
    return make_oren_nayar(std::move(kd), alpha, fast);
}

std::shared_ptr<BuiltBsdf> Importer::bsdf(xml_node n) {
    if (std::string(n.name()) == "ref") {
        const xml_node b = resolve(n);
        if (std::string(b.name()) != "bsdf") fail(n, "refers to " + describe(b) + ", not a <bsdf>");
        n = b;
    }
    const auto it = bsdfs_.find(n.internal_object());
    if (it != bsdfs_.end()) return it->second;
    begin_building(n);
    auto b = build_bsdf(n);
    building_.erase(n.internal_object());
    if (b->name.empty()) b->name = n.attribute("id") ? attr(n, "id") : fmt::format("{} (line {})", attr(n, "type"), line_of(n));
    bsdfs_[n.internal_object()] = b;
    return b;
}

std::shared_ptr<BuiltBsdf> Importer::build_bsdf(xml_node n) {
    const std::string type = need_attr(n, "type");
    Props p = props(n);
    auto b = std::make_shared<BuiltBsdf>();
    const auto nested = [&](bool required) -> std::shared_ptr<BuiltBsdf> {
        std::vector<xml_node> kids;
        for (xml_node c : p.objects)
            if (std::string(c.name()) == "bsdf" || std::string(c.name()) == "ref") kids.push_back(c);
        if (kids.empty()) {
            if (required) fail(n, "needs a nested <bsdf> (or <ref>)");
            return nullptr;
        }
        p.used.insert(kids[0].internal_object());
        return bsdf(kids[0]);
    };
    const auto distribution = [&](const std::string& def) { return microfacet_type(p, def); };
    const auto roughness = [&](float def) {
        ignore(p, {"sample_visible"});
        // Roughness textures are taken at their mean (scalar_param).
        const bool given_u = p.named.count("alpha_u") > 0, given_v = p.named.count("alpha_v") > 0;
        const float a = scalar_param(p, "alpha", def);
        const float au = given_u ? scalar_param(p, "alpha_u", a) : a, av = given_v ? scalar_param(p, "alpha_v", a) : a;
        if (given_u != given_v) fail(n, "give both alpha_u and alpha_v");
        float alpha = a;
        if (given_u) {
            alpha = std::sqrt(au * av);
            if (au != av) warn(n, fmt::format("anisotropic roughness ({}, {}) is rendered isotropic, alpha {}", au, av, alpha));
        }
        if (!(alpha >= 0.f)) fail(n, "roughness alpha must be >= 0");
        return alpha;
    };

    if (type == "dielectric" || type == "thindielectric" || type == "conductor" || type == "plastic")
        ignore_smooth_roughness(n, p);
    if (type == "diffuse" || type == "roughdiffuse") {
        // 0.6 also takes the name diffuseReflectance.
        if (p.named.count("reflectance") && p.named.count("diffuse_reflectance"))
            fail(n, "give either reflectance or diffuse_reflectance");
        auto kd = get_texture(p, p.named.count("diffuse_reflectance") ? "diffuse_reflectance" : "reflectance", Color(0.5f));
        if (type == "roughdiffuse") b->bsdf = build_rough_diffuse(p, std::move(kd));
        else b->bsdf = make_lambertian(std::move(kd));
    } else if (type == "conductor") {
        const ConductorIor c = conductor_ior(p, n);
        b->bsdf = make_conductor(c, glm::clamp(get_colour(p, "specular_reflectance", Color(1.f)), Color(0.f), Color(1.f)));
    } else if (type == "roughconductor") {
        const MicrofacetType md = distribution("beckmann");
        const float alpha = roughness(0.1f);
        const ConductorIor c = conductor_ior(p, n);
        std::shared_ptr<Texture> spec = get_texture(p, "specular_reflectance", Color(1.f));
        if (alpha < kMinGgxAlpha) {
            if (!spec->is_constant())
                unsupported(p.named.at("specular_reflectance"), "a textured reflectance on a smooth conductor", "uses its mean");
            b->bsdf = make_conductor(c, glm::clamp(spec->mean(), Color(0.f), Color(1.f)));
        } else {
            b->bsdf = make_rough_conductor(c, alpha, md, spec->is_constant() ? make_constant_texture(glm::clamp(spec->mean(), Color(0.f), Color(1.f))) : spec);
        }
    } else if (type == "dielectric" || type == "thindielectric" || type == "roughdielectric") {
        const float eta = ior(p, "int_ior", 1.5046f) / ior(p, "ext_ior", 1.00028f);
        auto r = tint_texture(p, "specular_reflectance"), t = tint_texture(p, "specular_transmittance");
        if (type == "dielectric") {
            b->bsdf = make_dielectric(eta, std::move(r), std::move(t));
        } else if (type == "thindielectric") {
            b->bsdf = make_thin_dielectric(eta, std::move(r), std::move(t));
        } else {
            const MicrofacetType md = distribution("beckmann");
            const float alpha = roughness(0.1f);
            b->bsdf = alpha < kMinGgxAlpha ? make_dielectric(eta, std::move(r), std::move(t))
                                           : make_rough_dielectric(eta, alpha, std::move(r), std::move(t), md);
        }
    } else if (type == "plastic" || type == "roughplastic") {
        float alpha = kSmoothPlasticAlpha;
        MicrofacetType md = MicrofacetType::GGX;
        if (type == "roughplastic") {
            md = distribution("beckmann");
            alpha = std::max(roughness(0.1f), kMinGgxAlpha);
        }
        const float eta = ior(p, "int_ior", 1.49f) / ior(p, "ext_ior", 1.00028f);
        const bool nonlinear = get_bool(p, "nonlinear", false);
        const Color spec = get_colour(p, "specular_reflectance", Color(1.f));
        auto kd = get_texture(p, "diffuse_reflectance", Color(0.5f));
        b->bsdf = make_coated_plastic(std::move(kd), glm::clamp(spec, Color(0.f), Color(1.f)), eta, alpha, md, nonlinear);
    } else if (type == "phong") {
        b->bsdf = build_phong(p);
    } else if (type == "ward") {
        const float alpha = roughness(0.1f);
        b->bsdf = build_ward(p, alpha);
    } else if (type == "twosided") {
        int count = 0;
        for (xml_node c : p.objects)
            count += std::string(c.name()) == "bsdf" || std::string(c.name()) == "ref";
        if (count > 1) unsupported(n, "a twosided BSDF with a different BSDF on each side", "uses the first on both");
        // gdr's reflective BSDFs are two-sided already: the nested one is the BSDF.
        const auto inner = nested(true);
        b->bsdf = inner->bsdf;
        b->opacity = inner->opacity;
        for (xml_node c : p.objects) p.used.insert(c.internal_object());
    } else if (type == "mask") {
        const auto inner = nested(true);
        b->bsdf = inner->bsdf;
        const xml_node o = p.named.count("opacity") ? p.named.at("opacity") : xml_node();
        if (!o) {
            b->opacity = make_constant_texture(Color(0.5f));  // Mitsuba's default: half transparent
        } else if (std::string(o.name()) == "texture" || std::string(o.name()) == "ref") {
            take(p, "opacity");
            xml_node t = std::string(o.name()) == "ref" ? resolve(o) : o;
            if (std::string(t.name()) != "texture") fail(o, "refers to " + describe(t) + ", not a <texture>");
            b->opacity = opacity_texture(t);
        } else {
            take(p, "opacity");
            // A fractional opacity lets rays through with probability 1 - opacity (Material::opacity).
            b->opacity = make_constant_texture(colour_of(o));
        }
    } else if (type == "bumpmap" || type == "normalmap") {
        // A nested texture (the height, or the tangent-space normal) and a
        // nested BSDF, either as <ref>; Mitsuba 0.6 scales a height with a
        // `scale` texture around it, Mitsuba 3 with a `scale` property.
        std::shared_ptr<BuiltBsdf> inner;
        std::shared_ptr<Texture> map;
        const auto consider = [&](xml_node c) {
            const xml_node t = std::string(c.name()) == "ref" ? resolve(c) : c;
            const std::string kind = t.name();
            if (kind == "texture" && !map) map = texture(t);
            else if (kind == "bsdf" && !inner) inner = bsdf(t);
            else return;
            p.used.insert(c.internal_object());
        };
        for (xml_node c : p.objects) consider(c);
        for (auto& [name, c] : p.named)
            if (name != "scale" && (std::string(c.name()) == "texture" || std::string(c.name()) == "ref")) consider(c);
        if (!inner) fail(n, "needs a nested <bsdf> (or <ref>)");
        if (!map) fail(n, "needs a nested <texture> (or <ref>): the " + std::string(type == "bumpmap" ? "height" : "normal") + " map");
        if (inner->bump || inner->normal_map) unsupported(n, "a " + type + " around another bump or normal map", "keeps the outer one only");
        b->bsdf = inner->bsdf, b->opacity = inner->opacity;
        if (type == "bumpmap") {
            const float scale = p.named.count("scale") ? scalar_param(p, "scale", 1.f) : 1.f;
            b->bump = scale == 1.f ? map : make_scaled_texture(map, Color(scale));
        } else {
            b->normal_map = map;
        }
    } else if (type == "coating") {
        const auto inner = nested(true);
        const float eta = ior(p, "int_ior", 1.5046f) / ior(p, "ext_ior", 1.00028f);
        const float thickness = scalar_param(p, "thickness", 1.f);
        if (!(thickness >= 0.f) || !std::isfinite(thickness)) fail(n, "thickness must be finite and >= 0");
        const auto sigma = get_texture(p, "sigma_a", Color(0.f));
        if (!sigma->is_constant()) warn(n, "a textured sigma_a is taken at its mean");
        auto spec = tint_texture(p, "specular_reflectance");
        b->opacity = inner->opacity, b->bump = inner->bump, b->normal_map = inner->normal_map;
        // Over a glass, what it transmits leaves through a like interface on the other side, as in Mitsuba.
        b->bsdf = make_coating(inner->bsdf, eta, sigma->mean() * thickness, std::move(spec));
    } else if (type == "blendbsdf" || type == "mixturebsdf") {
        // Every nested BSDF, in order.
        std::vector<std::shared_ptr<Bsdf>> parts;
        for (xml_node c : p.objects) {
            if (std::string(c.name()) != "bsdf" && std::string(c.name()) != "ref") continue;
            p.used.insert(c.internal_object());
            const auto part = bsdf(c);
            if (part->opacity || part->bump || part->normal_map)
                unsupported(c, "a mask, bump map or normal map inside a " + type, "renders the BSDF without it");
            parts.push_back(part->bsdf);
        }
        if (type == "blendbsdf") {
            if (parts.size() != 2) fail(n, fmt::format("a blendbsdf blends two nested BSDFs, got {}", parts.size()));
            b->bsdf = make_blend(parts[0], parts[1], get_texture(p, "weight", Color(0.5f)));
        } else {
            // Mitsuba's "weights": a comma- or space-separated list, one per BSDF.
            const xml_node wn = p.named.count("weights") ? p.named.at("weights") : n;
            std::vector<float> w;
            for (double v : numbers(wn, get_string(p, "weights", ""), "'weights'")) {
                if (!(v >= 0.0)) fail(wn, fmt::format("'{}' is not a weight (a number >= 0)", v));
                w.push_back(float(v));
            }
            if (w.size() != parts.size())
                fail(n, fmt::format("a mixturebsdf needs one weight per nested BSDF: {} weights, {} BSDFs", w.size(), parts.size()));
            // ensureEnergyConservation (default true): weights summing above 1 are scaled to sum to 1.
            double sum = 0.0;
            for (float x : w) sum += x;
            if (get_bool(p, "ensure_energy_conservation", true) && sum > 1.0)
                for (float& x : w) x = float(x / sum);
            try {
                b->bsdf = make_mixture(std::move(parts), std::move(w));  // 1 to 16 BSDFs, transmitting ones of one index
            } catch (const ParameterError& e) {
                fail(n, e.what());
            }
        }
    } else if (type == "roughcoating") {
        const auto inner = nested(true);
        const MicrofacetType md = distribution("beckmann");
        const float alpha = roughness(0.1f);
        const float int_ior = ior(p, "int_ior", 1.5046f), ext_ior = ior(p, "ext_ior", 1.00028f);
        if (int_ior == ext_ior) fail(n, "the interior and exterior indices of refraction must differ");
        const float thickness = scalar_param(p, "thickness", 1.f);
        if (!(thickness >= 0.f) || !std::isfinite(thickness)) fail(n, "thickness must be finite and >= 0");
        const auto sigma = get_texture(p, "sigma_a", Color(0.f));
        if (!sigma->is_constant()) warn(n, "a textured sigma_a is taken at its mean");
        const auto spec = get_texture(p, "specular_reflectance", Color(1.f));
        if (!spec->is_constant()) warn(n, "a textured specular_reflectance is taken at its mean");
        b->opacity = inner->opacity, b->bump = inner->bump, b->normal_map = inner->normal_map;
        b->bsdf = make_rough_coating(inner->bsdf, int_ior / ext_ior, alpha, md, sigma->mean() * thickness, spec->mean());
    } else {
        unsupported(n, "unsupported BSDF type '" + type + "'", "renders it as diffuse grey 0.5");
        b->bsdf = make_lambertian(make_constant_texture(Color(0.5f)));
        for (auto& [name, c] : p.named) p.used.insert(c.internal_object());
        for (xml_node c : p.objects) p.used.insert(c.internal_object());
    }
    finish(p);
    return b;
}

void Importer::begin_building(xml_node n) {
    if (building_.size() >= size_t(kMaxNesting))
        fail(n, fmt::format("BSDFs and textures nest (or refer on) more than {} deep", kMaxNesting));
    if (!building_.insert(n.internal_object()).second) fail(n, "refers to itself");
}

std::shared_ptr<Texture> Importer::texture(xml_node n) {
    const auto it = textures_.find(n.internal_object());
    if (it != textures_.end()) return it->second;
    begin_building(n);
    auto t = build_texture(n);
    building_.erase(n.internal_object());
    textures_[n.internal_object()] = t;
    return t;
}

std::shared_ptr<Texture> Importer::opacity_texture(xml_node t) {
    const auto it = opacities_.find(t.internal_object());
    if (it != opacities_.end()) return it->second;
    std::shared_ptr<Texture> o;
    if (attr(t, "type") == "bitmap") {
        // The opacity of a bitmap is its alpha channel where it has one.
        Props p = props(t);
        o = bitmap(t, p, true);
        finish(p);
    } else {
        o = texture(t);
    }
    opacities_[t.internal_object()] = o;
    return o;
}

std::shared_ptr<Texture> Importer::bitmap(xml_node n, Props& p, bool opacity) {
    // gdr's uv has v = 0 at the bottom of an image, Mitsuba's at the top; the
    // loaders store gdr's, so Mitsuba's uv is (u, 1 - v).
    const glm::mat3 flip(Vec3(1.f, 0.f, 0.f), Vec3(0.f, -1.f, 0.f), Vec3(0.f, 1.f, 1.f));
    const std::string name = get_string(p, "filename", "");
    if (name.empty()) fail(n, "a bitmap needs a 'filename'");
    ImageTextureOptions io;
    const std::string filter = get_string(p, "filter_type", "bilinear");
    if (filter == "nearest") io.nearest = true;
    else if (filter != "bilinear" && filter != "trilinear" && filter != "ewa")
        fail(n, "unknown filter_type '" + filter + "' (expected bilinear or nearest)");
    const std::string wrap = get_string(p, "wrap_mode", "repeat");
    if (wrap == "mirror") io.wrap = TextureWrap::Mirror;
    else if (wrap == "clamp") io.wrap = TextureWrap::Clamp;
    else if (wrap != "repeat") unsupported(n, "wrap_mode '" + wrap + "'", "repeats the texture");
    io.srgb = !get_bool(p, "raw", false);
    bool gamma_given = false;
    const float gamma = get_float(p, "gamma", -1.f, &gamma_given);
    // Mitsuba's gamma: 1 linear, -1 sRGB, any other positive value a power law.
    if (gamma_given && gamma == 1.f) {
        io.srgb = false;
    } else if (gamma_given && gamma != -1.f) {
        if (!(gamma > 0.f) || !std::isfinite(gamma)) fail(p.named.at("gamma"), "gamma must be positive, or -1 for sRGB");
        io.gamma = gamma;
    }
    ignore(p, {"max_anisotropy", "cache", "accel", "format"});
    if (p.named.count("channel")) unsupported(p.named.at("channel"), "a single channel of a bitmap", "uses its colour");
    take(p, "channel");
    const glm::mat3 uvm = get_uv_transform(p);
    const std::string file = file_path(n, name);
    std::shared_ptr<Texture> t;
    if (const std::string why = detail::not_a_file(file); !why.empty()) {
        // Published scenes (and their randomised variants) sometimes name
        // textures they do not ship.
        dropped(n, file + why + " (--lenient uses a constant in its place with a warning)",
                file + why + (opacity ? "; the surface is opaque (--lenient)" : "; it is mid-grey 0.5 (--lenient)"));
        return make_constant_texture(Color(opacity ? 1.f : 0.5f));
    }
    std::string ext = fs::path(file).extension().string();
    for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (ext == ".exr" && opacity) {
        unsupported(n, "an EXR opacity map (give an 8-bit image with alpha)", "makes the surface opaque");
        return make_constant_texture(Color(1.f));
    }
    if (ext == ".exr" && gamma_given && gamma != 1.f)
        warn(n, fmt::format("gamma {} is ignored: an EXR bitmap is read as linear values", gamma));
    try {
        // Mitsuba 0.x's bitmap drops an image's alpha channel and gives its
        // colour to whatever reads it, a mask's opacity too: a cut-out leaf
        // stored as green on a transparent white card is, there, a mostly
        // opaque white card (the shared living room's plants). Mitsuba's
        // opacity is per channel; gdr's is one number, the colour's luminance.
        // EXR holds linear floats, read by gdr's EXR reader (stb reads the rest).
        if (ext == ".exr") t = make_image_texture(read_exr_rgb(file), io);
        else t = opacity ? load_opacity_texture(file, io, version_major_ >= 2) : load_image_texture(file, io);
    } catch (const InputError& e) {
        fail(n, e.what());
    }
    inputs_.push_back(file);
    // Looked up at Mitsuba's transformed uv, turned back into gdr's.
    return make_uv_transformed_texture(t, flip * uvm * flip);
}

/// Mitsuba's `scale` texture: its one nested texture times `scale` (a number or colour).
std::shared_ptr<Texture> Importer::scale_texture(xml_node n, Props& p) {
    std::vector<xml_node> kids;
    for (xml_node c : p.objects)
        if (std::string(c.name()) == "texture" || std::string(c.name()) == "ref") kids.push_back(c);
    for (const auto& [name, c] : p.named)
        if (name != "scale" && (std::string(c.name()) == "texture" || std::string(c.name()) == "ref")) kids.push_back(c);
    if (kids.size() != 1) fail(n, "a scale texture needs exactly one nested <texture> (or <ref>)");
    p.used.insert(kids[0].internal_object());
    xml_node t = std::string(kids[0].name()) == "ref" ? resolve(kids[0]) : kids[0];
    if (std::string(t.name()) != "texture") fail(kids[0], "refers to " + describe(t) + ", not a <texture>");
    const Color scale = get_colour(p, "scale", Color(1.f));
    return make_scaled_texture(texture(t), scale);
}

std::shared_ptr<Texture> Importer::build_texture(xml_node n) {
    const std::string type = need_attr(n, "type");
    Props p = props(n);
    // gdr's uv has v = 0 at the bottom of an image, Mitsuba's at the top; the
    // loaders store gdr's, so Mitsuba's uv is (u, 1 - v).
    const glm::mat3 flip(Vec3(1.f, 0.f, 0.f), Vec3(0.f, -1.f, 0.f), Vec3(0.f, 1.f, 1.f));
    std::shared_ptr<Texture> t;
    if (type == "bitmap") {
        t = bitmap(n, p, false);
    } else if (type == "checkerboard") {
        auto c0 = get_texture(p, "color0", Color(0.4f));
        auto c1 = get_texture(p, "color1", Color(0.2f));
        const glm::mat3 uvm = get_uv_transform(p);
        t = make_checkerboard_texture(std::move(c0), std::move(c1), uvm * flip);
    } else if (type == "scale") {
        t = scale_texture(n, p);
    } else {
        unsupported(n, "unsupported texture type '" + type + "'", "uses grey 0.5");
        for (auto& [name, c] : p.named) p.used.insert(c.internal_object());
        for (xml_node c : p.objects) p.used.insert(c.internal_object());
        t = make_constant_texture(Color(0.5f));
    }
    finish(p);
    return t;
}

}  // namespace gdr::mitsuba_import
