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
#include "diffuse_glossy.h"

namespace gdr {
namespace {

/// The specular lobe is sampled as the cosine power around the mirror
/// direction r, density (n + 1) / (2 pi) cos^n a over the whole sphere
/// (samples below the horizon are rejected, as Mitsuba does).
class Phong final : public detail::DiffuseGlossy<Phong> {
public:
    Phong(std::shared_ptr<Texture> kd, std::shared_ptr<Texture> ks, float exponent, float scale)
        : DiffuseGlossy(std::move(kd), std::move(ks), scale), n_(exponent) {
        spec_norm_ = (n_ + 2.f) * (0.5f * kInvPi);
        pdf_norm_ = (n_ + 1.f) * (0.5f * kInvPi);
    }

    /// The specular lobe's roughness is the GGX alpha of equal highlight
    /// width, sqrt(2 / (n + 2)) (phong_to_alpha; Walter et al. 2007, "Microfacet
    /// models for refraction through rough surfaces", section 5.2), at most 1.
    float min_roughness() const override { return has_spec_ ? std::min(phong_to_alpha(n_), 1.f) : 1.f; }

private:
    friend class detail::DiffuseGlossy<Phong>;

    static Vec3 mirror(const Vec3& w) { return {-w.x, -w.y, w.z}; }

    std::optional<Vec3> sample_glossy(const Vec3& wo_up, const Vec2& u) const {
        // cos a = u^(1/(n+1)) has density (n+1) cos^n a on [0,1] in cos a.
        const float cos_a = std::pow(std::max(u.x, 0.f), 1.f / (n_ + 1.f));
        const float sin_a = safe_sqrt(1.f - cos_a * cos_a);
        const float phi = 2.f * kPi * u.y;
        const Frame fr(mirror(wo_up));
        return fr.to_world(Vec3(sin_a * std::cos(phi), sin_a * std::sin(phi), cos_a));
    }

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

    float n_;
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
