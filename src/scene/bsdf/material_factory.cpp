// MTL material -> BSDF, by the conventions of docs/scenes.md ("MTL rules"), and
// explicit BSDF types chosen by name (scene-file overrides).
#include <array>

#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"

namespace gdr {
namespace {

/// Names accepted by bsdf_from_desc, in the order they are listed in errors.
constexpr std::array<const char*, 7> kBsdfTypes = {"auto",           "diffuse",         "mirror",  "dielectric",
                                                    "roughconductor", "roughdielectric", "plastic"};

/// GGX alpha of a material: Pr when present (the converted scenes store alpha
/// there), else the Phong-equivalent alpha of Ns (classic MTL files).
float material_alpha(const MaterialDesc& m) { return m.pr >= 0.f ? m.pr : phong_to_alpha(m.ns); }

/// Diffuse reflectance texture: map_Kd as read by the loaders (modulated by
/// diffuse_map_scale()), else Kd.
std::shared_ptr<Texture> diffuse_texture(const MaterialDesc& m) {
    if (m.kd_map) return m.kd_map;
    if (m.map_kd.empty()) return make_constant_texture(m.kd);
    throw ParameterError("material '" + m.name + "': its map_kd '" + m.map_kd +
                         "' was not read (gdr/io/texture_files.h: read_material_textures)");
}

/// Reflectance of a mirror or conductor chosen explicitly by type: Ks, or Kd
/// when Ks is black (a diffuse MTL material overridden to metal keeps its colour).
Color specular_colour(const MaterialDesc& m) { return is_black(m.ks) ? m.kd : m.ks; }

float checked_ior(const MaterialDesc& m) {
    if (!(m.ni > 0.f) || !std::isfinite(m.ni))
        throw ParameterError("material '" + m.name + "': index of refraction Ni must be positive, got " +
                             std::to_string(m.ni));
    return m.ni;
}

/// Conductor of reflectance f0, or of the exact Fresnel of the material's
/// complex index tinted by f0: a delta reflection when the roughness is zero
/// or below what GGX can represent in float.
std::shared_ptr<Bsdf> conductor(const MaterialDesc& m, const Color& f0) {
    const float alpha = material_alpha(m);
    const bool smooth = m.pr == 0.f || alpha < kMinGgxAlpha;
    if (m.conductor_ior)
        return smooth ? make_conductor(*m.conductor_ior, f0)
                      : make_rough_conductor(*m.conductor_ior, alpha, MicrofacetType::GGX, make_constant_texture(f0));
    if (smooth) return make_mirror(f0);
    return make_rough_conductor(f0, alpha);
}

}  // namespace

std::shared_ptr<Bsdf> bsdf_from_mtl(const MaterialDesc& m) {
    if (m.illum == 5) return make_mirror(m.ks);
    if (m.illum == 7) {
        const float eta = checked_ior(m);
        if (m.pr > 1e-3f) return make_rough_dielectric(eta, m.pr);
        return make_dielectric(eta);
    }
    if (m.metal) return conductor(m, m.ks);
    if (!is_black(m.ks)) return make_plastic(diffuse_texture(m), m.ks, material_alpha(m));
    // Includes pure emitters (Kd = Ks = 0): a black Lambertian absorbs everything.
    return make_lambertian(diffuse_texture(m));
}

std::shared_ptr<Bsdf> bsdf_from_desc(const MaterialDesc& m, const std::string& type) {
    if (type == "auto") return bsdf_from_mtl(m);
    if (type == "diffuse") return make_lambertian(diffuse_texture(m));
    if (type == "mirror") return make_mirror(specular_colour(m));
    if (type == "dielectric") return make_dielectric(checked_ior(m));
    if (type == "roughconductor") return conductor(m, specular_colour(m));
    if (type == "roughdielectric") return make_rough_dielectric(checked_ior(m), material_alpha(m));
    if (type == "plastic") return make_plastic(diffuse_texture(m), m.ks, material_alpha(m));
    std::string list;
    for (const char* t : kBsdfTypes) list += (list.empty() ? "" : ", ") + std::string(t);
    throw ParameterError("material '" + m.name + "': unknown BSDF type '" + type + "' (expected one of: " + list +
                         ")");
}

}  // namespace gdr
