// A smooth dielectric coating over a nested reflective BSDF, the layered
// model of Weidlich and Wilkie, "Arbitrarily Layered Micro-Facet Surfaces"
// (2007), as Mitsuba's `coating` defines it: the interface reflects
// F(cos_o) (times specular_reflectance) as a delta lobe; the rest enters,
// is scattered once by the nested BSDF between the refracted directions
// wo', wi', is attenuated by the layer's absorption along both refracted
// segments, and leaves through the interface again:
//   f(wo, wi) = (1 - F(cos_o)) (1 - F(cos_i)) A f_n(wo', wi') / eta^2,
//   A = exp(-sigma_a d (1 / cos_o' + 1 / cos_i')),
// eta = n_int / n_ext. The 1 / eta^2 is the radiance leaving the denser layer
// (n^2 law) and its solid angle entering it (eta^2 cos' d omega' = cos d omega)
// together: irradiance crosses the interface unchanged but for Fresnel. f is
// reciprocal. Light reflected back down by the interface's underside is lost
// (as in Mitsuba: the model is single-bounce within the layer). Directions
// inside the layer keep the side of the surface they came from, as in
// Mitsuba, so the coating is two-sided over a two-sided reflective BSDF, and
// over a transmitting one (a glass) light the nested BSDF sends to the other
// side leaves through an interface like the coating's there: a coated glass
// refracts by the glass's own index overall, and its delta transmission
// carries (1 - F_o)(1 - F_i) A times the glass's.
#include <algorithm>
#include <cmath>

#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"
#include "layer_refraction.h"

namespace gdr {
namespace {

/// Tolerance (Euclidean distance of unit vectors) for a wi along the mirror direction.
constexpr float kDeltaTolerance = 1e-3f;

class Coating final : public Bsdf {
public:
    Coating(std::shared_ptr<Bsdf> nested, float eta, const Color& sigma_a_thickness, std::shared_ptr<Texture> specular)
        : nested_(std::move(nested)), eta_(eta), sigma_(sigma_a_thickness), specular_(std::move(specular)) {
        // Sampling weight of the interface's reflection against the layer
        // (Mitsuba's): 1/2 for a clear layer, more the more it absorbs.
        const Color a = glm::exp(-2.f * sigma_);
        w_specular_ = 1.f / ((a.r + a.g + a.b) / 3.f + 1.f);
        spec_mean_ = specular_ ? std::max(0.f, (specular_->mean().r + specular_->mean().g + specular_->mean().b) / 3.f) : 1.f;
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float p_spec = specular_probability(std::abs(wo.z));
        if (u_lobe < p_spec) return mirror_sample(wo, uv);
        float f_o;
        Vec3 wo_in;
        if (!enter(wo, wo_in, f_o)) return std::nullopt;
        const float u_nested = std::min((u_lobe - p_spec) / (1.f - p_spec), 0x1.fffffep-1f);
        const auto ns = nested_->sample(wo_in, uv, u_nested, u);
        if (!ns || ns->wi.z == 0.f) return std::nullopt;
        const bool reflected = ns->wi.z * wo_in.z > 0.f;
        if (ns->is_delta() && reflected) return mirror_sample(wo, uv);  // a nested mirror leaves along the mirror direction
        float f_i;
        Vec3 wi;
        if (!leave(ns->wi, wi, f_i)) return std::nullopt;  // trapped by total internal reflection: lost
        if (ns->is_delta()) return eval_delta(wo, wi, uv);  // the nested glass's refraction, refracted out below
        BsdfSample s;
        s.wi = wi;
        s.f = transmitted(f_o, f_i, wo_in.z, ns->wi.z) * ns->f;
        s.pdf = (1.f - p_spec) * ns->pdf * solid_angle_ratio(wi.z, ns->wi.z);
        if (!(s.pdf > 0.f)) return std::nullopt;
        s.eta = ns->eta;
        s.lobe = ns->lobe;
        s.roughness = ns->roughness;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        const auto r = refracted(wo, wi);
        return r ? r->weight * nested_->eval(r->wo, r->wi, uv) : Color(0.f);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        const auto r = refracted(wo, wi);
        return r ? r->density * nested_->pdf(r->wo, r->wi, uv) : 0.f;
    }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        const auto r = refracted(wo, wi);
        if (!r) return {};
        const BsdfEval n = nested_->eval_pdf(r->wo, r->wi, uv);
        return {r->weight * n.f, r->density * n.pdf};
    }

    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (wo.z == 0.f || wi.z == 0.f) return std::nullopt;
        if (same_hemisphere(wo, wi)) {
            const Vec3 wr(-wo.x, -wo.y, wo.z);
            if (glm::length(wi - wr) > kDeltaTolerance) return std::nullopt;
            return mirror_sample(wo, uv);
        }
        // Through a transmitting nested BSDF's delta lobe, in and out of the layer.
        const auto r = refracted(wo, wi);
        if (!r) return std::nullopt;
        const auto nd = nested_->eval_delta(r->wo, r->wi, uv);
        if (!nd || !(nd->pdf > 0.f)) return std::nullopt;
        float f_o, f_i;
        Vec3 unused;
        enter(wo, unused, f_o), enter(wi, unused, f_i);
        BsdfSample s = *nd;
        s.wi = wi;
        // f |cos wi| is the lobe's share of the light: the nested one's, nd->f |cos wi'|, through both interfaces.
        s.f = nd->f * (absorption(r->wo.z, r->wi.z) * ((1.f - f_o) * (1.f - f_i)) * std::abs(r->wi.z) / std::abs(wi.z));
        s.pdf = (1.f - specular_probability(std::abs(wo.z))) * nd->pdf;
        return s;
    }

