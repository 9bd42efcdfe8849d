// Rough conductor: GGX or Beckmann microfacet reflection with the exact
// Fresnel of a complex index of refraction (Mitsuba's roughconductor) or
// Schlick's from a normal-incidence reflectance (an MTL's Ks), two-sided. f = F(wi.h) D(h) G2(wo, wi) / (4 cos_o cos_i), G2
// height-correlated Smith, optionally times a reflectance texture (Mitsuba's
// specular_reflectance).
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"

namespace gdr {
namespace {

/// Metal of roughness alpha whose Fresnel term is exact for `ior`, or
/// Schlick's for normal-incidence reflectance f0 (MTL Ks) where ior is absent.
/// GGX is sampled through visible normals, so the only lost samples are
/// reflections that end below the horizon (the energy lost to
/// single-scattering masking); Beckmann by D cos, which also loses normals
/// facing away from wo.
class RoughConductor final : public Bsdf {
public:
    RoughConductor(const Color& f0, std::optional<ConductorIor> ior, Microfacet mf, std::shared_ptr<Texture> tint)
        : f0_(ior ? fresnel_conductor(*ior, 1.f) : f0), ior_(ior), mf_(mf), tint_(std::move(tint)) {
        // A constant tint is a factor on every value: kept as a colour, it saves a virtual call per evaluation.
        if (tint_ && tint_->is_constant()) tint_const_ = tint_->mean(), tint_ = nullptr;
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;  // two-sided: work with wo mirrored above
        const Vec3 wo_up(wo.x, wo.y, std::abs(wo.z));
        const Vec3 m = mf_.sample_normal(wo_up, u);
        if (glm::dot(wo_up, m) <= 0.f) return std::nullopt;
        const Vec3 wi_up = reflect(wo_up, m);
        if (wi_up.z <= 0.f) return std::nullopt;
        const GgxReflection g = mf_.reflection(wo_up, wi_up);
        if (!(g.pdf > 0.f)) return std::nullopt;
        BsdfSample s;
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.f = value(g, wi_up, uv);
        s.pdf = g.pdf;
        s.eta = 1.f;
        s.lobe = kReflection | kGlossy;
        s.roughness = mf_.alpha;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return value(mf_.reflection(up(wo), up(wi)), up(wi), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return 0.f;
        return mf_.reflection(up(wo), up(wi)).pdf;
    }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return {};
        const GgxReflection g = mf_.reflection(up(wo), up(wi));
        return {value(g, up(wi), uv), g.pdf};
    }

    uint32_t flags() const override { return kReflection | kGlossy; }
    Color albedo(const Vec2& uv) const override { return (tint_ ? f0_ * tint_->eval(uv) : f0_) * tint_const_; }
    float min_roughness() const override { return mf_.alpha; }

private:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }

    // The BSDF value of a reflection wo -> wi_up (upper hemisphere) with microfacet terms g.
    Color value(const GgxReflection& g, const Vec3& wi_up, const Vec2& uv) const {
        if (g.value <= 0.f) return Color(0.f);
        const float cos_h = glm::dot(wi_up, g.h);
        const Color f = (ior_ ? fresnel_conductor(*ior_, cos_h) : fresnel_schlick(f0_, cos_h)) * g.value;
        return (tint_ ? f * tint_->eval(uv) : f) * tint_const_;
    }

    Color f0_;                          // normal-incidence reflectance
    std::optional<ConductorIor> ior_;   // exact Fresnel where given
    Microfacet mf_;
    std::shared_ptr<Texture> tint_;  // specular reflectance texture; null = constant
    Color tint_const_{1.f};          // the specular reflectance where it is constant
};

}  // namespace

namespace {

void check_alpha(float alpha) {
    if (!std::isfinite(alpha) || alpha < 0.f)
        throw ParameterError("roughconductor: alpha must be a non-negative number, got " + std::to_string(alpha));
}

}  // namespace

std::shared_ptr<Bsdf> make_rough_conductor(const Color& f0, float alpha, MicrofacetType type,
                                           std::shared_ptr<Texture> reflectance) {
    check_alpha(alpha);
    return std::make_shared<RoughConductor>(f0, std::nullopt, Microfacet{type, std::max(alpha, kMinGgxAlpha)},
                                            std::move(reflectance));
}

std::shared_ptr<Bsdf> make_rough_conductor(const ConductorIor& ior, float alpha, MicrofacetType type,
                                           std::shared_ptr<Texture> reflectance) {
    check_alpha(alpha);
    check_conductor_ior(ior, "roughconductor");
    return std::make_shared<RoughConductor>(Color(0.f), ior, Microfacet{type, std::max(alpha, kMinGgxAlpha)},
                                            std::move(reflectance));
}

}  // namespace gdr
