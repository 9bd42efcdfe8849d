// Environment lights in the path-space core. An environment vertex is a
// light vertex at infinity (Vertex::infinite): a camera subpath whose ray
// leaves the scene ends on one, a light subpath may start on one, and next-
// event estimation may pick one. Its densities follow pbrt-v4's treatment of
// infinite lights (Pharr, Jakob and Humphreys, "Physically Based Rendering",
// 4th edition, 2023, bidirectional path tracing): the vertex itself is
// measured by solid angle (the density of its direction, 1/sr), and a light
// subpath leaving it starts on a disk of the scene's bounding sphere,
// perpendicular to the direction, so its first hit has the disk's planar
// density 1/(pi r^2) times the cosine there (1/m^2), with no distance term.
#pragma once

#include <string>

#include "gdr/path/subpath.h"

namespace gdr {

/// Unit world direction from vertex `from` towards vertex `to`: exact for
/// environment vertices (their direction, not their far point); zero if two
/// finite vertices coincide.
template <class H>
Vec3 vertex_direction(const BasicVertex<H>& from, const BasicVertex<H>& to) {
    // An environment vertex's ng is the direction light travels from it.
    if (to.infinite) return -to.si.ng;
    if (from.infinite) return from.si.ng;
    const Vec3 d = to.si.p - from.si.p;
    const float len = glm::length(d);
    return len > 0.f ? d / len : Vec3(0.f);
}
/// Planar density (1/m^2) of a light subpath's origin on the environment's
/// emission disk: 1 / (pi r^2) with r the scene's bounding radius.
template <class H>
double environment_disk_pdf(const H& scene) {
    const double r = scene.bounding_radius();
    return 1.0 / (3.14159265358979323846 * r * r);
}
/// Ends a camera subpath whose ray `ray` (unit direction) left the scene on
/// the environment vertex it reached, carrying throughput `beta`; pdf_w is
/// the solid-angle density (1/sr) with which the last vertex sampled the
/// ray's direction (0 after a delta lobe). Nothing without an environment.
void append_escape_vertex(const Scene& scene, const Ray& ray, const Color& beta, double pdf_w, Subpath& path);
/// Starts a light subpath on the environment, as pbrt-v4's infinite lights
/// emit: `ls` is the infinite sample the origin block's numbers drew
/// (Scene::sample_emitter_point), u_disk places the ray's origin on the disk
/// through the bounding sphere's centre perpendicular to the direction,
/// moved out of the sphere. Pushes the environment vertex onto `path` and
/// gives the ray into the scene, the throughput it carries (Le / (p_dir
/// p_disk), W/(m^2 sr) times sr m^2) and the disk density (1/m^2) for its
/// first hit. False if the sample is empty.
bool start_environment_subpath(const Scene& scene, const LightSample& ls, const Vec2& u_disk, Subpath& path,
                               Ray& ray, Color& beta, double& pdf_disk);
/// Next-event estimation from surface vertex `pt` towards infinite sample
/// `ls` (Scene::sample_light): the unweighted estimate (W/(m^2 sr), visibility
/// by an unbounded shadow ray, counted in `rays`), pt's BSDF density of the
/// direction (1/sr) and the environment vertex `q` the connection ends on.
/// False if it contributes nothing.
bool connect_environment(const Scene& scene, const Vertex& pt, const LightSample& ls, Color& value,
                         double& nee_pdf_w, Vertex& q, uint64_t& rays);

/// Throws InputError if `scene` has an environment light, naming `integrator`
/// as one that cannot render it yet (its estimators do not handle paths that
/// leave the scene); called before such an integrator's first sample.
void require_no_environment(const Scene& scene, const std::string& integrator);

}  // namespace gdr
