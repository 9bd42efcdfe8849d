// Cosine-weighted sampling of two-sided diffuse reflection, shared by the
// Lambertian and Oren-Nayar BSDFs.
#pragma once

#include <optional>

#include "gdr/scene/bsdf.h"
#include "gdr/scene/warp.h"

namespace gdr::detail {

/// Samples wi by the cosine on wo's side; f_up(wi_up) gives the BSDF value
/// (1/sr) for wi mirrored to the upper hemisphere. Nothing for a grazing wo or
/// sample (zero pdf, would divide by 0).
template <class F>
std::optional<BsdfSample> sample_two_sided_cosine(const Vec3& wo, const Vec2& u, F&& f_up) {
    if (wo.z == 0.f) return std::nullopt;
    Vec3 wi = warp::square_to_cosine_hemisphere(u);
    if (wi.z <= 0.f) return std::nullopt;
    BsdfSample s;
    s.pdf = warp::cosine_hemisphere_pdf(wi);
    s.f = f_up(wi);
    if (wo.z < 0.f) wi.z = -wi.z;  // two-sided: scatter back to wo's side
    s.wi = wi;
    s.eta = 1.f;
    s.lobe = kReflection | kDiffuse;
    s.roughness = 1.f;
    return s;
}

/// Solid-angle density (1/sr) of sample_two_sided_cosine: |cos wi| / pi on wo's side, else 0.
inline float two_sided_cosine_pdf(const Vec3& wo, const Vec3& wi) {
    return same_hemisphere(wo, wi) ? abs_cos_theta(wi) * kInvPi : 0.f;
}

}  // namespace gdr::detail
