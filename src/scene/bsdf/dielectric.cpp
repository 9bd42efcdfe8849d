// Smooth dielectric interface (MTL illum 7): delta reflection and refraction
// weighted by the exact unpolarised Fresnel term. Oriented: z > 0 is outside,
// eta = eta_inside / eta_outside.
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"

namespace gdr {
namespace {

/// See mirror.cpp: tolerance (distance of unit vectors) for eval_delta.
constexpr float kDeltaTolerance = 1e-3f;

/// Reflects with probability F and refracts with probability 1 - F, so the
/// throughput f |cos| / pdf is 1 for reflection and 1/eta_rel^2 for refraction
/// (radiance is compressed into the smaller solid angle of the denser side).
/// A tint (specular_reflectance / specular_transmittance) multiplies the
/// lobe's weight only: the lobe probabilities stay F and 1 - F.
class Dielectric final : public Bsdf {
public:
    Dielectric(float eta, std::shared_ptr<Texture> r, std::shared_ptr<Texture> t)
        : eta_(eta), r_(std::move(r)), t_(std::move(t)) {}

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2&) const override {
        if (wo.z == 0.f) return std::nullopt;
        const Geometry g = geometry(wo);
        if (u_lobe < g.F) return tinted(reflection(wo, g), r_, uv);
        return tinted(transmission(wo, g), t_, uv);
    }

    Color eval(const Vec3&, const Vec3&, const Vec2&) const override { return Color(0.f); }
    float pdf(const Vec3&, const Vec3&, const Vec2&) const override { return 0.f; }

    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (wo.z == 0.f || wi.z == 0.f) return std::nullopt;
        const Geometry g = geometry(wo);
        const bool refl = same_hemisphere(wo, wi);
        auto s = refl ? reflection(wo, g) : transmission(wo, g);
        if (!s || glm::length(s->wi - wi) > kDeltaTolerance) return std::nullopt;
        return tinted(s, refl ? r_ : t_, uv);
    }

    uint32_t flags() const override { return kReflection | kTransmission | kSpecular; }
    Color albedo(const Vec2& uv) const override {
        return 0.5f * ((r_ ? r_->eval(uv) : Color(1.f)) + (t_ ? t_->eval(uv) : Color(1.f)));
    }
    float min_roughness() const override { return 0.f; }
    float eta() const override { return eta_; }

private:
    struct Geometry {
        float eta_rel;  // eta of wi's side / eta of wo's side for refraction
        float F;        // Fresnel reflectance (1 on total internal reflection)
        float cos_t;    // |cos| of the refracted direction
    };

    Geometry geometry(const Vec3& wo) const {
        Geometry g;
        g.eta_rel = wo.z > 0.f ? eta_ : 1.f / eta_;
        g.F = fresnel_dielectric(std::abs(wo.z), g.eta_rel, g.cos_t);
        return g;
    }

    static std::optional<BsdfSample> reflection(const Vec3& wo, const Geometry& g) {
        if (g.F <= 0.f) return std::nullopt;
        BsdfSample s;
        s.wi = Vec3(-wo.x, -wo.y, wo.z);
        s.pdf = g.F;
        s.f = Color(g.F / std::abs(wo.z));
        s.eta = 1.f;
        s.lobe = kReflection | kSpecular;
        s.roughness = 0.f;
        return s;
    }

    static std::optional<BsdfSample> transmission(const Vec3& wo, const Geometry& g) {
        if (g.F >= 1.f || g.cos_t <= 0.f) return std::nullopt;  // total internal reflection
        BsdfSample s;
        // Snell: the tangential component shrinks by 1/eta_rel, the normal one flips side.
        s.wi = Vec3(-wo.x / g.eta_rel, -wo.y / g.eta_rel, wo.z > 0.f ? -g.cos_t : g.cos_t);
        s.pdf = 1.f - g.F;
        s.f = Color((1.f - g.F) / (g.eta_rel * g.eta_rel) / g.cos_t);
        s.eta = g.eta_rel;
        s.lobe = kTransmission | kSpecular;
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

std::shared_ptr<Bsdf> make_dielectric(float eta) { return make_dielectric(eta, nullptr, nullptr); }

std::shared_ptr<Bsdf> make_dielectric(float eta, std::shared_ptr<Texture> reflectance,
                                      std::shared_ptr<Texture> transmittance) {
    if (!(eta > 0.f) || !std::isfinite(eta))
        throw ParameterError("dielectric: index of refraction must be a positive number, got " + std::to_string(eta));
    return std::make_shared<Dielectric>(eta, std::move(reflectance), std::move(transmittance));
}

}  // namespace gdr
