// Rough dielectric interface: GGX or Beckmann microfacet reflection and
// refraction after Walter et al. 2007 (eqs. 20 and 21); GGX sampled through
// visible normals (Heitz 2018), Beckmann by D(m) cos(theta_m). Oriented: z > 0 is outside, eta = eta_inside / eta_outside.
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"

namespace gdr {
namespace {

/// The microfacet normal is drawn from the visible normals of wo (GGX) or
/// from D(m) cos(theta_m) (Beckmann, whose normals facing away from wo are
/// rejected); reflection
/// or refraction is then chosen with probability F(wo.m) / 1 - F(wo.m), so
/// the pdf of wi is F * p(m) * |dm/dwi| with the reflection Jacobian
/// 1 / (4 |wo.m|) (Walter eq. 14) or the refraction Jacobian
/// |wi.m| / (wi.m + wo.m / eta_rel)^2 (Walter eq. 17 in relative-index form).
/// Tints (Mitsuba's specular_reflectance / specular_transmittance) multiply
/// the reflected and transmitted values, not the sampling.
class RoughDielectric final : public Bsdf {
public:
    RoughDielectric(float eta, Microfacet mf, std::shared_ptr<Texture> r, std::shared_ptr<Texture> t)
        : eta_(eta), mf_(mf), r_(std::move(r)), t_(std::move(t)) {}

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        // D and G are symmetric under z -> -z, so a wo inside is handled as the
        // mirrored configuration above with the reciprocal relative index.
        const float side = wo.z > 0.f ? 1.f : -1.f;
        const float eta_rel = wo.z > 0.f ? eta_ : 1.f / eta_;
        const Vec3 wo_up(wo.x, wo.y, std::abs(wo.z));
        const Vec3 m = mf_.sample_normal(wo_up, u);
        const float cos_om = glm::dot(wo_up, m);
        if (cos_om <= 0.f) return std::nullopt;
        float cos_t;
        const float F = fresnel_dielectric(cos_om, eta_rel, cos_t);
        Vec3 wi_up;
        BsdfSample s;
        if (u_lobe < F) {
            wi_up = reflect(wo_up, m);
            if (wi_up.z <= 0.f) return std::nullopt;
            s.eta = 1.f;
            s.lobe = kReflection | kGlossy;
        } else {
            wi_up = glm::normalize(-wo_up / eta_rel + (cos_om / eta_rel - cos_t) * m);
            if (wi_up.z >= 0.f) return std::nullopt;
            s.eta = eta_rel;
            s.lobe = kTransmission | kGlossy;
        }
        // f and pdf from the same code as eval()/pdf(), so they agree exactly.
        const Terms t = terms_up(wo_up, wi_up, eta_rel);
        if (!(t.pdf > 0.f) || !(t.f > 0.f)) return std::nullopt;
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.f = Color(t.f) * tint(wi_up.z > 0.f, uv);
        s.pdf = t.pdf;
        s.roughness = mf_.alpha;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (wo.z == 0.f || wi.z == 0.f) return Color(0.f);
        const float side = wo.z > 0.f ? 1.f : -1.f;
        return Color(terms_up(up(wo, side), up(wi, side), wo.z > 0.f ? eta_ : 1.f / eta_).f) *
               tint(same_hemisphere(wo, wi), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (wo.z == 0.f || wi.z == 0.f) return 0.f;
        const float side = wo.z > 0.f ? 1.f : -1.f;
        return terms_up(up(wo, side), up(wi, side), wo.z > 0.f ? eta_ : 1.f / eta_).pdf;
    }

    uint32_t flags() const override { return kReflection | kTransmission | kGlossy; }
    Color albedo(const Vec2& uv) const override { return 0.5f * (tint(true, uv) + tint(false, uv)); }
    float min_roughness() const override { return mf_.alpha; }
    float eta() const override { return eta_; }

private:
    struct Terms {
        float f = 0.f;    // BSDF value (1/sr), radiance transport
        float pdf = 0.f;  // solid-angle pdf of sample() (1/sr)
    };

