// A small renderer that is not gdr's: analytic spheres and parallelograms
// intersected by a linear loop, four materials of its own, parallelogram
// area lights and a pinhole camera. It models gdr::PathHost
// (gdr/path/host.h), so gdr's path-space core can run on its scenes; it
// uses only gdr's header-only vocabulary types (vectors, frames, rays,
// BsdfSample, LightSample). Header-only.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "gdr/path/host.h"

namespace toy {

using gdr::BsdfEval, gdr::BsdfSample, gdr::Color, gdr::Frame, gdr::LightSample, gdr::Ray, gdr::Vec2, gdr::Vec3;
using gdr::kPi;

/// The scattering models of the toy renderer.
enum class Kind { Diffuse, Mirror, Glass, Glossy };

/// A material: `albedo` is the Lambertian reflectance, the mirror's reflectance or the glossy
/// lobe's normal-incidence Fresnel reflectance (Schlick's f0), unitless; `alpha` the glossy
/// lobe's GGX roughness; `eta` the glass's index (inside / outside, the outside is the normal's
/// side); `emission` the radiance its front side emits (W/(m^2 sr)).
struct Material {
    Kind kind = Kind::Diffuse;
    Color albedo{0.8f};
    float alpha = 0.3f, eta = 1.5f;
    Color emission{0.f};
};

/// gdr::SurfaceTraits of a material (see gdr/path/host.h for the fields' meaning).
struct Traits {
    bool black = false, pure_delta = false;
    float min_roughness = 1.f;
    bool wo_side_only = false;
};

/// A sphere (centre c, radius r; normals point outwards) or a parallelogram (corner c, edges
/// e1, e2; normal along e1 x e2, its front), scene units.
struct Primitive {
    bool sphere = false;
    Vec3 c{0.f}, e1{0.f}, e2{0.f}, n{0.f};
    float r = 0.f, area = 0.f;
    int material = 0;
};

/// The toy renderer's hit record: the gdr::HitRecord members plus its material and uv.
struct Hit {
    Vec3 p{0.f}, ng{0.f, 0.f, 1.f};  ///< Point (scene units), unit geometric normal (outwards / front).
    Frame frame;                     ///< Shading frame, frame.n = ng (no shading normals here).
    float t = 0.f;                   ///< Ray parameter of the hit (scene units for unit directions).
    uint32_t prim = 0;               ///< Index of the primitive hit.
    int material = 0;                ///< Index of its material.
    Vec2 uv{0.f};                    ///< Parallelogram coordinates along e1, e2 in [0,1]; 0 on spheres.
};

/// Pinhole camera with gdr's look-at and film conventions (gdr::CameraModel).
class PinholeCamera {
public:
    PinholeCamera() = default;
    /// Eye, point looked at, approximate up, vertical field of view (degrees), resolution (pixels).
    PinholeCamera(Vec3 eye, Vec3 target, Vec3 up, float fov_y_deg, int w, int h) : eye_(eye), w_(w), h_(h) {
        if (w <= 0 || h <= 0) throw std::invalid_argument("toy camera: resolution must be positive");
        if (!(fov_y_deg > 0.f && fov_y_deg < 180.f)) throw std::invalid_argument("toy camera: fov must be in (0, 180)");
        if (!(glm::length(glm::cross(target - eye, up)) > 0.f))
            throw std::invalid_argument("toy camera: eye and target coincide, or up is along the view");
        fwd_ = glm::normalize(target - eye);
        right_ = glm::normalize(glm::cross(fwd_, up));
        up_ = glm::cross(right_, fwd_);
        ty_ = std::tan(0.5f * fov_y_deg * kPi / 180.f);
        tx_ = ty_ * float(w) / float(h);
    }
    /// Primary ray through film point `film` (pixels, (0,0) the top-left corner, y down).
    Ray generate_ray(const Vec2& film) const {
        const float sx = 2.f * film.x / float(w_) - 1.f, sy = 1.f - 2.f * film.y / float(h_);
        return Ray{eye_, glm::normalize(fwd_ + sx * tx_ * right_ + sy * ty_ * up_), 0.f, gdr::kInf};
    }
    /// Density (1/sr) of the primary ray direction w with the film point uniform over the whole
    /// film, as gdr::Camera::direction_pdf: 1 / (A cos^3), A the film's area at distance 1.
    float direction_pdf(const Vec3& w) const {
        const float c = glm::dot(w, fwd_);
        if (!(c > 0.f) || std::abs(glm::dot(w, right_)) > c * tx_ || std::abs(glm::dot(w, up_)) > c * ty_) return 0.f;
        return 1.f / (4.f * tx_ * ty_ * c * c * c);
    }
    const Vec3& forward() const { return fwd_; }  ///< Unit viewing direction.
    int width() const { return w_; }    ///< Pixels across.
    int height() const { return h_; }   ///< Pixels down.

private:
    Vec3 eye_{0.f}, fwd_{0.f, 0.f, -1.f}, right_{1.f, 0.f, 0.f}, up_{0.f, 1.f, 0.f};
    float tx_ = 1.f, ty_ = 1.f;
    int w_ = 1, h_ = 1;
};

/// Exact unpolarised Fresnel reflectance for |cos_i| on the incident side and relative index
/// eta (transmitted / incident); sets cos_t, |cos| of the refracted direction (1 and 0 on total
/// internal reflection).
inline float fresnel_dielectric(float cos_i, float eta, float& cos_t) {
    const float sin2_t = (1.f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.f) return cos_t = 0.f, 1.f;
    cos_t = std::sqrt(1.f - sin2_t);
    const float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t), rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

/// GGX (Trowbridge-Reitz) normal distribution D(m) of roughness a (1/sr), Walter et al.,
/// "Microfacet models for refraction through rough surfaces", 2007, eq. 33.
inline float ggx_d(const Vec3& m, float a) {
    if (m.z <= 0.f) return 0.f;
    const float k = m.z * m.z * (a * a - 1.f) + 1.f;
    return a * a / (kPi * k * k);
}

/// Smith's masking of GGX for local direction w (Walter et al. 2007, eq. 34, as 1/(1+Lambda)).
inline float ggx_lambda(const Vec3& w, float a) {
    const float c2 = w.z * w.z;
    return c2 <= 0.f ? 1e30f : 0.5f * (std::sqrt(1.f + a * a * (1.f - c2) / c2) - 1.f);
}

/// The toy renderer: a handful of primitives, their materials and a camera; models gdr::PathHost.
class Renderer {
public:
    using Interaction = Hit;  ///< The hit record gdr's core reads.

