// The lobe choice shared by gdr's two plastics (the MTL plastic and
// Mitsuba's coated plastic): a cosine-weighted diffuse direction, or the
// mirror of a sampled microfacet normal. Internal to the library.
#pragma once

#include <optional>

#include "gdr/scene/bsdf.h"
#include "gdr/scene/microfacet.h"
#include "gdr/scene/warp.h"

namespace gdr::detail {

/// Transmittance (unitless, in [0, 1]) of a rough dielectric interface of
/// relative index eta (far side / near side) and microfacets mf, for light
/// arriving at cosine cos_o: 1 - F(wo.m) over the normals seen from wo, by a
/// fixed quadrature (deterministic). Defined in coated_plastic.cpp.
double rough_transmittance(const Microfacet& mf, float eta, float cos_o);

/// Samples a direction for wo_up (upper hemisphere): the cosine lobe if
/// `diffuse`, else the mirror of mf's sampled normal, and sets s.lobe and
/// s.roughness to the lobe's. Nothing where the direction falls below the
/// surface or Beckmann's normal faces away from wo_up.
inline std::optional<Vec3> sample_plastic_lobe(bool diffuse, const Microfacet& mf, const Vec3& wo_up, const Vec2& u,
                                               BsdfSample& s) {
    Vec3 wi_up;
    if (diffuse) {
        wi_up = warp::square_to_cosine_hemisphere(u);
        s.lobe = kReflection | kDiffuse;
        s.roughness = 1.f;
    } else {
        const Vec3 m = mf.sample_normal(wo_up, u);
        if (glm::dot(wo_up, m) <= 0.f) return std::nullopt;  // Beckmann's D cos sampling only
        wi_up = reflect(wo_up, m);
        s.lobe = kReflection | kGlossy;
        s.roughness = mf.alpha;
    }
    if (wi_up.z <= 0.f) return std::nullopt;
    return wi_up;
}

}  // namespace gdr::detail
