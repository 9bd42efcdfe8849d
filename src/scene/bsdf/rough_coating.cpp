// A rough dielectric coating over a nested BSDF, as Mitsuba's `roughcoating`
// defines it (Jakob, "Mitsuba renderer documentation", version 0.5/0.6,
// plugin roughcoating: "a very approximate model", the roughened version of
// `coating`). The interface reflects as a rough dielectric,
//   f_s = specular_reflectance F(wi.h) D G2 / (4 cos_o cos_i),
// and lets through the fraction T(cos) of light a rough interface transmits
// at each of the two angles; inside, the light is refracted as if the
// coating were smooth, scattered once by the nested BSDF between the
// refracted directions wo', wi', and absorbed along both segments:
//   f_n = T(cos_o) T(cos_i) A f_nested(wo', wi') / eta^2,
// A = exp(-sigma_a d (1 / |cos_o'| + 1 / |cos_i'|)). As in the smooth
// coating the layer's directions keep their side, so a glass's transmission
// leaves through a like interface on the other side. Light reflected back
// inside is lost. The interface is sampled with Mitsuba's probability, its
// share 1 - T(cos_o) reweighted towards the layer the more the layer absorbs.
#include <algorithm>
#include <array>
#include <cmath>

#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"
#include "layer_refraction.h"
#include "plastic_lobes.h"

namespace gdr {
namespace {

/// Cosines at which the interface's transmittance is tabulated (uniform in cos).
constexpr int kTableSize = 64;

class RoughCoating final : public Bsdf {
public:
    RoughCoating(std::shared_ptr<Bsdf> nested, float eta, Microfacet mf, const Color& sigma_a_thickness,
                 const Color& specular)
        : nested_(std::move(nested)), eta_(eta), mf_(mf), sigma_(sigma_a_thickness), specular_(specular) {
        for (int k = 0; k < kTableSize; ++k)
            t_[size_t(k)] = float(detail::rough_transmittance(mf_, eta_, float(k) / float(kTableSize - 1)));
        const Color a = glm::exp(-2.f * sigma_);
        w_specular_ = 1.f / ((a.r + a.g + a.b) / 3.f + 1.f);
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float p_spec = specular_probability(std::abs(wo.z));
        BsdfSample s;
        Vec3 wi;
        if (u_lobe < p_spec) {
            // The interface's glossy reflection, about a sampled microfacet normal.
            const Vec3 wo_up(wo.x, wo.y, std::abs(wo.z));
            const Vec3 m = mf_.sample_normal(wo_up, u);
            if (glm::dot(wo_up, m) <= 0.f) return std::nullopt;
            const Vec3 wi_up = reflect(wo_up, m);
            if (wi_up.z <= 0.f) return std::nullopt;
            wi = Vec3(wi_up.x, wi_up.y, wo.z > 0.f ? wi_up.z : -wi_up.z);
            s.lobe = kReflection | kGlossy;
            s.roughness = mf_.alpha;
            s.eta = 1.f;
        } else {
            Vec3 wo_in;
            if (!detail::refract_into_layer(wo, eta_, wo_in)) return std::nullopt;
            const float u_nested = std::min((u_lobe - p_spec) / (1.f - p_spec), 0x1.fffffep-1f);
            const auto ns = nested_->sample(wo_in, uv, u_nested, u);
            if (!ns || ns->wi.z == 0.f) return std::nullopt;
            if (!detail::refract_out_of_layer(ns->wi, eta_, wi)) return std::nullopt;  // trapped by total internal reflection: lost
            if (ns->is_delta()) return eval_delta(wo, wi, uv);
            s.lobe = ns->lobe;
            s.roughness = ns->roughness;
            s.eta = ns->eta;
        }
        // A smooth sample carries the whole BSDF's value and density (one-sample MIS of the two choices).
        const BsdfEval e = eval_pdf(wo, wi, uv);
        if (!(e.pdf > 0.f)) return std::nullopt;
        s.wi = wi;
        s.f = e.f;
        s.pdf = e.pdf;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override { return eval_pdf(wo, wi, uv).f; }
    float pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override { return eval_pdf(wo, wi, uv).pdf; }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        BsdfEval r;
        if (wo.z == 0.f || wi.z == 0.f) return r;
        const float p_spec = specular_probability(std::abs(wo.z));
        if (same_hemisphere(wo, wi)) {
            const Vec3 wo_up(wo.x, wo.y, std::abs(wo.z)), wi_up(wi.x, wi.y, std::abs(wi.z));
            const GgxReflection g = mf_.reflection(wo_up, wi_up);
            if (g.value > 0.f) r.f += specular_ * (fresnel_dielectric(glm::dot(wi_up, g.h), eta_) * g.value);
            r.pdf += p_spec * g.pdf;
        }
        Vec3 wo_in, wi_in;
        if (!pair_inside(wo, wi, wo_in, wi_in)) return r;
        const BsdfEval n = nested_->eval_pdf(wo_in, wi_in, uv);
        r.f += layer(wo, wi, wo_in, wi_in) * n.f;
        r.pdf += (1.f - p_spec) * n.pdf * std::abs(wi.z) / (eta_ * eta_ * std::abs(wi_in.z));
        return r;
    }

    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        // Only the nested BSDF has delta lobes: reached through the layer.
        Vec3 wo_in, wi_in;
        if (wo.z == 0.f || wi.z == 0.f || !pair_inside(wo, wi, wo_in, wi_in)) return std::nullopt;
        const auto nd = nested_->eval_delta(wo_in, wi_in, uv);
        if (!nd || !(nd->pdf > 0.f)) return std::nullopt;
        BsdfSample s = *nd;
        s.wi = wi;
        // f |cos wi| is the lobe's share of the light: the nested one's, nd->f |cos wi'|, through both interfaces.
        s.f = nd->f * (layer(wo, wi, wo_in, wi_in) * (eta_ * eta_) * std::abs(wi_in.z) / std::abs(wi.z));
        s.pdf = (1.f - specular_probability(std::abs(wo.z))) * nd->pdf;
        return s;
    }

