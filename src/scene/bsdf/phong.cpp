// Modified Phong reflection (Lafortune and Willems, "Using the modified Phong
// reflectance model for physically based rendering", 1994), as Mitsuba's
// `phong` plugin defines it: a Lambertian lobe plus a lobe around the mirror
// direction,
//   f = kd / pi + ks (n + 2) / (2 pi) max(0, cos a)^n,  cos a = wi . reflect(wo),
// two-sided like gdr's other reflective BSDFs. The specular lobe's
// normalisation makes its albedo exactly ks at normal incidence and less
// elsewhere (part of the lobe falls below the horizon).
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/warp.h"

namespace gdr {
namespace {

/// The specular lobe is sampled as the cosine power around the mirror
/// direction r, density (n + 1) / (2 pi) cos^n a over the whole sphere
/// (samples below the horizon are rejected, as Mitsuba does); lobes are picked
/// with Mitsuba's weight ks_mean / (kd_mean + ks_mean) (channel averages).
/// sample() returns the sum of both lobes and the mixture pdf.
class Phong final : public Bsdf {
public:
    Phong(std::shared_ptr<Texture> kd, std::shared_ptr<Texture> ks, float exponent, float scale)
        : kd_(std::move(kd)), ks_(std::move(ks)), n_(exponent), scale_(scale) {
        const auto avg = [](const Color& c) { return (c.r + c.g + c.b) / 3.f; };
        const float wd = std::max(0.f, avg(kd_->mean())), ws = std::max(0.f, avg(ks_->mean()));
        p_spec_ = wd + ws > 0.f ? ws / (wd + ws) : 0.f;
        has_spec_ = max_component(ks_->mean()) > 0.f || !ks_->is_constant();
        has_diffuse_ = max_component(kd_->mean()) > 0.f || !kd_->is_constant();
        if (!has_spec_) p_spec_ = 0.f;
        if (!has_diffuse_ && has_spec_) p_spec_ = 1.f;
        spec_norm_ = (n_ + 2.f) * (0.5f * kInvPi);
        pdf_norm_ = (n_ + 1.f) * (0.5f * kInvPi);
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;
        const Vec3 wo_up = up(wo);
        Vec3 wi_up;
        BsdfSample s;
        if (u_lobe < p_spec_) {
            // cos a = u^(1/(n+1)) has density (n+1) cos^n a on [0,1] in cos a.
            const float cos_a = std::pow(std::max(u.x, 0.f), 1.f / (n_ + 1.f));
            const float sin_a = safe_sqrt(1.f - cos_a * cos_a);
            const float phi = 2.f * kPi * u.y;
            const Frame fr(mirror(wo_up));
            wi_up = fr.to_world(Vec3(sin_a * std::cos(phi), sin_a * std::sin(phi), cos_a));
            s.lobe = kReflection | kGlossy;
            s.roughness = min_roughness();
        } else {
            wi_up = warp::square_to_cosine_hemisphere(u);
            s.lobe = kReflection | kDiffuse;
            s.roughness = 1.f;
        }
        if (wi_up.z <= 0.f) return std::nullopt;
        s.pdf = pdf_up(wo_up, wi_up);
        if (!(s.pdf > 0.f)) return std::nullopt;
        s.f = eval_up(wo_up, wi_up, uv);
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.eta = 1.f;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return eval_up(up(wo), up(wi), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return 0.f;
        return pdf_up(up(wo), up(wi));
    }

    uint32_t flags() const override {
        return kReflection | (has_diffuse_ ? kDiffuse : 0u) | (has_spec_ ? kGlossy : 0u);
    }
    Color albedo(const Vec2& uv) const override { return (kd_->eval(uv) + ks_->eval(uv)) * scale_; }
    /// The specular lobe's roughness is the GGX alpha of equal highlight
    /// width, sqrt(2 / (n + 2)) (phong_to_alpha; Walter et al. 2007, "Microfacet
    /// models for refraction through rough surfaces", section 5.2), at most 1.
    float min_roughness() const override { return has_spec_ ? std::min(phong_to_alpha(n_), 1.f) : 1.f; }

private:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }
    static Vec3 mirror(const Vec3& w) { return {-w.x, -w.y, w.z}; }

    float lobe_cos_pow(const Vec3& wo_up, const Vec3& wi_up) const {
        const float c = glm::dot(wi_up, mirror(wo_up));
        return c > 0.f ? std::pow(c, n_) : 0.f;
    }

    Color eval_up(const Vec3& wo_up, const Vec3& wi_up, const Vec2& uv) const {
        Color f = kd_->eval(uv) * kInvPi;
        if (has_spec_) f += ks_->eval(uv) * (spec_norm_ * lobe_cos_pow(wo_up, wi_up));
        return f * scale_;
    }

    float pdf_up(const Vec3& wo_up, const Vec3& wi_up) const {
        float p = (1.f - p_spec_) * warp::cosine_hemisphere_pdf(wi_up);
        if (p_spec_ > 0.f) p += p_spec_ * pdf_norm_ * lobe_cos_pow(wo_up, wi_up);
        return p;
    }

    std::shared_ptr<Texture> kd_, ks_;
    float n_;
    float scale_;
    float p_spec_ = 0.f;
    bool has_spec_ = false, has_diffuse_ = false;
    float spec_norm_ = 0.f, pdf_norm_ = 0.f;
};

}  // namespace

std::shared_ptr<Bsdf> make_phong(std::shared_ptr<Texture> kd, std::shared_ptr<Texture> ks, float exponent) {
    if (!std::isfinite(exponent) || exponent < 0.f)
        throw ParameterError("phong: exponent must be a non-negative number, got " + std::to_string(exponent));
    if (!kd) kd = make_constant_texture(Color(0.f));
    if (!ks) ks = make_constant_texture(Color(0.f));
    // Mitsuba scales both weights down when kd + ks exceeds 1 in some channel
    // (of their means), so the BSDF conserves energy.
    const float m = max_component(kd->mean() + ks->mean());
    const float scale = m > 1.f ? 1.f / m : 1.f;
    return std::make_shared<Phong>(std::move(kd), std::move(ks), exponent, scale);
}

}  // namespace gdr