    uint32_t flags() const override { return nested_->flags() | kReflection | kSpecular; }
    Color albedo(const Vec2& uv) const override { return nested_->albedo(uv); }
    float min_roughness() const override { return 0.f; }
    float eta() const override { return nested_->eta(); }  // refracting in and out, the glass's index remains

private:
    /// A pair of outside directions seen inside the layer: the refracted
    /// directions (each on its own side), the factor on the nested value
    /// (transmitted()) and the one on its density (the lobe's selection
    /// probability times d omega' / d omega).
    struct Refracted {
        Vec3 wo, wi;
        Color weight;
        float density;
    };
    /// nullopt where the coating's smooth part is zero: different sides over
    /// a BSDF that does not transmit, a grazing direction, or total internal
    /// reflection.
    std::optional<Refracted> refracted(const Vec3& wo, const Vec3& wi) const {
        if (wo.z == 0.f || wi.z == 0.f) return std::nullopt;
        if (!same_hemisphere(wo, wi) && !(nested_->flags() & kTransmission)) return std::nullopt;
        Refracted r;
        float f_o, f_i;
        if (!enter(wo, r.wo, f_o) || !enter(wi, r.wi, f_i)) return std::nullopt;
        r.weight = transmitted(f_o, f_i, r.wo.z, r.wi.z);
        r.density = (1.f - specular_probability(std::abs(wo.z))) * solid_angle_ratio(wi.z, r.wi.z);
        return r;
    }

    /// Probability of sampling the interface's reflection for a wo at cos_o.
    float specular_probability(float cos_o) const {
        const float r = fresnel_dielectric(cos_o, eta_) * spec_mean_;
        const float a = r * w_specular_, b = (1.f - r) * (1.f - w_specular_);
        return a + b > 0.f ? a / (a + b) : 0.f;
    }

    /// w (outside) refracted into the layer, and the interface's Fresnel
    /// reflectance there; false on total internal reflection.
    bool enter(const Vec3& w, Vec3& w_in, float& fresnel) const {
        if (!detail::refract_into_layer(w, eta_, w_in)) return false;
        fresnel = fresnel_dielectric(std::abs(w.z), eta_);
        return fresnel < 1.f;
    }

