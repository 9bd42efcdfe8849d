// Diffuse + glossy mixture for MTL Kd + Ks materials, two-sided.
// f = kd(uv) / pi + ks * D G2 / (4 cos_o cos_i): a Lambertian base plus an
// uncoupled GGX (or Beckmann) reflection lobe whose Fresnel is 1 (Ks already is the
// reflectance an MTL author asked for). Not energy-coupled like a layered
// model; instead both weights are scaled so that kd_mean + ks <= 1 per channel.
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"
#include "gdr/scene/warp.h"
#include "plastic_lobes.h"

namespace gdr {
namespace {

/// Lobes are picked with probability proportional to their luminance weights,
/// clamped to [0.1, 0.9] so that neither lobe is starved when both exist.
/// sample() returns the sum of both lobes and the mixture pdf (one-sample MIS),
/// which keeps f and pdf identical to eval() and pdf().
class Plastic final : public Bsdf {
public:
    Plastic(std::shared_ptr<Texture> kd, const Color& ks, Microfacet mf) : kd_(std::move(kd)), mf_(mf) {
        const Color kd_mean = kd_->mean();
        const float m = max_component(kd_mean + ks);
        scale_ = m > 1.f ? 1.f / m : 1.f;  // albedo <= 1 for the mean texel
        ks_ = ks * scale_;
        const float wd = std::max(0.f, luminance(kd_mean * scale_));
        const float wg = std::max(0.f, luminance(ks_));
        if (wd + wg <= 0.f)
            p_diffuse_ = 1.f;  // black: any valid sampler works, diffuse is cheapest
        else if (wd == 0.f)
            p_diffuse_ = 0.f;
        else if (wg == 0.f)
            p_diffuse_ = 1.f;
        else
            p_diffuse_ = std::clamp(wd / (wd + wg), 0.1f, 0.9f);
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;
        const Vec3 wo_up(wo.x, wo.y, std::abs(wo.z));
        BsdfSample s;
        const std::optional<Vec3> sampled = detail::sample_plastic_lobe(u_lobe < p_diffuse_, mf_, wo_up, u, s);
        if (!sampled) return std::nullopt;
        const Vec3 wi_up = *sampled;
        const GgxReflection g = mf_.reflection(wo_up, wi_up);
        s.pdf = pdf_up(g, wi_up);
        if (!(s.pdf > 0.f)) return std::nullopt;
        s.f = eval_up(g, uv);
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.eta = 1.f;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return eval_up(mf_.reflection(up(wo), up(wi)), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return 0.f;
        return pdf_up(mf_.reflection(up(wo), up(wi)), up(wi));
    }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return {};
        const Vec3 wi_up = up(wi);
        const GgxReflection g = mf_.reflection(up(wo), wi_up);
        return {eval_up(g, uv), pdf_up(g, wi_up)};
    }

    uint32_t flags() const override { return kReflection | kDiffuse | kGlossy; }
    Color albedo(const Vec2& uv) const override { return kd_->eval(uv) * scale_ + ks_; }
    float min_roughness() const override { return std::min(mf_.alpha, 1.f); }

private:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }

    // Value and density of a reflection into wi_up (upper hemisphere) whose GGX terms are g.
    Color eval_up(const GgxReflection& g, const Vec2& uv) const {
        return kd_->eval(uv) * (scale_ * kInvPi) + ks_ * g.value;
    }

    float pdf_up(const GgxReflection& g, const Vec3& wi_up) const {
        return p_diffuse_ * warp::cosine_hemisphere_pdf(wi_up) + (1.f - p_diffuse_) * g.pdf;
    }

    std::shared_ptr<Texture> kd_;
    Color ks_;
    Microfacet mf_;
    float scale_ = 1.f;
    float p_diffuse_ = 1.f;
};

}  // namespace

std::shared_ptr<Bsdf> make_plastic(std::shared_ptr<Texture> kd, const Color& ks, float alpha, MicrofacetType type) {
    if (!std::isfinite(alpha) || alpha < 0.f)
        throw ParameterError("plastic: alpha must be a non-negative number, got " + std::to_string(alpha));
    if (!kd) kd = make_constant_texture(Color(0.f));
    return std::make_shared<Plastic>(std::move(kd), ks, Microfacet{type, std::max(alpha, kMinGgxAlpha)});
}

}  // namespace gdr
