// Subpaths: the path-space core of the bidirectional methods. A camera
// subpath starts at the eye and carries importance's adjoint, radiance; a
// light subpath starts on an emitter and carries importance. Every vertex
// keeps the two area densities with which the walks of both directions would
// produce it (pdf_fwd, pdf_rev), the representation of Veach's "Robust Monte
// Carlo Methods for Light Transport Simulation" (1997, section 10.2) and of
// pbrt-v4's bidirectional integrator: an (s, t) connection then finds every
// other strategy's density by remapping a few of them (connection.h).
// Measures are in the names: pdf_w is per steradian, pdf_a per square metre.
#pragma once

#include <type_traits>

#include <cstdint>
#include <vector>

#include "gdr/core/sampler.h"
#include "gdr/path/vertex.h"
#include "gdr/path/host.h"
#include "gdr/scene/scene.h"

namespace gdr {

/// What a subpath vertex is.
enum class VertexType : uint8_t {
    Camera,   ///< The pinhole (a delta position): si.p is the eye, si.ng the viewing direction.
    Light,    ///< A point on an emitter where a light subpath starts (or an s = 1 connection's sampled light).
    Surface,  ///< A scattering point found by a walk.
};

/// One vertex of a subpath on host H (gdr/path/host.h; Vertex on gdr's Scene).
template <class H>
struct BasicVertex {
    VertexType type = VertexType::Surface;
    typename H::Interaction si;  ///< The point; a light vertex has p, ng, frame and prim (no material); a camera p and ng.
    Vec3 wo{0.f};           ///< Unit world direction towards the previous vertex of its subpath (0 at the start).
    /// Throughput of the subpath up to and including the arrival here: We/pdf
    /// or Le/pdf at the start (a light vertex's Le/pdf_a, in W/(m^2 sr)
    /// times m^2), times f |cos| / pdf_w per scattering, over roulette survival.
    Color beta{0.f};
    Color le{0.f};            ///< A light vertex's emitted radiance (W/(m^2 sr), front side); 0 otherwise.
    double pdf_fwd = 0.0;     ///< Area density (1/m^2) with which its own subpath's walk produced it (0 after a delta lobe).
    double pdf_rev = 0.0;     ///< Area density (1/m^2) with which the other direction's walk would produce it from the next vertex.
    bool delta = false;       ///< The direction sampled here came from a Dirac lobe (so no strategy connects here).
    /// The direction sampled here (local wi, f in 1/sr, solid-angle pdf in
    /// 1/sr, lobe, roughness, eta); pdf 0 if the walk sampled none.
    BsdfSample bs;
    float rr_survival = 1.f;  ///< Russian roulette survival probability applied after this vertex (1 if none).
    float u_light = 0.f;      ///< Random number that picks the emitter of this vertex's s = 1 connection (camera walks).
    float u_lobe = 0.f;       ///< Random number that chose the lobe (for replay).
    Vec2 u_dir{0.f};          ///< Random numbers that chose the direction (for replay).
    /// Random number of probabilistic vertex classification (0.5 unless
    /// draw_classification_numbers() drew it), shared by a base path and its offsets.
    float u_classify = 0.5f;
    /// A light vertex at infinity, on the environment (path/environment.h):
    /// si.ng is the unit direction light travels from it into the scene, si.p
    /// a point far along -si.ng; its "area" densities are solid-angle ones
    /// (1/sr) of that direction, and the first vertex after it on a light
    /// subpath has the density of the emission disk, per m^2 (pbrt-v4's
    /// convention for infinite lights).
    bool infinite = false;
    /// A light vertex on a delta light (delta_light.h; owned by the Scene),
    /// or null. A point or spot light's vertex is its position, its "area"
    /// densities are discrete probabilities (its selection's), and le its
    /// intensity (W/sr) along si.ng; a directional light's is a vertex at
    /// infinity (`infinite`, si.ng the direction light travels) with le its
    /// irradiance (W/m^2) and a discrete selection probability as density.
    /// No walk can hit one: a strategy that would need to is impossible.
    const DeltaLight* delta_light = nullptr;