    uint32_t flags() const override { return nested_->flags() | kReflection | kGlossy; }
    Color albedo(const Vec2& uv) const override { return nested_->albedo(uv); }
    float min_roughness() const override { return std::min(mf_.alpha, nested_->min_roughness()); }
    float eta() const override { return nested_->eta(); }  // refracting in and out, a glass's index remains

private:
    /// The interface's transmittance at |cos| c, interpolated in the table.
    float transmittance(float c) const {
        const float x = std::clamp(c, 0.f, 1.f) * float(kTableSize - 1);
        const int i = std::min(int(x), kTableSize - 2);
        const float t = x - float(i);
        return t_[size_t(i)] * (1.f - t) + t_[size_t(i) + 1] * t;
    }

    /// Probability of sampling the interface's reflection for a wo at cos_o (Mitsuba's).
    float specular_probability(float cos_o) const {
        const float r = 1.f - transmittance(cos_o);
        const float a = r * w_specular_, b = (1.f - r) * (1.f - w_specular_);
        return a + b > 0.f ? a / (a + b) : 0.f;
    }

    /// Both directions inside the layer; false where the nested BSDF cannot
    /// connect them (opposite sides without transmission) or one is trapped.
    bool pair_inside(const Vec3& wo, const Vec3& wi, Vec3& wo_in, Vec3& wi_in) const {
        if (!same_hemisphere(wo, wi) && !(nested_->flags() & kTransmission)) return false;
        return detail::refract_into_layer(wo, eta_, wo_in) && detail::refract_into_layer(wi, eta_, wi_in);
    }

    /// The factor on the nested value: both transmittances, the absorption and 1 / eta^2.
    Color layer(const Vec3& wo, const Vec3& wi, const Vec3& wo_in, const Vec3& wi_in) const {
        const Color a = glm::exp(-sigma_ * (1.f / std::abs(wo_in.z) + 1.f / std::abs(wi_in.z)));
        return a * (transmittance(std::abs(wo.z)) * transmittance(std::abs(wi.z)) / (eta_ * eta_));
    }

    std::shared_ptr<Bsdf> nested_;
    float eta_;
    Microfacet mf_;
    Color sigma_, specular_;
    std::array<float, kTableSize> t_{};
    float w_specular_ = 0.5f;
};

}  // namespace

std::shared_ptr<Bsdf> make_rough_coating(std::shared_ptr<Bsdf> nested, float eta, float alpha, MicrofacetType type,
                                         const Color& sigma_a_thickness, const Color& specular_reflectance) {
    if (!nested) throw ParameterError("roughcoating: a nested BSDF is required");
    if (!(eta > 0.f) || !std::isfinite(eta) || eta == 1.f)
        throw ParameterError("roughcoating: the relative index must be finite, > 0 and not 1");
    if (!(alpha >= 0.f) || !std::isfinite(alpha)) throw ParameterError("roughcoating: alpha must be finite and >= 0");
    if (!is_finite(sigma_a_thickness) || sigma_a_thickness.r < 0.f || sigma_a_thickness.g < 0.f ||
        sigma_a_thickness.b < 0.f)
        throw ParameterError("roughcoating: sigma_a times thickness must be finite and >= 0");
    return std::make_shared<RoughCoating>(std::move(nested), eta, Microfacet{type, std::max(alpha, kMinGgxAlpha)},
                                          sigma_a_thickness, glm::clamp(specular_reflectance, Color(0.f), Color(1.f)));
}

}  // namespace gdr
