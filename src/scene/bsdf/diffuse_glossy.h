// A Lambertian lobe plus a glossy lobe, two-sided, as Mitsuba's `phong` and
// `ward` combine them: lobes are picked with Mitsuba's weight
// ks_mean / (kd_mean + ks_mean) (channel averages), and sample() returns the
// sum of both lobes with the mixture pdf.
#pragma once

#include "gdr/scene/bsdf.h"
#include "gdr/scene/warp.h"

namespace gdr::detail {

/// Base of two-sided diffuse-plus-glossy reflection. Derived (CRTP) supplies
/// sample_glossy(wo_up, u) -> std::optional<Vec3> (a direction, any side, or
/// nothing), eval_up(wo_up, wi_up, uv) -> Color (f, 1/sr) and
/// pdf_up(wo_up, wi_up) -> float (the mixture's solid-angle density, 1/sr),
/// all for wo, wi mirrored to the upper hemisphere, and min_roughness().
template <class Derived>
class DiffuseGlossy : public Bsdf {
public:
    DiffuseGlossy(std::shared_ptr<Texture> kd, std::shared_ptr<Texture> ks, float scale)
        : kd_(std::move(kd)), ks_(std::move(ks)), scale_(scale) {
        const auto avg = [](const Color& c) { return (c.r + c.g + c.b) / 3.f; };
        const float wd = std::max(0.f, avg(kd_->mean())), ws = std::max(0.f, avg(ks_->mean()));
        has_spec_ = max_component(ks_->mean()) > 0.f || !ks_->is_constant();
        has_diffuse_ = max_component(kd_->mean()) > 0.f || !kd_->is_constant();
        p_spec_ = wd + ws > 0.f ? ws / (wd + ws) : 0.f;
        if (!has_spec_) p_spec_ = 0.f;
        if (!has_diffuse_ && has_spec_) p_spec_ = 1.f;
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        if (wo.z == 0.f) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;
        const Vec3 wo_up = up(wo);
        Vec3 wi_up;
        BsdfSample s;
        if (u_lobe < p_spec_) {
            const std::optional<Vec3> g = derived().sample_glossy(wo_up, u);
            if (!g) return std::nullopt;
            wi_up = *g;
            s.lobe = kReflection | kGlossy;
            s.roughness = derived().min_roughness();
        } else {
            wi_up = warp::square_to_cosine_hemisphere(u);
            s.lobe = kReflection | kDiffuse;
            s.roughness = 1.f;
        }
        if (wi_up.z <= 0.f) return std::nullopt;
        s.pdf = derived().pdf_up(wo_up, wi_up);
        if (!(s.pdf > 0.f)) return std::nullopt;
        s.f = derived().eval_up(wo_up, wi_up, uv);
        s.wi = Vec3(wi_up.x, wi_up.y, side * wi_up.z);
        s.eta = 1.f;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        if (!same_hemisphere(wo, wi)) return Color(0.f);
        return derived().eval_up(up(wo), up(wi), uv);
    }

    float pdf(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (!same_hemisphere(wo, wi)) return 0.f;
        return derived().pdf_up(up(wo), up(wi));
    }

    uint32_t flags() const override {
        return kReflection | (has_diffuse_ ? kDiffuse : 0u) | (has_spec_ ? kGlossy : 0u);
    }
    Color albedo(const Vec2& uv) const override { return (kd_->eval(uv) + ks_->eval(uv)) * scale_; }

protected:
    static Vec3 up(const Vec3& w) { return {w.x, w.y, std::abs(w.z)}; }

    std::shared_ptr<Texture> kd_, ks_;
    float scale_;
    float p_spec_ = 0.f;  ///< Probability of sampling the glossy lobe.
    bool has_spec_ = false, has_diffuse_ = false;

private:
    const Derived& derived() const { return static_cast<const Derived&>(*this); }
};

}  // namespace gdr::detail