    /// Adds a material and returns its index.
    int add(const Material& m) { return materials_.push_back(m), int(materials_.size()) - 1; }
    /// Adds a sphere (centre, radius in scene units, material index).
    void sphere(Vec3 c, float r, int mat) {
        if (!(r > 0.f)) throw std::invalid_argument("toy renderer: sphere radius must be positive");
        prims_.push_back({true, c, {}, {}, {}, r, 4.f * kPi * r * r, mat});
    }
    /// Adds a parallelogram corner + [0,1]^2 of edges (e1, e2), front along e1 x e2; an emitting
    /// material makes it an area light.
    void quad(Vec3 c, Vec3 e1, Vec3 e2, int mat) {
        const Vec3 x = glm::cross(e1, e2);
        if (!(glm::length(x) > 0.f)) throw std::invalid_argument("toy renderer: parallelogram edges are parallel");
        prims_.push_back({false, c, e1, e2, glm::normalize(x), 0.f, glm::length(x), mat});
    }
    /// Sets the camera and collects the lights and bounds; call after the last primitive (the
    /// queries below read what it collects). Throws on an emitting sphere.
    void finish(const PinholeCamera& cam) {
        camera_ = cam, lights_.clear(), light_cdf_.clear(), light_area_ = 0.f;
        Vec3 lo(gdr::kInf), hi(-gdr::kInf);
        for (uint32_t i = 0; i < prims_.size(); ++i) {
            const Primitive& q = prims_[i];
            if (q.sphere) lo = glm::min(lo, q.c - q.r), hi = glm::max(hi, q.c + q.r);
            else for (Vec3 v : {q.c, q.c + q.e1, q.c + q.e2, q.c + q.e1 + q.e2}) lo = glm::min(lo, v), hi = glm::max(hi, v);
            if (q.material < 0 || size_t(q.material) >= materials_.size())
                throw std::invalid_argument("toy renderer: primitive " + std::to_string(i) + " names no material");
            if (gdr::max_component(materials_[q.material].emission) <= 0.f) continue;
            if (q.sphere) throw std::invalid_argument("toy renderer: emitting sphere (only parallelograms emit)");
            lights_.push_back(i), light_area_ += q.area, light_cdf_.push_back(light_area_);
        }
        radius_ = 0.5f * glm::length(hi - lo);
    }

