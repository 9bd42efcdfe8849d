// Isotropic GGX (Trowbridge-Reitz) microfacet distribution, Smith masking,
// visible-normal sampling and Fresnel terms. All directions are unit vectors
// in the local shading frame (z = macro-surface normal). `alpha` is the GGX
// roughness (alpha = 0 would be a perfect mirror; callers keep it >= kMinGgxAlpha).
// References: Walter et al. 2007 "Microfacet models for refraction through
// rough surfaces" (EGSR); Heitz 2014 "Understanding the masking-shadowing
// function" (JCGT 3(2)); Heitz 2018 "Sampling the GGX distribution of visible
// normals" (JCGT 7(4)).
#pragma once

#include "gdr/core/math.h"
#include "gdr/scene/warp.h"

namespace gdr {

/// Smallest GGX alpha the microfacet code is used with: below it D overflows
/// float precision and the lobe is treated as a delta (mirror) by the factories.
inline constexpr float kMinGgxAlpha = 1e-4f;

/// GGX normal distribution D(m) (1/sr), normalised so that the projected
/// microfacet area integrates to one: integral D(m) cos(theta_m) dm = 1 (Walter eq. 33).
inline float ggx_d(const Vec3& m, float alpha) {
    if (m.z <= 0.f) return 0.f;
    const float a2 = alpha * alpha;
    const float cos2 = m.z * m.z;
    const float k = cos2 * (a2 - 1.f) + 1.f;  // = cos^2 (a2 + tan^2) form without the tan singularity
    return a2 / (kPi * k * k);
}

/// Smith Lambda(w) for GGX (Heitz 2014 eq. 72): the ratio of shadowed to
/// visible projected microfacet area; unitless, >= 0.
inline float ggx_lambda(const Vec3& w, float alpha) {
    const float cos2 = w.z * w.z;
    if (cos2 <= 0.f) return kInf;
    const float tan2 = std::max(0.f, 1.f - cos2) / cos2;
    return 0.5f * (std::sqrt(1.f + alpha * alpha * tan2) - 1.f);
}

/// Smith masking G1(w, m) for GGX (unitless in [0,1]); zero when the microfacet
/// m is seen from its back side relative to the macro-surface side of w.
inline float smith_g1(const Vec3& w, const Vec3& m, float alpha) {
    if (glm::dot(w, m) * w.z <= 0.f) return 0.f;
    return 1.f / (1.f + ggx_lambda(w, alpha));
}

/// Height-correlated Smith masking-shadowing G2(wo, wi, m) (Heitz 2014 eq. 99),
/// unitless in [0,1]. Chosen over the separable form G1*G1 because it does not
/// double-count the correlation between masking and shadowing, so rough lobes
/// lose less energy than the separable form predicts (closer to ground truth).
inline float smith_g2(const Vec3& wo, const Vec3& wi, const Vec3& m, float alpha) {
    if (glm::dot(wo, m) * wo.z <= 0.f || glm::dot(wi, m) * wi.z <= 0.f) return 0.f;
    return 1.f / (1.f + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
}

/// Samples a microfacet normal m from the distribution of normals visible from
/// wo, D_wo(m) = G1(wo,m) max(0, wo.m) D(m) / wo.z (Heitz 2018, listing 1).
/// wo must lie in the upper hemisphere; u in [0,1)^2. Returns m with m.z >= 0.
inline Vec3 ggx_sample_visible_normal(const Vec3& wo, float alpha, const Vec2& u) {
    // Stretch to the alpha = 1 configuration, where visible normals are a projected hemisphere.
    const Vec3 vh = glm::normalize(Vec3(alpha * wo.x, alpha * wo.y, wo.z));
    const float lensq = vh.x * vh.x + vh.y * vh.y;
    const Vec3 t1 = lensq > 0.f ? Vec3(-vh.y, vh.x, 0.f) * (1.f / std::sqrt(lensq)) : Vec3(1.f, 0.f, 0.f);
    const Vec3 t2 = glm::cross(vh, t1);
    // Uniform disk point, then warp the half of the disk hidden by the
    // projection. Any uniform map of the disk will do; the concentric one
    // needs no sin/cos call (Heitz's listing uses polar coordinates).
    const Vec2 disk = warp::square_to_uniform_disk(u);
    const float p1 = disk.x;
    float p2 = disk.y;
    const float s = 0.5f * (1.f + vh.z);
    p2 = (1.f - s) * safe_sqrt(1.f - p1 * p1) + s * p2;
    const Vec3 nh = p1 * t1 + p2 * t2 + safe_sqrt(1.f - p1 * p1 - p2 * p2) * vh;
    // Unstretch back to the alpha ellipsoid.
    return glm::normalize(Vec3(alpha * nh.x, alpha * nh.y, std::max(1e-7f, nh.z)));
}

/// Solid-angle density of ggx_sample_visible_normal producing m (1/sr, over microfacet normals).
inline float ggx_visible_normal_pdf(const Vec3& wo, const Vec3& m, float alpha) {
    if (wo.z <= 0.f) return 0.f;
    return smith_g1(wo, m, alpha) * std::max(0.f, glm::dot(wo, m)) * ggx_d(m, alpha) / wo.z;
}

/// GGX reflection of one pair of directions: its value and its sampling
/// density share the half vector, D and Lambda(wo), which a BSDF needing both
/// (sample(), eval_pdf()) would otherwise compute twice.
struct GgxReflection {
    float value = 0.f;  ///< D G2 / (4 cos_o cos_i) without Fresnel (1/sr, Walter eq. 20).
    /// Density of reflecting wo about a visible normal from
    /// ggx_sample_visible_normal: D_wo(h) / (4 wo.h), the Jacobian of h -> wi
    /// (Walter eq. 14) (1/sr).
    float pdf = 0.f;
    Vec3 h{0.f};        ///< Half vector normalize(wo + wi), for a Fresnel term (0 if a direction is below the surface).
};

/// GgxReflection of wo and wi; both must be in the upper hemisphere, else all is 0.
inline GgxReflection ggx_reflection(const Vec3& wo, const Vec3& wi, float alpha) {
    GgxReflection r;
    if (wo.z <= 0.f || wi.z <= 0.f) return r;
    r.h = glm::normalize(wo + wi);
    // The Smith terms through S(w) = cos sqrt(1 + alpha^2 tan^2) = sqrt(cos^2
    // + alpha^2 sin^2), so that 1 + Lambda(w) = (cos + S) / (2 cos). Then
    //   value = D G2 / (4 cos_o cos_i) = D / (2 (S_o cos_i + S_i cos_o)),
    //   pdf   = D G1(wo) / (4 cos_o)    = D / (2 (cos_o + S_o)):
    // the same quantities as smith_g2 and smith_g1 give, with one division
    // each instead of four and five (this is on every glossy vertex's path).
    const float a2 = alpha * alpha;
    const float co2 = wo.z * wo.z, ci2 = wi.z * wi.z;
    const float s_o = std::sqrt(co2 + a2 * std::max(0.f, 1.f - co2));
    const float s_i = std::sqrt(ci2 + a2 * std::max(0.f, 1.f - ci2));
    const float k = r.h.z * r.h.z * (a2 - 1.f) + 1.f;
    const float d2 = 2.f * (kPi * k * k);  // D / 2 = a2 / d2 (ggx_d; h.z > 0 here)
    // The side tests of smith_g1/g2: wo.z > 0, so only the microfacet's side remains.
    const bool wo_visible = glm::dot(wo, r.h) > 0.f;
    if (wo_visible && glm::dot(wi, r.h) > 0.f) r.value = a2 / (d2 * (s_o * wi.z + s_i * wo.z));
    if (wo_visible) r.pdf = a2 / (d2 * (wo.z + s_o));
    return r;
}

/// Density alone of ggx_reflection (1/sr).
inline float ggx_reflection_pdf(const Vec3& wo, const Vec3& wi, float alpha) {
    return ggx_reflection(wo, wi, alpha).pdf;
}

/// Value alone of ggx_reflection (1/sr).
inline float ggx_reflection_eval(const Vec3& wo, const Vec3& wi, float alpha) {
    return ggx_reflection(wo, wi, alpha).value;
}

/// Schlick's approximation of conductor Fresnel reflectance (unitless RGB)
/// for normal reflectance f0 at |cos| of the angle between w and the microfacet normal.
inline Color fresnel_schlick(const Color& f0, float cos_theta) {
    const float c = std::clamp(1.f - std::abs(cos_theta), 0.f, 1.f);
    const float c5 = (c * c) * (c * c) * c;
    return f0 + (Color(1.f) - f0) * c5;
}

/// The microfacet normal distributions gdr renders; both take an alpha of the
/// same meaning for narrow lobes (the RMS slope), so they share the
/// equivalent roughness the shift mappings read.
enum class MicrofacetType {
    GGX,       ///< Trowbridge-Reitz (Walter et al. 2007), sampled through visible normals.
    Beckmann,  ///< Beckmann (Walter et al. 2007, eq. 25), sampled by D(m) cos(theta_m).
};

/// Beckmann normal distribution D(m) (1/sr), normalised like ggx_d:
/// exp(-tan^2 / alpha^2) / (pi alpha^2 cos^4) (Walter et al. 2007, eq. 25).
inline float beckmann_d(const Vec3& m, float alpha) {
    if (m.z <= 0.f) return 0.f;
    const float cos2 = m.z * m.z;
    const float tan2 = std::max(0.f, 1.f - cos2) / cos2;
    const float a2 = alpha * alpha;
    return std::exp(-tan2 / a2) / (kPi * a2 * cos2 * cos2);
}

/// Smith Lambda(w) for Beckmann (Heitz 2014, eq. 80, exact through erf):
/// with a = 1 / (alpha tan theta), Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),
/// computed through erfc to keep its precision where Lambda is small.
inline float beckmann_lambda(const Vec3& w, float alpha) {
    const float cos2 = w.z * w.z;
    if (cos2 <= 0.f) return kInf;
    const float tan = std::sqrt(std::max(0.f, 1.f - cos2) / cos2);
    if (tan <= 0.f) return 0.f;
    const float a = 1.f / (alpha * tan);
    if (a > 6.f) return 0.f;  // below float resolution of the difference
    return 0.5f * (std::exp(-a * a) / (a * std::sqrt(kPi)) - std::erfc(a));
}

/// Samples a Beckmann microfacet normal with density D(m) cos(theta_m)
/// (Walter et al. 2007, eqs. 28 and 29): tan^2 = -alpha^2 log(1 - u.x); u in [0,1)^2.
inline Vec3 beckmann_sample_normal(float alpha, const Vec2& u) {
    const float tan2 = -alpha * alpha * std::log(std::max(1.f - u.x, 1e-30f));
    const float cos_t = 1.f / std::sqrt(1.f + tan2);
    const float sin_t = std::sqrt(std::max(0.f, 1.f - cos_t * cos_t));
    const float phi = 2.f * kPi * u.y;
    return {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t};
}

/// One microfacet distribution of either type, with what the BSDFs need of it:
/// D, Smith masking, normal sampling and its density. GGX samples visible
/// normals; Beckmann samples D(m) cos(theta_m), the classic scheme, whose
/// normals may face away from wo: callers reject those (sample_normal_pdf
/// is the density of every normal drawn, back-facing ones included).
struct Microfacet {
    MicrofacetType type = MicrofacetType::GGX;  ///< Which distribution.
    float alpha = 0.1f;                         ///< Roughness (>= kMinGgxAlpha).

    /// D(m) (1/sr).
    float d(const Vec3& m) const { return type == MicrofacetType::GGX ? ggx_d(m, alpha) : beckmann_d(m, alpha); }
    /// Smith Lambda(w), unitless.
    float lambda(const Vec3& w) const {
        return type == MicrofacetType::GGX ? ggx_lambda(w, alpha) : beckmann_lambda(w, alpha);
    }
    /// Height-correlated Smith G2 (as smith_g2), unitless in [0,1].
    float g2(const Vec3& wo, const Vec3& wi, const Vec3& m) const {
        if (glm::dot(wo, m) * wo.z <= 0.f || glm::dot(wi, m) * wi.z <= 0.f) return 0.f;
        return 1.f / (1.f + lambda(wo) + lambda(wi));
    }
    /// A microfacet normal for wo (upper hemisphere); u in [0,1)^2.
    Vec3 sample_normal(const Vec3& wo, const Vec2& u) const {
        return type == MicrofacetType::GGX ? ggx_sample_visible_normal(wo, alpha, u) : beckmann_sample_normal(alpha, u);
    }
    /// Solid-angle density of sample_normal producing m (1/sr); for GGX
    /// zero where m faces away from wo.
    float sample_normal_pdf(const Vec3& wo, const Vec3& m) const {
        if (type == MicrofacetType::GGX) return ggx_visible_normal_pdf(wo, m, alpha);
        return beckmann_d(m, alpha) * std::max(0.f, m.z);
    }
    /// Value and density of a reflection wo -> wi about h = normalize(wo + wi),
    /// as ggx_reflection (both upper hemisphere, else all 0); the density
    /// counts only normals that face wo, the ones the BSDFs keep.
    GgxReflection reflection(const Vec3& wo, const Vec3& wi) const {
        if (type == MicrofacetType::GGX) return ggx_reflection(wo, wi, alpha);
        GgxReflection r;
        if (wo.z <= 0.f || wi.z <= 0.f) return r;
        r.h = glm::normalize(wo + wi);
        const float cos_oh = glm::dot(wo, r.h);
        if (cos_oh <= 0.f) return r;
        const float D = beckmann_d(r.h, alpha);
        r.value = D * g2(wo, wi, r.h) / (4.f * wo.z * wi.z);
        r.pdf = D * r.h.z / (4.f * cos_oh);
        return r;
    }
};

/// Exact unpolarised Fresnel reflectance (unitless in [0,1]) of a smooth
/// dielectric interface. cos_i = cosine of the incident direction with the
/// normal on its own side (> 0); eta = eta_transmitted / eta_incident.
/// Returns 1 on total internal reflection; cos_t receives the (positive)
/// cosine of the refracted direction (0 on TIR).
inline float fresnel_dielectric(float cos_i, float eta, float& cos_t) {
    cos_i = std::clamp(cos_i, 0.f, 1.f);
    const float sin2_t = (1.f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.f) {
        cos_t = 0.f;
        return 1.f;
    }
    cos_t = std::sqrt(1.f - sin2_t);
    // Amplitude ratios for s- and p-polarised light (Fresnel equations).
    const float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    const float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

/// fresnel_dielectric without the refracted cosine.
inline float fresnel_dielectric(float cos_i, float eta) {
    float cos_t;
    return fresnel_dielectric(cos_i, eta, cos_t);
}

/// The complex index of refraction eta + i k of a conductor relative to the
/// medium outside it, per RGB channel (unitless). The default, eta 0 and
/// k 1, reflects everything at every angle (Mitsuba's material "none").
struct ConductorIor {
    Color eta{0.f};  ///< Real part: the refractive index.
    Color k{1.f};    ///< Imaginary part: the extinction coefficient (>= 0).
};

/// Exact unpolarised Fresnel reflectance (unitless RGB in [0, 1]) of a smooth
/// conductor at |cos_i|, the cosine of the incident direction with the
/// (micro)surface normal. The Fresnel equations for a complex index: with
/// a^2 + b^2 = |eta^2 - k^2 - sin^2 + 2 i eta k| and a = Re sqrt(that), the
/// s-polarised reflectance is (a^2 + b^2 + cos^2 - 2 a cos) / (the same
/// with + 2 a cos), and the p-polarised one that times (cos^2 (a^2 + b^2) +
/// sin^4 - 2 a cos sin^2) / (the same with +) (Born and Wolf, "Principles
/// of Optics", 1999, section 14.2). k = 0 gives fresnel_dielectric.
inline Color fresnel_conductor(const ConductorIor& ior, float cos_i) {
    const double c = std::min(1.0, double(std::abs(cos_i))), c2 = c * c, s2 = 1.0 - c2;
    Color f;
    for (int i = 0; i < 3; ++i) {
        const double n = ior.eta[i], k = ior.k[i];
        const double t0 = n * n - k * k - s2;
        const double a2b2 = std::sqrt(t0 * t0 + 4.0 * n * n * k * k);
        const double a = std::sqrt(std::max(0.0, 0.5 * (a2b2 + t0)));
        const double rs_den = a2b2 + c2 + 2.0 * a * c;
        const double rp_num = c2 * a2b2 + s2 * s2 - 2.0 * a * c * s2, rp_den = c2 * a2b2 + s2 * s2 + 2.0 * a * c * s2;
        // Both denominators vanish only at grazing incidence on an index of 1, where the limit is 1.
        if (!(rs_den > 0.0) || !(rp_den > 0.0)) {
            f[i] = 1.f;
            continue;
        }
        const double rs = (a2b2 + c2 - 2.0 * a * c) / rs_den;
        const double rp = rs * rp_num / rp_den;
        f[i] = float(std::clamp(0.5 * (rs + rp), 0.0, 1.0));
    }
    return f;
}

}  // namespace gdr
