// Rough conductor: GGX microfacet reflection with Schlick Fresnel, two-sided.
// f = F(wi.h) D(h) G2(wo, wi) / (4 cos_o cos_i), G2 height-correlated Smith.
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"

namespace gdr {
namespace {

/// Metal with normal-incidence reflectance f0 (MTL Ks) and GGX roughness alpha;
/// sampled through visible normals, so the only lost samples are reflections
/// that end below the horizon (the energy lost to single-scattering masking).
class RoughConductor final : public Bsdf {
public:
    RoughConductor(const Color& f0, float alpha) : f0_(f0), alpha_(alpha) {}

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2&, float, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;  // two-sided: work with wo mirrored above
        const Vec3 wo_up(wo.x, wo.y, std::abs(wo.z));
        const Vec3 m = ggx_sample_visible_normal(wo_up, alpha_, u);
        const Vec3 wi_up = reflect(wo_up, m);
        if (wi_up.z <= 0.f) return std::nullopt;
        const GgxReflection g = ggx_reflection(wo_up, wi_up, alpha_);
        if (!(g.pdf > 0.f)) return std::nullopt;
        BsdfSample s;
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.f = value(g, wi_up);
        s.pdf = g.pdf;
        s.eta = 1.f;
        s.lobe = kReflection | kGlossy;
        s.roughness = alpha_;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return value(ggx_reflection(up(wo), up(wi), alpha_), up(wi));
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return 0.f;
        return ggx_reflection_pdf(up(wo), up(wi), alpha_);
    }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return {};
        const GgxReflection g = ggx_reflection(up(wo), up(wi), alpha_);
        return {value(g, up(wi)), g.pdf};
    }

    uint32_t flags() const override { return kReflection | kGlossy; }
    Color albedo(const Vec2&) const override { return f0_; }
    float min_roughness() const override { return alpha_; }

private:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }

    // The BSDF value of a reflection wo -> wi_up (upper hemisphere) with GGX terms g.
    Color value(const GgxReflection& g, const Vec3& wi_up) const {
        if (g.value <= 0.f) return Color(0.f);
        return fresnel_schlick(f0_, glm::dot(wi_up, g.h)) * g.value;
    }

    Color f0_;
    float alpha_;
};

}  // namespace

std::shared_ptr<Bsdf> make_rough_conductor(const Color& f0, float alpha) {
    if (!std::isfinite(alpha) || alpha < 0.f)
        throw ParameterError("roughconductor: alpha must be a non-negative number, got " + std::to_string(alpha));
    return std::make_shared<RoughConductor>(f0, std::max(alpha, kMinGgxAlpha));
}

}  // namespace gdr