    // ---- gdr::PathHost ----
    /// Closest hit along `ray` in [tmin, tmax].
    bool intersect(const Ray& ray, Hit& hit) const {
        float tmax = ray.tmax;
        int best = -1;
        Vec2 uv(0.f);
        for (uint32_t i = 0; i < prims_.size(); ++i)
            if (float t; hit_prim(prims_[i], ray, tmax, t, uv)) tmax = t, best = int(i), hit.uv = uv;
        if (best < 0) return false;
        const Primitive& q = prims_[best];
        hit.t = tmax, hit.p = ray.o + tmax * ray.d, hit.prim = uint32_t(best), hit.material = q.material;
        hit.ng = q.sphere ? glm::normalize(hit.p - q.c) : q.n;
        hit.frame = Frame(hit.ng);
        return true;
    }
    /// The open segment between two surface points (normals n0, n1 offset its ends) is unblocked.
    bool visible(const Vec3& p0, const Vec3& n0, const Vec3& p1, const Vec3& n1) const {
        const Vec3 a = gdr::offset_ray_origin(p0, n0, p1 - p0), b = gdr::offset_ray_origin(p1, n1, p0 - p1);
        const float len = glm::length(b - a);
        if (!(len > 0.f)) return true;
        const Ray ray{a, (b - a) / len, 0.f, len};
        Vec2 uv;
        for (const Primitive& q : prims_)
            if (float t; hit_prim(q, ray, ray.tmax, t, uv)) return false;
        return true;
    }
    bool has_lights() const { return !lights_.empty(); }  ///< There is an area light.
    /// A point uniform over the lights' total area (light chosen with probability area / total).
    LightSample sample_light(const Vec3& ref, float u_select, const Vec2& u) const {
        LightSample ls;
        if (lights_.empty()) return ls;
        const size_t k = std::min(size_t(std::upper_bound(light_cdf_.begin(), light_cdf_.end(), u_select * light_area_) -
                                         light_cdf_.begin()), lights_.size() - 1);
        const Primitive& q = prims_[lights_[k]];
        ls.p = q.c + u.x * q.e1 + u.y * q.e2, ls.n = q.n, ls.prim = lights_[k], ls.pdf_a = 1.f / light_area_;
        ls.radiance = light_radiance(ls, glm::normalize(ref - ls.p));
        return ls;
    }
    /// Area density (1/m^2) with which sample_light() produces the point `hit`.
    float light_pdf_a(const Hit& hit) const { return is_emitter(hit) ? 1.f / light_area_ : 0.f; }
    /// Radiance the sampled light point sends along w (W/(m^2 sr); 0 from its back).
    Color light_radiance(const LightSample& ls, const Vec3& w) const {
        return glm::dot(ls.n, w) > 0.f ? materials_[prims_[ls.prim].material].emission : Color(0.f);
    }
    /// True if the surface at `hit` emits.
    bool is_emitter(const Hit& hit) const { return gdr::max_component(materials_[hit.material].emission) > 0.f; }
    /// Radiance the surface at `hit` emits along w (W/(m^2 sr); 0 from its back).
    Color emitted(const Hit& hit, const Vec3& w) const {
        return glm::dot(hit.ng, w) > 0.f ? materials_[hit.material].emission : Color(0.f);
    }
    /// Samples wi (local) for wo (local) with lobe number u_lobe and direction numbers u.
    std::optional<BsdfSample> sample_bsdf(const Hit& hit, const Vec3& wo, float u_lobe, const Vec2& u) const {
        const Material& m = materials_[hit.material];
        if (wo.z == 0.f || surface(hit).black) return std::nullopt;
        const float side = wo.z > 0.f ? 1.f : -1.f;  // reflective models are two-sided: mirrored below
        BsdfSample s;
        s.lobe = gdr::kReflection;
        if (m.kind == Kind::Diffuse) {  // cosine-weighted hemisphere
            const float r = std::sqrt(u.x), phi = 2.f * kPi * u.y;
            s.wi = Vec3(r * std::cos(phi), r * std::sin(phi), side * std::sqrt(std::max(0.f, 1.f - u.x)));
            s.lobe |= gdr::kDiffuse, s.roughness = 1.f;
        } else if (m.kind == Kind::Glossy) {  // D(m) cos(m) sampling of the half vector (Walter 2007, eq. 35)
            const float tan2 = m.alpha * m.alpha * u.x / (1.f - u.x), phi = 2.f * kPi * u.y;
            const float cz = 1.f / std::sqrt(1.f + tan2), sz = std::sqrt(std::max(0.f, 1.f - cz * cz));
            const Vec3 h(sz * std::cos(phi), sz * std::sin(phi), side * cz);
            s.wi = gdr::reflect(wo, h);
            s.lobe |= gdr::kGlossy, s.roughness = m.alpha;
        } else {
            return delta(m, wo, u_lobe < fresnel(m, wo) ? 0 : 1);
        }
        const BsdfEval e = eval_bsdf(hit, wo, s.wi);
        if (!(e.pdf > 0.f)) return std::nullopt;
        return s.f = e.f, s.pdf = e.pdf, s;
    }
    /// f and sampling density (1/sr each) of the non-delta lobes for local wo, wi.
    BsdfEval eval_bsdf(const Hit& hit, Vec3 wo, Vec3 wi) const {
        const Material& m = materials_[hit.material];
        if (!gdr::same_hemisphere(wo, wi) || m.kind == Kind::Mirror || m.kind == Kind::Glass) return {};
        if (wo.z < 0.f) wo.z = -wo.z, wi.z = -wi.z;
        if (m.kind == Kind::Diffuse) return {m.albedo / kPi, wi.z / kPi};
        const Vec3 h = glm::normalize(wo + wi);
        const float d = ggx_d(h, m.alpha), c = glm::dot(wo, h);
        const float g = 1.f / (1.f + ggx_lambda(wo, m.alpha) + ggx_lambda(wi, m.alpha));
        const Color f = m.albedo + (Color(1.f) - m.albedo) * std::pow(1.f - c, 5.f);  // Schlick
        return {f * d * g / (4.f * wo.z * wi.z), d * h.z / (4.f * c)};
    }
    /// The sampling density alone (1/sr).
    float pdf_bsdf(const Hit& hit, const Vec3& wo, const Vec3& wi) const { return eval_bsdf(hit, wo, wi).pdf; }
    /// For wi along a delta lobe of wo: that lobe's f and probability as sample_bsdf gives them.
    std::optional<BsdfSample> eval_delta(const Hit& hit, const Vec3& wo, const Vec3& wi) const {
        const Material& m = materials_[hit.material];
        if (wo.z == 0.f || (m.kind != Kind::Mirror && m.kind != Kind::Glass)) return std::nullopt;
        auto s = delta(m, wo, gdr::same_hemisphere(wo, wi) ? 0 : 1);
        // Tolerance of unit-vector distance for a direction that went through frames and offsets.
        if (!s || glm::length(s->wi - wi) > 1e-3f) return std::nullopt;
        return s;
    }
    /// LobeFlags of the material at `hit`.
    uint32_t bsdf_flags(const Hit& hit) const {
        switch (materials_[hit.material].kind) {
            case Kind::Diffuse: return gdr::kReflection | gdr::kDiffuse;
            case Kind::Glossy: return gdr::kReflection | gdr::kGlossy;
            case Kind::Mirror: return gdr::kReflection | gdr::kSpecular;
            default: return gdr::kReflection | gdr::kTransmission | gdr::kSpecular;
        }
    }
    /// The material's traits; only Lambertian reflection depends on wo through its side alone, and
    /// only Lambertian and mirror reflection of albedo 0 are black (Schlick's glossy Fresnel is not).
    Traits surface(const Hit& hit) const {
        const Material& m = materials_[hit.material];
        const bool delta = m.kind == Kind::Mirror || m.kind == Kind::Glass;
        const bool scaled = m.kind == Kind::Diffuse || m.kind == Kind::Mirror;  // f proportional to albedo
        return {scaled && gdr::max_component(m.albedo) <= 0.f, delta,
                delta ? 0.f : m.kind == Kind::Glossy ? m.alpha : 1.f, m.kind == Kind::Diffuse};
    }
    const PinholeCamera& camera() const { return camera_; }  ///< The camera.
    float bounding_radius() const { return radius_; }        ///< Half the diagonal of the bounds (scene units).


private:
    // Ray-primitive test within (ray.tmin, tmax): t of the hit and the parallelogram's uv.
    static bool hit_prim(const Primitive& q, const Ray& ray, float tmax, float& t, Vec2& uv) {
        if (q.sphere) {  // |o + t d - c|^2 = r^2 with |d| = 1
            uv = Vec2(0.f);
            const Vec3 oc = ray.o - q.c;
            const float b = glm::dot(oc, ray.d), disc = b * b - (glm::dot(oc, oc) - q.r * q.r);
            if (disc < 0.f) return false;
            const float s = std::sqrt(disc);
            t = -b - s > ray.tmin ? -b - s : -b + s;
            return t > ray.tmin && t < tmax;
        }
        const float dn = glm::dot(ray.d, q.n);
        if (dn == 0.f) return false;
        t = glm::dot(q.c - ray.o, q.n) / dn;
        if (!(t > ray.tmin && t < tmax)) return false;
        const Vec3 x = ray.o + t * ray.d - q.c, w = glm::cross(q.e1, q.e2);
        const float inv = 1.f / glm::dot(w, w);
        uv = Vec2(glm::dot(w, glm::cross(x, q.e2)) * inv, glm::dot(w, glm::cross(q.e1, x)) * inv);
        return uv.x >= 0.f && uv.x <= 1.f && uv.y >= 0.f && uv.y <= 1.f;
    }
    // Fresnel reflectance of the glass for wo (1 for the mirror: reflection is its only lobe).
    static float fresnel(const Material& m, const Vec3& wo) {
        float cos_t;
        return m.kind == Kind::Mirror ? 1.f : fresnel_dielectric(std::abs(wo.z), wo.z > 0.f ? m.eta : 1.f / m.eta, cos_t);
    }
    // Delta lobe `lobe` (0 reflection, 1 refraction) of a mirror or glass for wo: its f, such
    // that f |cos| / pdf is the throughput (refraction compresses radiance by 1/eta^2), and pdf,
    // its probability; nullopt if it has none (refraction under total internal reflection).
    static std::optional<BsdfSample> delta(const Material& m, const Vec3& wo, int lobe) {
        BsdfSample s;
        float cos_t = 0.f, eta = wo.z > 0.f ? m.eta : 1.f / m.eta;
        const float F = m.kind == Kind::Mirror ? 1.f : fresnel_dielectric(std::abs(wo.z), eta, cos_t);
        s.roughness = 0.f;
        if (lobe == 0) {
            s.wi = Vec3(-wo.x, -wo.y, wo.z), s.pdf = F, s.lobe = gdr::kReflection | gdr::kSpecular;
            s.f = (m.kind == Kind::Mirror ? m.albedo : Color(1.f)) * F / std::abs(wo.z);
            return F > 0.f ? std::optional(s) : std::nullopt;
        }
        if (m.kind == Kind::Mirror || F >= 1.f) return std::nullopt;
        s.wi = Vec3(-wo.x / eta, -wo.y / eta, wo.z > 0.f ? -cos_t : cos_t), s.pdf = 1.f - F, s.eta = eta;
        s.f = Color((1.f - F) / (eta * eta * cos_t)), s.lobe = gdr::kTransmission | gdr::kSpecular;
        return s;
    }