    static Vec3 up(const Vec3& w, float side) { return {w.x, w.y, side * w.z}; }

    // The tint of a reflected (or else transmitted) value.
    Color tint(bool reflected, const Vec2& uv) const {
        const auto& t = reflected ? r_ : t_;
        return t ? t->eval(uv) : Color(1.f);
    }

    // wo above the surface (wo.z > 0); eta_rel = eta below / eta above.
    Terms terms_up(const Vec3& wo, const Vec3& wi, float eta_rel) const {
        Terms t;
        if (wi.z > 0.f) {
            const Vec3 h = glm::normalize(wo + wi);
            const float cos_oh = glm::dot(wo, h);
            if (cos_oh <= 0.f) return t;
            const float F = fresnel_dielectric(cos_oh, eta_rel);
            const float D = mf_.d(h);
            t.f = F * D * mf_.g2(wo, wi, h) / (4.f * wo.z * wi.z);
            t.pdf = F * mf_.sample_normal_pdf(wo, h) / (4.f * cos_oh);
            return t;
        }
        // Generalised half vector of refraction (Walter eq. 16), on the outer side.
        Vec3 hv = wo + eta_rel * wi;
        const float len = glm::length(hv);
        if (!(len > 1e-6f)) return t;  // eta_rel ~ 1 and wi ~ -wo: no unique microfacet
        Vec3 h = hv / len;
        if (h.z < 0.f) h = -h;
        const float cos_oh = glm::dot(wo, h), cos_ih = glm::dot(wi, h);
        if (cos_oh <= 0.f || cos_ih >= 0.f) return t;  // refraction through a back-facing microfacet
        const float F = fresnel_dielectric(cos_oh, eta_rel);  // wo's side: the choice sample() makes
        if (F >= 1.f) return t;
        // The value's Fresnel term from the outer direction's cosine, whichever
        // of wo and wi that is: near grazing microfacet incidence 1 - F is
        // ill-conditioned, and taking it from the same side for (wo, wi) and
        // (wi, wo) keeps f reciprocal to rounding (it equals F analytically).
        const float F_value = eta_rel > 1.f ? F : fresnel_dielectric(-cos_ih, 1.f / eta_rel);
        const float denom = cos_ih + cos_oh / eta_rel;
        const float jacobian = -cos_ih / (denom * denom);  // |dh/dwi|
        const float D = mf_.d(h);
        // Walter eq. 21 with the 1/eta_rel^2 radiance scaling folded in.
        t.f = (1.f - F_value) * D * mf_.g2(wo, wi, h) * cos_oh * jacobian / (wo.z * -wi.z) / (eta_rel * eta_rel);
        t.pdf = (1.f - F) * mf_.sample_normal_pdf(wo, h) * jacobian;
        return t;
    }

    float eta_;
    Microfacet mf_;
    std::shared_ptr<Texture> r_, t_;  // tints of reflection and transmission; null = 1
};

}  // namespace

std::shared_ptr<Bsdf> make_rough_dielectric(float eta, float alpha) {
    return make_rough_dielectric(eta, alpha, nullptr, nullptr);
}

std::shared_ptr<Bsdf> make_rough_dielectric(float eta, float alpha, std::shared_ptr<Texture> reflectance,
                                            std::shared_ptr<Texture> transmittance, MicrofacetType type) {
    if (!(eta > 0.f) || !std::isfinite(eta))
        throw ParameterError("roughdielectric: index of refraction must be a positive number, got " +
                             std::to_string(eta));
    if (!std::isfinite(alpha) || alpha < 0.f)
        throw ParameterError("roughdielectric: alpha must be a non-negative number, got " + std::to_string(alpha));
    // An index-matched interface does not bend light: the microfacets are
    // invisible and the generalised half vector is undefined, so use the smooth model.
    if (std::abs(eta - 1.f) < 1e-4f) return make_dielectric(eta, std::move(reflectance), std::move(transmittance));
    return std::make_shared<RoughDielectric>(eta, Microfacet{type, std::max(alpha, kMinGgxAlpha)}, std::move(reflectance),
                                             std::move(transmittance));
}

}  // namespace gdr
