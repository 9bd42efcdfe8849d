// Lambertian (ideal diffuse) reflection, two-sided, with a textured albedo.
#include "gdr/scene/bsdf.h"
#include "cosine_lobe.h"

namespace gdr {
namespace {

/// f = kd / pi on the side of wo; cosine-weighted sampling makes f cos / pdf = kd.
class Lambertian final : public Bsdf {
public:
    explicit Lambertian(std::shared_ptr<Texture> kd)
        : kd_(std::move(kd)), constant_(kd_->is_constant()), f_const_(kd_->mean() * kInvPi) {}

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float, const Vec2& u) const override {
        return detail::sample_two_sided_cosine(wo, u, [&](const Vec3&) { return f(uv); });
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return f(uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        return detail::two_sided_cosine_pdf(wo, wi);
    }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return {};
        return {f(uv), abs_cos_theta(wi) * kInvPi};
    }

    uint32_t flags() const override { return kReflection | kDiffuse; }
    Color albedo(const Vec2& uv) const override { return kd_->eval(uv); }
    float min_roughness() const override { return 1.f; }
    bool wo_side_only() const override { return true; }
    bool is_black() const override { return constant_ && gdr::is_black(f_const_); }

private:
    // kd / pi; kept for untextured materials, which are most of them, to save
    // a virtual call per evaluation.
    Color f(const Vec2& uv) const { return constant_ ? f_const_ : kd_->eval(uv) * kInvPi; }

    std::shared_ptr<Texture> kd_;
    bool constant_;
    Color f_const_;
};

}  // namespace

std::shared_ptr<Bsdf> make_lambertian(std::shared_ptr<Texture> kd) {
    if (!kd) kd = make_constant_texture(Color(0.f));
    return std::make_shared<Lambertian>(std::move(kd));
}

}  // namespace gdr
