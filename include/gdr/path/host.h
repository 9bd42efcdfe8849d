// The host interface: what gdr's path-space core (the walk, the vertex
// records, the shift steps and their Jacobians, the gradient MIS, the PT and
// G-PT estimators and the shift validator) asks of the renderer it runs in.
// A renderer with its own geometry, materials, lights and camera models
// PathHost with about ten operations and then runs gdr's shift mappings on
// its own scenes; gdr's own Scene is one model (gdr/scene/scene.h). Every
// value is in gdr's conventions: directions are unit vectors, BSDF
// directions are local to the hit's shading frame (z = shading normal) and
// point away from the surface (wo towards the camera side, wi towards the
// light side), f never includes the cosine, densities name their measure.
// docs/host.md walks through a complete host.
#pragma once

#include <concepts>
#include <cstdint>
#include <optional>

#include "gdr/core/math.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/camera.h"
#include "gdr/scene/light_sample.h"

namespace gdr {

/// A surface hit as the core reads it: the host's own record type with at
/// least these members (it may hold anything else, e.g. its material):
/// p, the point (scene units); ng, the unit geometric normal (its front is
/// the emitting side); frame, the shading frame (frame.n on ng's side); t,
/// the ray parameter of the hit; prim, an identifier of the primitive hit
/// (the validator checks that a perturbed ray hits the same one).
template <class I>
concept HitRecord = std::default_initializable<I> && std::copyable<I> && requires(I& i) {
    { i.p } -> std::convertible_to<Vec3>;
    { i.ng } -> std::convertible_to<Vec3>;
    { i.frame } -> std::convertible_to<Frame>;
    { i.t } -> std::convertible_to<float>;
    { i.prim } -> std::convertible_to<uint32_t>;
};

/// What a host says of the material at a hit, as fields (the shifts classify
/// every vertex they visit, so these are read often): black, it scatters
/// nothing (a walk ends there); pure_delta, every lobe is a Dirac delta;
/// min_roughness, the smallest roughness of its lobes (0 with a delta lobe,
/// a GGX alpha for glossy lobes, 1 for diffuse), which decides where shifts
/// reconnect; wo_side_only, its values depend on wo only through the side it
/// is on (true for every reflective BSDF that is not view dependent beyond
/// that; false is always safe).
template <class T>
concept SurfaceTraits = requires(const T& m) {
    { m.black } -> std::convertible_to<bool>;
    { m.pure_delta } -> std::convertible_to<bool>;
    { m.min_roughness } -> std::convertible_to<float>;
    { m.wo_side_only } -> std::convertible_to<bool>;
};

/// The camera as the core reads it: generate_ray(film) is the primary ray
/// through film point `film` (pixel units, (0,0) the top-left corner of the
/// top-left pixel; unit direction); direction_pdf(w) is the density of a
/// primary ray along unit world direction w with film points uniform over
/// the whole film, 1 / (A cos^3 theta) for a pinhole whose film has area A
/// at unit distance (1/sr, 0 outside the film; bidirectional MIS reads it
/// as the camera vertex's density); forward() the unit viewing direction
/// (the camera vertex's normal); width() and height() the film's resolution
/// in pixels.
template <class C>
concept CameraModel = requires(const C& c, const Vec2& film, const Vec3& w) {
    { c.generate_ray(film) } -> std::same_as<Ray>;
    { c.direction_pdf(w) } -> std::convertible_to<float>;
    { c.forward() } -> std::convertible_to<Vec3>;
    { c.width() } -> std::convertible_to<int>;
    { c.height() } -> std::convertible_to<int>;
};

/// A renderer that gdr's path-space core runs on. `Interaction` is its hit
/// record (HitRecord). The operations, all const and safe to call from
/// several threads at once:
/// - intersect(ray, hit): the closest hit along `ray` within [tmin, tmax],
///   written into `hit`; false on a miss (then `hit` may hold anything).
/// - visible(p0, n0, p1, n1): the open segment between two surface points
///   is unblocked; n0, n1 are their geometric normals for offsetting the
///   ends off the surfaces (a zero normal: a point that is not on a surface).
/// - has_lights(): there is something sample_light() can sample.
/// - sample_light(ref, u_select, u): a point on an emitter for reference
///   point `ref`, chosen with numbers in [0,1): LightSample's p, n, prim,
///   radiance (towards ref, W/(m^2 sr), 0 from the back) and pdf_a, the
///   area density including the emitter's selection (1/m^2).
/// - light_pdf_a(hit): the pdf_a with which sample_light() produces the
///   emitter point `hit`, reached by a ray (1/m^2; the MIS weight of hitting
///   an emitter by BSDF sampling reads it).
/// - light_radiance(sample, w): radiance (W/(m^2 sr)) that the sampled
///   emitter point sends along unit world direction w, which the core only
///   asks on its front side (an offset path sees the base's light point
///   from another point).
/// - is_emitter(hit), emitted(hit, w): whether the surface emits, and the
///   radiance it sends along unit world direction w (0 from the back).
/// - sample_bsdf(hit, wo, u_lobe, u): a direction wi with f (1/sr, no
///   cosine; for a delta lobe the weight such that f |cos wi| / pdf is the
///   throughput), pdf (1/sr including the lobe choice; for a delta lobe the
///   discrete lobe probability), lobe flags, the lobe's roughness and the
///   relative eta crossed; nullopt if none. u_lobe picks the lobe, u the
///   direction: shifts replay them, so the same numbers must give the same
///   direction.
/// - eval_bsdf(hit, wo, wi): f and the density sample_bsdf gives wi
///   (1/sr each), over the non-delta lobes only.
/// - pdf_bsdf(hit, wo, wi): that density alone (1/sr).
/// - eval_delta(hit, wo, wi): for a wi exactly along a delta lobe of wo,
///   that lobe's f and discrete probability as sample_bsdf returns them;
///   nullopt if there is no such lobe (the half-vector shift maps delta
///   lobes onto delta lobes with it).
/// - bsdf_flags(hit): the union of the LobeFlags of the material's lobes.
/// - surface(hit): the material's SurfaceTraits.
/// - camera(): the CameraModel.
/// - bounding_radius(): radius of a sphere holding the scene (scene units),
///   the scale of the validator's tolerances.
/// Orientation is the host's own and must not be flipped towards the ray:
/// ng's front is the emitting side, and a dielectric's outside is on
/// frame.n's side. A light sample leaves infinite, delta and delta_light at
/// their defaults (those are gdr's environment and delta lights); prim is
/// the host's link back to its emitter. eval_delta() must accept a wi within
/// about 1e-3 (unit-vector distance) of the exact delta direction, since the
/// shifts compute it in their own arithmetic.
/// Optional operations the core uses when a host has them: environment()
/// (an environment light behind every miss), prefetch_light(),
/// transport_factor() (light subpaths through refraction), packet
/// traversal (intersect4/intersect8/visible8); gdr's Scene has them all.
template <class H>
concept PathHost = HitRecord<typename H::Interaction> &&
    requires(const H& h, const typename H::Interaction& hit, typename H::Interaction& out, const Ray& ray,
             const Vec3& p, const Vec3& w, const Vec2& u, float u1, const LightSample& ls) {
        { h.intersect(ray, out) } -> std::same_as<bool>;
        { h.visible(p, p, p, p) } -> std::same_as<bool>;
        { h.has_lights() } -> std::same_as<bool>;
        { h.sample_light(p, u1, u) } -> std::same_as<LightSample>;
        { h.light_pdf_a(hit) } -> std::convertible_to<float>;
        { h.light_radiance(ls, w) } -> std::same_as<Color>;
        { h.is_emitter(hit) } -> std::same_as<bool>;
        { h.emitted(hit, w) } -> std::same_as<Color>;
        { h.sample_bsdf(hit, w, u1, u) } -> std::same_as<std::optional<BsdfSample>>;
        { h.eval_bsdf(hit, w, w) } -> std::same_as<BsdfEval>;
        { h.pdf_bsdf(hit, w, w) } -> std::convertible_to<float>;
        { h.eval_delta(hit, w, w) } -> std::same_as<std::optional<BsdfSample>>;
        { h.bsdf_flags(hit) } -> std::convertible_to<uint32_t>;
        { h.surface(hit) } -> SurfaceTraits;
        { h.camera() } -> CameraModel;
        { h.bounding_radius() } -> std::convertible_to<float>;
    };

/// A host with an environment light (gdr's Scene): rays that leave the scene
/// end on it, and sample_light() may return its directions.
template <class H>
concept EnvironmentHost = PathHost<H> && requires(const H& h, const Vec3& p, const Vec3& w) {
    { h.environment() };
    { h.beyond_scene(p, w) } -> std::same_as<Vec3>;
    { h.environment_pdf(w) } -> std::convertible_to<float>;
};

/// A host that can start loading an emitter's data before a light sample
/// needs it (gdr's Scene on scenes with many emitters).
template <class H>
concept PrefetchingHost = requires(const H& h, float u) {
    { h.light_prefetch_pays() } -> std::same_as<bool>;
    h.prefetch_light(u);
};

/// A host with delta lights (point, spot, directional; gdr's Scene): light
/// samples may be delta ones, and picks_delta(u) says whether the light
/// numbers u pick one; delta_light_pdf(light) is its selection probability.
template <class H>
concept DeltaLightHost = requires(const H& h, float u, const DeltaLight& l) {
    { h.picks_delta(u) } -> std::same_as<bool>;
    { h.delta_light_pdf(l) } -> std::convertible_to<float>;
};

/// The host's BSDF value alone (1/sr, no cosine, non-delta lobes): its
/// bsdf_f() where it has one (a value without the density may be cheaper),
/// else eval_bsdf()'s f.
template <PathHost H>
Color host_bsdf_f(const H& h, const typename H::Interaction& hit, const Vec3& wo, const Vec3& wi) {
    if constexpr (requires { { h.bsdf_f(hit, wo, wi) } -> std::same_as<Color>; })
        return h.bsdf_f(hit, wo, wi);
    else
        return h.eval_bsdf(hit, wo, wi).f;
}

/// The factor turning the host's BSDF value (radiance transport) into the
/// value for `mode`: only light subpaths (TransportMode::Importance) through
/// refraction differ. A host without transport_factor() is taken to have
/// none (its camera walks are exact; it offers no light tracing).
template <PathHost H>
float host_transport_factor(const H& h, const typename H::Interaction& hit, const Vec3& wo, const Vec3& wi,
                            TransportMode mode) {
    if constexpr (requires { { h.transport_factor(hit, wo, wi, mode) } -> std::convertible_to<float>; })
        return h.transport_factor(hit, wo, wi, mode);
    else
        return (void)hit, (void)wo, (void)wi, (void)mode, 1.f;
}

/// Offset of a ray origin along the geometric normal that escapes the surface's
/// own float rounding (relative to the point's magnitude), scene units.
inline Vec3 offset_ray_origin(const Vec3& p, const Vec3& ng, const Vec3& dir) {
    const float scale = 1e-4f * std::max(1.f, std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z))));
    return p + (glm::dot(ng, dir) >= 0.f ? scale : -scale) * ng;
}

/// A ray leaving hit record `hit` along unit world direction `dir`.
template <HitRecord I>
Ray spawn_ray(const I& hit, const Vec3& dir) {
    return Ray{offset_ray_origin(hit.p, hit.ng, dir), dir, 0.f, kInf};
}

}  // namespace gdr
