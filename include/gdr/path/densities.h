// The area densities of subpath vertices and the scattering values a
// connection reads (declared in gdr/path/subpath.h), templated on the host
// (gdr/path/host.h); gdr's Scene's are compiled once, in the library.
#pragma once

#include <type_traits>

#include <algorithm>

#include "gdr/path/environment.h"
#include "gdr/path/subpath.h"
#include "gdr/path/walk.h"

namespace gdr {

template <PathHost H>
double pdf_area(const H& scene, std::type_identity_t<const BasicVertex<H>*> prev, const BasicVertex<H>& cur, const BasicVertex<H>& next) {
    if (cur.infinite) return area_density(environment_disk_pdf(scene), cur, next);
    if (next.infinite || (prev && prev->infinite)) {
        // Directions to vertices at infinity are theirs, not their far points'.
        if (cur.type != VertexType::Surface || !prev) return 0.0;
        const auto& si = cur.si;
        const double pdf_w = scene.pdf_bsdf(si, si.frame.to_local(vertex_direction(cur, *prev)),
                                            si.frame.to_local(vertex_direction(cur, next)));
        return area_density(pdf_w, cur, next);
    }
    const Vec3 d = next.si.p - cur.si.p;
    const float len = glm::length(d);
    if (!(len > 0.f)) return 0.0;
    const Vec3 w = d / len;
    double pdf_w = 0.0;
    switch (cur.type) {
        case VertexType::Camera: pdf_w = scene.camera().direction_pdf(w); break;
        case VertexType::Light:
            pdf_w = cur.delta_light ? cur.delta_light->emission_pdf_w(w) : std::max(0.f, glm::dot(cur.si.ng, w)) * kInvPi;
            break;
        case VertexType::Surface: {
            if (!prev) return 0.0;
            const Vec3 to_prev = glm::normalize(prev->si.p - cur.si.p);
            const auto& si = cur.si;
            pdf_w = scene.pdf_bsdf(si, si.frame.to_local(to_prev), si.frame.to_local(w));
            break;
        }
    }
    return area_density(pdf_w, cur, next);
}

template <PathHost H>
double pdf_light_origin(const H& scene, const BasicVertex<H>& v) {
    if constexpr (DeltaLightHost<H>)
        if (v.delta_light) return scene.delta_light_pdf(*v.delta_light);
    if constexpr (EnvironmentHost<H>)
        if (v.infinite) return scene.environment_pdf(-v.si.ng);
    if (v.type == VertexType::Light) return v.pdf_fwd;
    if (v.type != VertexType::Surface || !scene.is_emitter(v.si)) return 0.0;
    return scene.light_pdf_a(v.si);
}

template <PathHost H>
double pdf_light_direction(const H& scene, const BasicVertex<H>& v, const BasicVertex<H>& next) {
    return v.infinite ? area_density(environment_disk_pdf(scene), v, next) : pdf_light_direction(v, next);
}

template <class H>
double pdf_light_direction(const BasicVertex<H>& v, const BasicVertex<H>& next) {
    if (v.infinite) return 0.0;  // needs the scene's disk: the overload above
    const Vec3 d = next.si.p - v.si.p;
    const float len = glm::length(d);
    if (!(len > 0.f)) return 0.0;
    if (v.delta_light) return area_density(v.delta_light->emission_pdf_w(d / len), v, next);
    return area_density(std::max(0.f, glm::dot(v.si.ng, d / len)) * kInvPi, v, next);
}

template <PathHost H>
Color vertex_f(const H& scene, const BasicVertex<H>& v, const Vec3& w, TransportMode mode) {
    if (v.type != VertexType::Surface) return Color(0.f);
    const auto& si = v.si;
    const Vec3 wo = si.frame.to_local(v.wo), wi = si.frame.to_local(w);
    return host_bsdf_f(scene, si, wo, wi) *
           (host_transport_factor(scene, si, wo, wi, mode) * shading_correction(si, v.wo, w, mode));
}

template <class H>
float abs_cos_shading(const BasicVertex<H>& v, const Vec3& w) {
    return v.type == VertexType::Camera ? 1.f : std::abs(glm::dot(v.si.frame.n, w));
}

}  // namespace gdr