    /// w_in (inside) refracted out, and the Fresnel term, the same from
    /// either side of the interface for one pair of angles.
    bool leave(const Vec3& w_in, Vec3& w, float& fresnel) const {
        if (!detail::refract_out_of_layer(w_in, eta_, w)) return false;
        fresnel = fresnel_dielectric(std::abs(w.z), eta_);
        return fresnel < 1.f;
    }

    /// The layer's absorption along both refracted segments.
    Color absorption(float cos_o_in, float cos_i_in) const {
        return glm::exp(-sigma_ * (1.f / std::abs(cos_o_in) + 1.f / std::abs(cos_i_in)));
    }

    /// Both Fresnel transmittances, the absorption along both refracted
    /// segments and the 1 / eta^2 of the file comment.
    Color transmitted(float f_o, float f_i, float cos_o_in, float cos_i_in) const {
        return absorption(cos_o_in, cos_i_in) * ((1.f - f_o) * (1.f - f_i) / (eta_ * eta_));
    }

    /// d omega_in / d omega outside, for the density of wi: |cos| / (eta^2 |cos'|).
    float solid_angle_ratio(float cos_out, float cos_in) const {
        return std::abs(cos_out) / (eta_ * eta_ * std::abs(cos_in));
    }

    /// The delta lobe along the mirror direction: the interface's reflection,
    /// plus the nested BSDF's own mirror lobe where it has one (refracted in
    /// and out, it leaves along the same direction; the same Fresnel
    /// transmittance both ways), with the probability that sample() produces
    /// that direction by either choice.
    std::optional<BsdfSample> mirror_sample(const Vec3& wo, const Vec2& uv) const {
        const Vec3 wr(-wo.x, -wo.y, wo.z);
        const float cos_o = std::abs(wo.z);
        const float fresnel = fresnel_dielectric(cos_o, eta_);
        const float p_spec = specular_probability(cos_o);
        Color throughput = fresnel * (specular_ ? specular_->eval(uv) : Color(1.f));
        float pdf = p_spec;
        float f_o;
        Vec3 wo_in;
        if (p_spec < 1.f && enter(wo, wo_in, f_o)) {
            if (const auto nd = nested_->eval_delta(wo_in, Vec3(-wo_in.x, -wo_in.y, wo_in.z), uv); nd && nd->pdf > 0.f) {
                const Color a = absorption(wo_in.z, wo_in.z);
                throughput += a * ((1.f - f_o) * (1.f - f_o)) * nd->f * std::abs(wo_in.z);  // nd->f |cos| is its reflectance
                pdf += (1.f - p_spec) * nd->pdf;
            }
        }
        if (!(pdf > 0.f)) return std::nullopt;
        BsdfSample s;
        s.wi = wr;
        s.f = throughput / cos_o;  // the lobe's value: f |cos| is its reflectance, f |cos| / pdf the sample's weight
        s.pdf = pdf;
        s.eta = 1.f;
        s.lobe = kReflection | kSpecular;
        s.roughness = 0.f;
        return s;
    }

    std::shared_ptr<Bsdf> nested_;
    float eta_;
    Color sigma_;
    std::shared_ptr<Texture> specular_;
    float w_specular_ = 0.5f, spec_mean_ = 1.f;
};

}  // namespace

std::shared_ptr<Bsdf> make_coating(std::shared_ptr<Bsdf> nested, float eta, const Color& sigma_a_thickness,
                                   std::shared_ptr<Texture> specular_reflectance) {
    if (!nested) throw ParameterError("coating: a nested BSDF is required");
    if (!(eta > 0.f) || !std::isfinite(eta)) throw ParameterError("coating: the relative index must be finite and > 0");
    if (!is_finite(sigma_a_thickness) || sigma_a_thickness.r < 0.f || sigma_a_thickness.g < 0.f ||
        sigma_a_thickness.b < 0.f)
        throw ParameterError("coating: sigma_a times thickness must be finite and >= 0");
    return std::make_shared<Coating>(std::move(nested), eta, sigma_a_thickness, std::move(specular_reflectance));
}

}  // namespace gdr
