// Oren-Nayar rough diffuse reflection (Oren and Nayar, "Generalization of
// Lambert's reflectance model", SIGGRAPH 1994), as Mitsuba's `roughdiffuse`
// defines it: the surface is a field of V-cavities whose slopes have standard
// deviation sigma = alpha / sqrt(2) (alpha the Beckmann-style RMS slope). The
// full model adds to the single-scattering terms C1..C3 (the paper's eq. 30)
// the two-bounce interreflection term (its eq. 31), which grows as albedo^2;
// the qualitative model keeps A + B max(0, cos dphi) sin(a) tan(b) only.
// Two-sided, sampled by the cosine like a Lambertian.
#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"
#include "cosine_lobe.h"

namespace gdr {
namespace {

class OrenNayar final : public Bsdf {
public:
    OrenNayar(std::shared_ptr<Texture> kd, float alpha, bool fast) : kd_(std::move(kd)), fast_(fast) {
        const float sigma = alpha / std::sqrt(2.f);
        s2_ = sigma * sigma;
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float, const Vec2& u) const override {
        return detail::sample_two_sided_cosine(wo, u, [&](const Vec3& wi_up) { return value(up(wo), wi_up, uv); });
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return value(up(wo), up(wi), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        return detail::two_sided_cosine_pdf(wo, wi);
    }

    uint32_t flags() const override { return kReflection | kDiffuse; }
    Color albedo(const Vec2& uv) const override { return kd_->eval(uv); }
    float min_roughness() const override { return 1.f; }

private:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }

    // f for wo, wi in the upper hemisphere.
    Color value(const Vec3& wo, const Vec3& wi, const Vec2& uv) const {
        const Color rho = kd_->eval(uv);
        const float sin_o = safe_sqrt(1.f - wo.z * wo.z), sin_i = safe_sqrt(1.f - wi.z * wi.z);
        // cos(phi_i - phi_o) from the tangential components (0 when either is along the normal).
        float cos_dphi = 0.f;
        if (sin_o > 1e-6f && sin_i > 1e-6f)
            cos_dphi = std::clamp((wo.x * wi.x + wo.y * wi.y) / (sin_o * sin_i), -1.f, 1.f);
        // alpha = max(theta_i, theta_o), beta = min: the larger angle has the smaller cosine.
        const bool i_larger = wi.z < wo.z;
        const float sin_a = i_larger ? sin_i : sin_o;
        const float sin_b = i_larger ? sin_o : sin_i, cos_b = i_larger ? wo.z : wi.z;
        const float tan_b = sin_b / std::max(cos_b, 1e-7f);
        const float a = s2_ / (s2_ + 0.33f), b = s2_ / (s2_ + 0.09f);
        if (fast_) {
            const float k = (1.f - 0.5f * a) + 0.45f * b * std::max(cos_dphi, 0.f) * sin_a * tan_b;
            return rho * (k * kInvPi);
        }
        const float th_a = std::acos(std::clamp(i_larger ? wi.z : wo.z, -1.f, 1.f));
        const float th_b = std::acos(std::clamp(cos_b, -1.f, 1.f));
        const float two_b_pi = 2.f * th_b * kInvPi;
        const float c1 = 1.f - 0.5f * a;
        const float c2 = 0.45f * b * (cos_dphi >= 0.f ? sin_a : sin_a - two_b_pi * two_b_pi * two_b_pi);
        const float four_ab = 4.f * th_a * th_b * kInvPi * kInvPi;
        const float c3 = 0.125f * b * four_ab * four_ab;
        const float tan_half = std::tan(0.5f * (th_a + th_b));
        const float single = c1 + cos_dphi * c2 * tan_b + (1.f - std::abs(cos_dphi)) * c3 * tan_half;
        const float twice = 0.17f * s2_ / (s2_ + 0.13f) * (1.f - cos_dphi * two_b_pi * two_b_pi);
        return (rho * single + rho * rho * twice) * kInvPi;
    }

    std::shared_ptr<Texture> kd_;
    bool fast_;
    float s2_ = 0.f;  // sigma^2
};

}  // namespace

std::shared_ptr<Bsdf> make_oren_nayar(std::shared_ptr<Texture> kd, float alpha, bool fast) {
    if (!std::isfinite(alpha) || alpha < 0.f)
        throw ParameterError("roughdiffuse: alpha must be a non-negative number, got " + std::to_string(alpha));
    if (!kd) kd = make_constant_texture(Color(0.5f));
    return std::make_shared<OrenNayar>(std::move(kd), alpha, fast);
}

}  // namespace gdr