    std::vector<Material> materials_;
    std::vector<Primitive> prims_;
    std::vector<uint32_t> lights_;    // emitting parallelograms
    std::vector<float> light_cdf_;    // running sum of their areas (m^2)
    float light_area_ = 0.f, radius_ = 0.f;
    PinholeCamera camera_;
};

static_assert(gdr::PathHost<Renderer>, "the toy renderer must model gdr's host interface");

/// A Cornell-style box [-1,1]^3 (open towards the camera at z = +1): white floor, ceiling and back
/// wall, red left and green right wall, a ceiling light, and glass, mirror and rough glossy spheres.
inline Renderer cornell_scene(int width = 64, int height = 64) {
    Renderer r;
    const int white = r.add({Kind::Diffuse, Color(0.75f)}), red = r.add({Kind::Diffuse, Color(0.7f, 0.1f, 0.1f)});
    const int green = r.add({Kind::Diffuse, Color(0.1f, 0.6f, 0.15f)});
    const int light = r.add({Kind::Diffuse, Color(0.f), 1.f, 1.f, Color(12.f, 11.f, 9.f)});
    const int glass = r.add({Kind::Glass, Color(1.f), 0.f, 1.5f});
    const int mirror = r.add({Kind::Mirror, Color(0.95f)});
    const int glossy = r.add({Kind::Glossy, Color(0.9f, 0.6f, 0.3f), 0.2f});
    r.quad({-1, -1, -1}, {0, 0, 2}, {2, 0, 0}, white);   // floor, front +y
    r.quad({-1, 1, -1}, {2, 0, 0}, {0, 0, 2}, white);    // ceiling, front -y
    r.quad({-1, -1, -1}, {2, 0, 0}, {0, 2, 0}, white);   // back wall, front +z
    r.quad({-1, -1, -1}, {0, 2, 0}, {0, 0, 2}, red);     // left wall, front +x
    r.quad({1, -1, -1}, {0, 0, 2}, {0, 2, 0}, green);    // right wall, front -x
    r.quad({-0.3f, 0.999f, -0.3f}, {0.6f, 0, 0}, {0, 0, 0.6f}, light);  // ceiling light, front -y
    r.sphere({-0.5f, -0.65f, -0.3f}, 0.35f, glass);
    r.sphere({0.45f, -0.65f, -0.45f}, 0.35f, mirror);
    r.sphere({0.1f, -0.75f, 0.4f}, 0.25f, glossy);
    r.finish(PinholeCamera({0, 0, 3.4f}, {0, 0, 0}, {0, 1, 0}, 40.f, width, height));
    return r;
}

}  // namespace toy
