// Ideal mirror (MTL illum 5) and smooth conductor (Mitsuba's conductor): a
// single delta reflection lobe, two-sided.
#include <fmt/format.h>

#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"

namespace gdr {
namespace {

/// Direction tolerance (Euclidean distance of unit vectors) for recognising a
/// wi as the mirror direction in eval_delta; loose enough for float round-off
/// of a direction that went through world<->local frames and ray offsets.
constexpr float kDeltaTolerance = 1e-3f;

/// Perfect specular reflection of reflectance r (no Fresnel, as MTL illum 5),
/// or of r times the exact Fresnel reflectance of `ior` at the angle of
/// reflection where ior is given.
class Mirror final : public Bsdf {
public:
    explicit Mirror(const Color& r, std::optional<ConductorIor> ior = std::nullopt) : r_(r), ior_(ior) {}

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2&, float, const Vec2&) const override {
        if (wo.z == 0.f) return std::nullopt;
        return make(Vec3(-wo.x, -wo.y, wo.z));
    }

    Color eval(const Vec3&, const Vec3&, const Vec2&) const override { return Color(0.f); }
    float pdf(const Vec3&, const Vec3&, const Vec2&) const override { return 0.f; }

    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2&) const override {
        if (wo.z == 0.f || !same_hemisphere(wo, wi)) return std::nullopt;
        const Vec3 wr(-wo.x, -wo.y, wo.z);
        if (glm::length(wi - wr) > kDeltaTolerance) return std::nullopt;
        return make(wr);  // the exact mirror direction, so f matches sample() bit for bit
    }

    uint32_t flags() const override { return kReflection | kSpecular; }
    Color albedo(const Vec2&) const override { return ior_ ? r_ * fresnel_conductor(*ior_, 1.f) : r_; }
    float min_roughness() const override { return 0.f; }

private:
    BsdfSample make(const Vec3& wi) const {
        BsdfSample s;
        s.wi = wi;
        const Color r = ior_ ? r_ * fresnel_conductor(*ior_, wi.z) : r_;
        s.f = r / abs_cos_theta(wi);  // so that f |cos| / pdf = r
        s.pdf = 1.f;
        s.eta = 1.f;
        s.lobe = kReflection | kSpecular;
        s.roughness = 0.f;
        return s;
    }

    Color r_;
    std::optional<ConductorIor> ior_;
};

}  // namespace

void check_conductor_ior(const ConductorIor& ior, const std::string& what) {
    for (int i = 0; i < 3; ++i)
        if (!(ior.eta[i] >= 0.f && ior.k[i] >= 0.f && std::isfinite(ior.eta[i]) && std::isfinite(ior.k[i])))
            throw ParameterError(fmt::format("{}: eta ({}, {}, {}) and k ({}, {}, {}) must be finite and >= 0", what,
                                             ior.eta.r, ior.eta.g, ior.eta.b, ior.k.r, ior.k.g, ior.k.b));
}

std::shared_ptr<Bsdf> make_mirror(const Color& r) { return std::make_shared<Mirror>(r); }

std::shared_ptr<Bsdf> make_conductor(const ConductorIor& ior, const Color& tint) {
    check_conductor_ior(ior, "conductor");
    return std::make_shared<Mirror>(tint, ior);
}

}  // namespace gdr
