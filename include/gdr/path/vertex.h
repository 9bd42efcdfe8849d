// Path-space building blocks: the measure conversions between solid angle
// and area, roulette, and the record of a light sample that shift mappings share.
#pragma once

#include <vector>

#include "gdr/core/math.h"
#include "gdr/scene/scene.h"

namespace gdr {

/// Geometry factor between two points: |cos_a| |cos_b| / distance^2 (1/m^2);
/// cosines are taken against the unit normals n_a and n_b.
inline double geometry_term(const Vec3& a, const Vec3& n_a, const Vec3& b, const Vec3& n_b) {
    const Vec3d d = Vec3d(b) - Vec3d(a);
    const double d2 = glm::dot(d, d);
    if (!(d2 > 0.0)) return 0.0;
    const Vec3d w = d / std::sqrt(d2);
    return std::abs(glm::dot(w, Vec3d(n_a))) * std::abs(glm::dot(w, Vec3d(n_b))) / d2;
}

/// Solid-angle density (1/sr) -> area density (1/m^2) at a point at distance
/// `dist` whose surface makes |cos| `cos_at_point` with the incoming
/// direction; in float (path tracing) or double (shift arithmetic). The one
/// conversion between the two measures.
template <class T>
T pdf_w_to_a(T pdf_w, T dist, T cos_at_point) {
    return dist > T(0) ? pdf_w * std::abs(cos_at_point) / (dist * dist) : T(0);
}

/// Area density (1/m^2) -> solid-angle density (1/sr); the inverse of pdf_w_to_a.
template <class T>
T pdf_a_to_w(T pdf_a, T dist, T cos_at_point) {
    return std::abs(cos_at_point) > T(0) ? pdf_a * dist * dist / std::abs(cos_at_point) : T(0);
}

/// Russian roulette survival probability for a path throughput (unitless).
inline float roulette_survival(const Color& throughput) { return std::min(0.95f, max_component(throughput)); }

/// A next-event (light) sample taken at a path vertex.
struct LightConnection {
    bool valid = false;       ///< A sample was drawn (vertex had a non-delta lobe, scene has lights).
    LightSample light;        ///< The point on the emitter (area measure), or the environment's direction (solid angle); shared by offset paths.
    bool visible = false;     ///< Segment vertex -> light point unblocked; meaningful only if `tested`.
    /// The segment was traced: only where the sample contributes to the base
    /// (radiance and f nonzero), as a path tracer would; an offset that sees
    /// the same light point from the same vertex with other BSDF values
    /// traces it itself when it was not.
    bool tested = false;
    float u_select = 0.f;     ///< Random number that picked the emitter triangle.
    Vec2 u_point{0.f};        ///< Random numbers that picked the point on it.
    // The segment to the light point as seen from the vertex, measured once
    // (measure()) and read by the base's terms and by every offset that
    // shares the vertex.
    float dist = 0.f;         ///< Distance from the vertex to the light point (scene units); 0 if they coincide.
    Vec3 wi{0.f};             ///< Unit direction to the light point in the vertex's shading frame (if dist > 0).
    double pdf_w = 0.0;       ///< Light-sampling density of that direction (1/sr); 0 if dist is 0.
    Color f{0.f};             ///< BSDF value at the vertex for (wo, wi) (1/sr; 0 if dist is 0).
    float pdf_bsdf = 0.f;     ///< BSDF sampling density of wi at the vertex given wo (1/sr; 0 if dist is 0 or the light is a delta light).

    /// Fills dist, wi, pdf_w, f and pdf_bsdf for this sample taken at surface
    /// point `at` of `host` entered from local direction `wo`; call again
    /// whenever `light`, `at` or `wo` changes.
    template <class H>
    void measure(const H& host, const typename H::Interaction& at, const Vec3& wo) {
        const Vec3 d = light.p - at.p;
        dist = glm::length(d);
        if (!(dist > 0.f)) {
            dist = 0.f, wi = Vec3(0.f), pdf_w = 0.0, f = Color(0.f), pdf_bsdf = 0.f;
            return;
        }
        // An environment sample is a direction, the same from every point
        // (its light.p is only a far end for the shadow ray).
        const Vec3 w = light.infinite ? -light.n : d / dist;
        wi = at.frame.to_local(w);
        pdf_w = light.infinite ? double(light.pdf_w)
                               : pdf_a_to_w(double(light.pdf_a), double(dist), double(glm::dot(light.n, w)));
        const BsdfEval fe = host.eval_bsdf(at, wo, wi);
        // No BSDF sample reaches a delta light: light sampling is its only strategy.
        f = fe.f, pdf_bsdf = light.delta ? 0.f : fe.pdf;
    }
};

}  // namespace gdr
