// A diffuse base under a smooth or rough dielectric coating, as Mitsuba's
// `plastic` and `roughplastic` describe it (Jakob, "Mitsuba renderer
// documentation", version 0.5/0.6, plugins plastic and roughplastic), after
// the layered model of Weidlich and Wilkie, "Arbitrarily layered micro-facet
// surfaces" (GRAPHITE 2007):
//   f = ks F(wo.h) D G2 / (4 cos_o cos_i)
//     + kd' T(cos_o) T(cos_i) / (eta^2 pi),
// where F is the dielectric Fresnel reflectance of the coating, T(cos) the
// fraction of light the (rough) coating lets through from outside at that
// angle, and kd' = kd / (1 - Fdr (nonlinear ? kd : 1)) sums the light that
// bounces between the base and the coating's underside, Fdr being the
// coating's reflectance for diffuse light from inside. The Fresnel factors
// make the coating reflect much more at grazing angles than at normal
// incidence (0.04 for eta 1.5), which is what makes a varnished floor show
// its windows.
#include <array>

#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"
#include "gdr/scene/warp.h"
#include "plastic_lobes.h"

namespace gdr {

namespace detail {

/// Quadrature points per axis over the microfacet normals of one cosine.
constexpr int kQuadrature = 32;

/// Transmittance of a rough dielectric interface (eta = far side / near side)
/// for light arriving at cosine `cos_o`: the share of the microfacets seen from
/// wo, weighted by what each lets through, 1 - F(wo.m). Integrated over the
/// microfacet normals by importance sampling on a fixed stratified grid, so
/// the value is deterministic. At alpha -> 0 it becomes 1 - F(cos_o).
double rough_transmittance(const Microfacet& mf, float eta, float cos_o) {
    const float c = std::clamp(cos_o, 1e-4f, 1.f);
    const Vec3 wo(std::sqrt(std::max(0.f, 1.f - c * c)), 0.f, c);
    const float g1 = 1.f / (1.f + mf.lambda(wo));
    double sum = 0.0;
    for (int j = 0; j < kQuadrature; ++j)
        for (int i = 0; i < kQuadrature; ++i) {
            const Vec2 u((float(i) + 0.5f) / kQuadrature, (float(j) + 0.5f) / kQuadrature);
            const Vec3 m = mf.sample_normal(wo, u);
            const float pdf = mf.sample_normal_pdf(wo, m);
            const float wom = glm::dot(wo, m);
            if (!(pdf > 0.f) || wom <= 0.f) continue;
            // Density of normals seen from wo: G1 (wo.m) D(m) / cos_o.
            const double visible = double(g1) * wom * mf.d(m) / c;
            sum += (1.0 - fresnel_dielectric(wom, eta)) * visible / pdf;
        }
    return std::clamp(sum / double(kQuadrature * kQuadrature), 0.0, 1.0);
}

}  // namespace detail

namespace {

using detail::rough_transmittance;

/// Cosines at which the coating's transmittance is tabulated (uniform in cos).
constexpr int kTableSize = 64;

class CoatedPlastic final : public Bsdf {
public:
    CoatedPlastic(std::shared_ptr<Texture> kd, const Color& ks, float eta, Microfacet mf, bool nonlinear)
        : kd_(std::move(kd)), ks_(ks), eta_(eta), mf_(mf), nonlinear_(nonlinear) {
        for (int k = 0; k < kTableSize; ++k)
            t_ext_[size_t(k)] = float(rough_transmittance(mf_, eta_, float(k) / float(kTableSize - 1)));
        // Fdr: the coating's reflectance for diffuse (cosine-distributed) light
        // from inside, 1 - 2 integral T_int(mu) mu dmu, by the midpoint rule.
        constexpr int n = 64;
        double t = 0.0;
        for (int i = 0; i < n; ++i) {
            const float mu = (float(i) + 0.5f) / float(n);
            t += rough_transmittance(mf_, 1.f / eta_, mu) * mu;
        }
        fdr_ = float(std::clamp(1.0 - 2.0 * t / n, 0.0, 1.0));
        inv_eta2_ = 1.f / (eta_ * eta_);
        kd_mean_ = coated(kd_->mean());
        wd_ = std::max(0.f, luminance(kd_mean_ * inv_eta2_));
        ws_ = std::max(0.f, luminance(ks_));
        has_diffuse_ = max_component(kd_->mean()) > 0.f || !kd_->is_constant();
        has_spec_ = ws_ > 0.f;
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;
        const Vec3 wo_up = up(wo);
        const float ps = p_spec(wo_up.z);
        BsdfSample s;
        const std::optional<Vec3> sampled = detail::sample_plastic_lobe(u_lobe >= ps, mf_, wo_up, u, s);
        if (!sampled) return std::nullopt;
        const Vec3 wi_up = *sampled;
        const GgxReflection g = mf_.reflection(wo_up, wi_up);
        s.pdf = pdf_up(g, wo_up, wi_up);
        if (!(s.pdf > 0.f)) return std::nullopt;
        s.f = eval_up(g, wo_up, wi_up, uv);
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.eta = 1.f;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return eval_up(mf_.reflection(up(wo), up(wi)), up(wo), up(wi), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return 0.f;
        return pdf_up(mf_.reflection(up(wo), up(wi)), up(wo), up(wi));
    }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return {};
        const Vec3 wo_up = up(wo), wi_up = up(wi);
        const GgxReflection g = mf_.reflection(wo_up, wi_up);
        return {eval_up(g, wo_up, wi_up, uv), pdf_up(g, wo_up, wi_up)};
    }

