// Thin dielectric sheet (a window pane, Mitsuba's thindielectric): two
// parallel smooth interfaces so close that light leaves where it entered.
// Delta reflection and straight-through delta transmission, two-sided,
// weighted by the Fresnel reflectance summed over the internal bounces.
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"

namespace gdr {
namespace {

/// See mirror.cpp: tolerance (distance of unit vectors) for eval_delta.
constexpr float kDeltaTolerance = 1e-3f;

/// One interface reflects R and transmits 1 - R; the light bouncing between
/// the two faces adds up to R' = R + (1 - R)^2 R / (1 - R^2) = 2R / (1 + R)
/// reflected and 1 - R' transmitted (no absorption). Each lobe is sampled
/// with its own weight, so f |cos| / pdf is 1 for both.
/// Tints (Mitsuba's specular_reflectance / specular_transmittance) multiply
/// the lobes' weights, not their probabilities.
class ThinDielectric final : public Bsdf {
public:
    ThinDielectric(float eta, std::shared_ptr<Texture> r, std::shared_ptr<Texture> t)
        : eta_(eta), r_(std::move(r)), t_(std::move(t)) {}

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2&) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float r = reflectance(wo);
        return u_lobe < r ? tinted(lobe(Vec3(-wo.x, -wo.y, wo.z), r, kReflection), r_, uv)
                          : tinted(lobe(-wo, 1.f - r, kTransmission), t_, uv);
    }

    Color eval(const Vec3&, const Vec3&, const Vec2&) const override { return Color(0.f); }
    float pdf(const Vec3&, const Vec3&, const Vec2&) const override { return 0.f; }

    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (wo.z == 0.f || wi.z == 0.f) return std::nullopt;
        const float r = reflectance(wo);
        const bool reflect = same_hemisphere(wo, wi);
        const Vec3 w = reflect ? Vec3(-wo.x, -wo.y, wo.z) : -wo;
        if (glm::length(wi - w) > kDeltaTolerance) return std::nullopt;
        return reflect ? tinted(lobe(w, r, kReflection), r_, uv) : tinted(lobe(w, 1.f - r, kTransmission), t_, uv);
    }

    uint32_t flags() const override { return kReflection | kTransmission | kSpecular; }
    Color albedo(const Vec2& uv) const override {
        return 0.5f * ((r_ ? r_->eval(uv) : Color(1.f)) + (t_ ? t_->eval(uv) : Color(1.f)));
    }
    float min_roughness() const override { return 0.f; }
    // Directions are not bent, and radiance is not compressed: eta() stays 1.

private:
    float reflectance(const Vec3& wo) const {
        const float r = fresnel_dielectric(std::abs(wo.z), eta_);
        return r < 1.f ? 2.f * r / (1.f + r) : 1.f;
    }

    static std::optional<BsdfSample> lobe(const Vec3& wi, float weight, uint32_t side) {
        if (!(weight > 0.f)) return std::nullopt;
        BsdfSample s;
        s.wi = wi;
        s.pdf = weight;
        s.f = Color(weight / std::abs(wi.z));
        s.eta = 1.f;
        s.lobe = side | kSpecular;
        s.roughness = 0.f;
        return s;
    }

    static std::optional<BsdfSample> tinted(std::optional<BsdfSample> s, const std::shared_ptr<Texture>& tint,
                                            const Vec2& uv) {
        if (s && tint) s->f *= tint->eval(uv);
        return s;
    }

    float eta_;
    std::shared_ptr<Texture> r_, t_;  // tints of reflection and transmission; null = 1
};

}  // namespace

std::shared_ptr<Bsdf> make_thin_dielectric(float eta, std::shared_ptr<Texture> reflectance,
                                           std::shared_ptr<Texture> transmittance) {
    if (!(eta > 0.f) || !std::isfinite(eta))
        throw ParameterError("thin dielectric: index of refraction must be a positive number, got " + std::to_string(eta));
    return std::make_shared<ThinDielectric>(eta, std::move(reflectance), std::move(transmittance));
}

}  // namespace gdr