    /// True if the walk sampled a direction here (bs is valid).
    bool scattered() const { return bs.pdf > 0.f; }
};
/// A vertex of a subpath on gdr's own Scene.
using Vertex = BasicVertex<Scene>;

/// A camera or light subpath on host H: v[0] is its endpoint (camera or light vertex).
template <class H>
struct BasicSubpath {
    TransportMode mode = TransportMode::Radiance;  ///< Radiance for camera subpaths, importance for light subpaths.
    std::vector<BasicVertex<H>> v;  ///< Vertices in walk order.
    uint64_t rays = 0;      ///< Rays cast to build it.
    /// Number of vertices, endpoint included.
    int size() const { return int(v.size()); }
};
/// A subpath on gdr's own Scene.
using Subpath = BasicSubpath<Scene>;

/// Limits of a subpath walk.
struct WalkOptions {
    /// Most vertices after the endpoint (a path of s + t vertices has s + t - 1
    /// segments, bounded by the integrator's max_depth); -1 unlimited.
    int max_vertices = -1;
    /// Vertex index from which Russian roulette may end the walk (roulette
    /// on the throughput relative to the endpoint's, as the path tracer's).
    int rr_depth = 5;
    /// Record pdf_rev (a BSDF density per vertex): strategies with two or
    /// more light vertices need it; a path tracer's (StrategySet max_s <= 1) do not.
    bool reverse_densities = true;
    /// Record pdf_fwd at every vertex; without it only at emitters, the one
    /// place a path tracer's MIS weight (s = 0 against s = 1) reads it.
    bool forward_densities = true;
};

/// Traces the camera subpath through film point `film` (pixel units): v[0]
/// is the camera, v[k] the k-th hit, drawing vertex k's numbers from the
/// dims::vertex(k) block of `sampler`, as the path tracer does.
void trace_camera_subpath(const Scene& scene, const Vec2& film, const Sampler& sampler, const WalkOptions& opt,
                          Subpath& path);
/// trace_camera_subpath() along primary ray `ray` (unit direction) instead
/// of a film point: the camera vertex sits at ray.o. If `first` is given, it
/// is the ray's hit record, already traced (e.g. in one Embree packet with
/// other samples' rays), and `first_hit` says whether the ray hit.
void trace_camera_subpath(const Scene& scene, const Ray& ray, const Sampler& sampler, const WalkOptions& opt,
                          Subpath& path, const SurfaceInteraction* first = nullptr, bool first_hit = false);
/// Traces a light subpath: v[0] is a point on an emitter chosen by power and
/// area with a cosine-distributed direction (numbers from
/// dims::light_origin()), or a delta light with its own emission direction
/// (DeltaLight::sample_emission; a directional light's ray enters through
/// the bounding disk, as an environment's), v[k] its k-th hit
/// (dims::light_vertex(k)). Empty when the scene has no emitter.
void trace_light_subpath(const Scene& scene, const Sampler& sampler, const WalkOptions& opt, Subpath& path);

/// Area density (1/m^2) at `next` with which vertex `cur`, reached from
/// `prev` (nullptr at a subpath's start), samples the direction to it: the
/// BSDF's density for a surface, the emission density (cos / pi) for a light,
/// the film's direction density for the camera; converted with the cosine
/// at `next` where it is a surface (none at the camera). 0 for a delta lobe.
template <PathHost H>
double pdf_area(const H& scene, std::type_identity_t<const BasicVertex<H>*> prev, const BasicVertex<H>& cur, const BasicVertex<H>& next);
/// Area density (1/m^2) at vertex `to` of solid-angle density pdf_w (1/sr)
/// of the direction from `from`: pdf_w_to_a with the cosine at `to`'s
/// geometric normal (none at the camera).
template <class H>
double area_density(double pdf_w, const BasicVertex<H>& from, const BasicVertex<H>& to) {
    // An environment vertex is measured by solid angle; from one, pdf_w is
    // the emission disk's planar density, projected onto `to` (environment.h).
    if (to.infinite) return pdf_w;
    if (from.infinite)
        return to.type == VertexType::Camera ? pdf_w : pdf_w * std::abs(glm::dot(Vec3d(to.si.ng), Vec3d(from.si.ng)));
    const Vec3d d = Vec3d(to.si.p) - Vec3d(from.si.p);
    const double dist = glm::length(d);
    if (!(dist > 0.0)) return 0.0;
    // The pinhole has no surface: its density takes no cosine.
    const double cos_at_to = to.type == VertexType::Camera ? 1.0 : glm::dot(Vec3d(to.si.ng), d) / dist;
    return pdf_w_to_a(pdf_w, dist, cos_at_to);
}
/// Area density (1/m^2) with which a light subpath would start at emitter
/// point `v` (power and area selection; for an environment vertex the
/// solid-angle density of its direction, selection included); 0 where it does not emit.
template <PathHost H>
double pdf_light_origin(const H& scene, const BasicVertex<H>& v);
/// Area density (1/m^2) at `next` of the direction a light subpath starting
/// at emitter point `v` would emit towards it (cos / pi, converted; for an
/// environment vertex the emission disk's density, path/environment.h).
template <PathHost H>
double pdf_light_direction(const H& scene, const BasicVertex<H>& v, const BasicVertex<H>& next);
/// pdf_light_direction() of a finite emitter point `v` (0 for an environment vertex).
template <class H>
double pdf_light_direction(const BasicVertex<H>& v, const BasicVertex<H>& next);
/// Scattering value at surface vertex `v` from its previous vertex (v.wo)
/// towards unit world direction w, for the vertex's subpath's transport
/// `mode`, with the shading-normal correction that importance transport
/// needs (Veach 1997, section 5.3): f (1/sr).
template <PathHost H>
Color vertex_f(const H& scene, const BasicVertex<H>& v, const Vec3& w, TransportMode mode);
/// |cos| between unit world direction w and the vertex's shading normal (1 at the camera).
template <class H>
float abs_cos_shading(const BasicVertex<H>& v, const Vec3& w);

/// True for a vertex a connection can join on host H: it has a non-delta
/// scattering (or is an endpoint) and is not a black surface.
template <PathHost H>
bool connectible(const H& host, const BasicVertex<H>& v) {
    if (v.type != VertexType::Surface) return true;
    const auto& m = host.surface(v.si);
    return !m.pure_delta && !m.black;
}

// gdr's own Scene's are compiled once, in the library (gdr/path/densities.h).
extern template double pdf_area(const Scene&, const Vertex*, const Vertex&, const Vertex&);
extern template double pdf_light_origin(const Scene&, const Vertex&);
extern template double pdf_light_direction(const Scene&, const Vertex&, const Vertex&);
extern template double pdf_light_direction(const Vertex&, const Vertex&);
extern template Color vertex_f(const Scene&, const Vertex&, const Vec3&, TransportMode);
extern template float abs_cos_shading(const Vertex&, const Vec3&);

}  // namespace gdr