    uint32_t flags() const override {
        return kReflection | (has_diffuse_ ? kDiffuse : 0u) | (has_spec_ || !has_diffuse_ ? kGlossy : 0u);
    }
    // At normal incidence: the base seen through the coating twice, plus the coating's own reflection.
    Color albedo(const Vec2& uv) const override {
        const float t0 = t_ext_.back();
        return coated(kd_->eval(uv)) * (t0 * t0 * inv_eta2_) + ks_ * (1.f - t0);
    }
    float min_roughness() const override { return std::min(mf_.alpha, 1.f); }
    bool is_black() const override { return !has_diffuse_ && !has_spec_; }

private:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }

    // kd' of the base: the light that leaves it after any number of bounces under the coating.
    Color coated(const Color& kd) const {
        Color r;
        for (int i = 0; i < 3; ++i) {
            const float denom = 1.f - fdr_ * (nonlinear_ ? kd[i] : 1.f);
            r[i] = denom > 0.f ? kd[i] / denom : 0.f;
        }
        return r;
    }

    // T(cos) of the coating from outside, interpolated linearly in the table.
    float t_ext(float cos_t) const {
        const float x = std::clamp(cos_t, 0.f, 1.f) * float(kTableSize - 1);
        const int k = std::min(int(x), kTableSize - 2);
        const float f = x - float(k);
        return t_ext_[size_t(k)] * (1.f - f) + t_ext_[size_t(k + 1)] * f;
    }

    // Probability of sampling the coating's lobe: the coating's reflectance at wo
    // against the diffuse light it lets through, kept within [0.05, 0.95] where
    // both lobes exist so that neither is starved.
    float p_spec(float cos_o) const {
        if (!has_spec_) return 0.f;
        if (!has_diffuse_) return 1.f;
        const float t = t_ext(cos_o);
        const float s = (1.f - t) * ws_, d = t * wd_;
        return s + d > 0.f ? std::clamp(s / (s + d), 0.05f, 0.95f) : 0.5f;
    }

    Color eval_up(const GgxReflection& g, const Vec3& wo_up, const Vec3& wi_up, const Vec2& uv) const {
        Color f(0.f);
        if (has_diffuse_)
            f += coated(kd_->eval(uv)) * (t_ext(wo_up.z) * t_ext(wi_up.z) * inv_eta2_ * kInvPi);
        if (has_spec_ && g.value > 0.f) f += ks_ * (fresnel_dielectric(glm::dot(wo_up, g.h), eta_) * g.value);
        return f;
    }

    float pdf_up(const GgxReflection& g, const Vec3& wo_up, const Vec3& wi_up) const {
        const float ps = p_spec(wo_up.z);
        return (1.f - ps) * warp::cosine_hemisphere_pdf(wi_up) + ps * g.pdf;
    }

    std::shared_ptr<Texture> kd_;
    Color ks_;
    float eta_;
    Microfacet mf_;
    bool nonlinear_;
    std::array<float, kTableSize> t_ext_{};
    float fdr_ = 0.f, inv_eta2_ = 1.f;
    Color kd_mean_{0.f};
    float wd_ = 0.f, ws_ = 0.f;
    bool has_diffuse_ = true, has_spec_ = true;
};

}  // namespace

std::shared_ptr<Bsdf> make_coated_plastic(std::shared_ptr<Texture> kd, const Color& ks, float eta, float alpha,
                                          MicrofacetType type, bool nonlinear) {
    if (!std::isfinite(alpha) || alpha < 0.f)
        throw ParameterError("plastic: alpha must be a non-negative number, got " + std::to_string(alpha));
    if (!std::isfinite(eta) || !(eta > 0.f))
        throw ParameterError("plastic: the coating's relative index of refraction must be positive, got " +
                             std::to_string(eta));
    if (!kd) kd = make_constant_texture(Color(0.f));
    return std::make_shared<CoatedPlastic>(std::move(kd), ks, eta, Microfacet{type, std::max(alpha, kMinGgxAlpha)},
                                           nonlinear);
}

}  // namespace gdr
