#include "gdr/path/subpath.h"

#include "gdr/path/walk.h"

#include "gdr/path/vertex.h"
#include "gdr/path/dims.h"
#include "gdr/path/densities.h"
#include "gdr/path/environment.h"
#include "gdr/scene/warp.h"

namespace gdr {


void trace_camera_subpath(const Scene& scene, const Vec2& film, const Sampler& sampler, const WalkOptions& opt,
                          Subpath& path) {
    trace_camera_subpath(scene, scene.camera().generate_ray(film), sampler, opt, path);
}

void trace_camera_subpath(const Scene& scene, const Ray& ray, const Sampler& sampler, const WalkOptions& opt,
                          Subpath& path, const SurfaceInteraction* first, bool first_hit) {
    SurfaceInteraction* slot = begin_camera_subpath(scene, ray, path);
    if (first) *slot = *first;
    else first_hit = scene.intersect(ray, *slot);
    walk_subpath(scene, ray, Color(1.f), Color(1.f), scene.camera().direction_pdf(ray.d), sampler, opt, path,
                 RecordVertices{}, true, first_hit);
}

namespace {

// trace_light_subpath() from delta-light sample `ls` (Scene::sample_emitter_point).
void start_delta_subpath(const Scene& scene, const LightSample& ls, const Sampler& sampler, const WalkOptions& opt,
                         Subpath& path) {
    const uint32_t b = dims::light_origin();
    const DeltaLight& dl = *ls.delta_light;
    if (ls.infinite) {
        // A delta direction: the environment's disk, with the selection
        // probability as the direction's density and E in place of L.
        Ray ray;
        Color beta;
        double pdf_disk = 0.0;
        if (start_environment_subpath(scene, ls, sampler.at2(b + dims::kEmitDir), path, ray, beta, pdf_disk)) {
            path.v.back().delta_light = &dl;
            walk_subpath(scene, ray, beta, Color(1.f), pdf_disk, sampler, opt, path, RecordVertices{});
        }
        return;
    }
    if (!(ls.pdf_a > 0.f)) return;
    const Vec3 w = dl.sample_emission(sampler.at2(b + dims::kEmitDir));
    const float pdf_dir = dl.emission_pdf_w(w);
    Vertex& l = path.v.emplace_back();
    l.type = VertexType::Light;
    l.delta_light = &dl;
    l.si.p = ls.p;
    l.si.ng = w;  // the emitted direction: cosines at a point light are 1
    l.si.frame = Frame(w);
    l.le = dl.intensity_towards(w);
    l.pdf_fwd = ls.pdf_a;
    // I(w) / (p_select pdf_dir): W/sr over (unitless times 1/sr), no cosine at a point.
    l.beta = dl.intensity / ls.pdf_a;
    if (!(pdf_dir > 0.f) || is_black(l.le)) return;
    const Ray ray{ls.p, w, 0.f, kInf};
    walk_subpath(scene, ray, l.le / (ls.pdf_a * pdf_dir), Color(1.f), pdf_dir, sampler, opt, path, RecordVertices{});
}

}  // namespace

void trace_light_subpath(const Scene& scene, const Sampler& sampler, const WalkOptions& opt, Subpath& path) {
    path.mode = TransportMode::Importance;
    path.v.clear();
    path.rays = 0;
    if (!scene.has_lights()) return;
    const uint32_t b = dims::light_origin();
    const LightSample ls = scene.sample_emitter_point(sampler.at(b + dims::kEmitSelect), sampler.at2(b + dims::kEmitPoint));
    if (ls.delta) {
        start_delta_subpath(scene, ls, sampler, opt, path);
        return;
    }
    if (ls.infinite) {
        Ray ray;
        Color beta;
        double pdf_disk = 0.0;
        if (start_environment_subpath(scene, ls, sampler.at2(b + dims::kEmitDir), path, ray, beta, pdf_disk))
            walk_subpath(scene, ray, beta, Color(1.f), pdf_disk, sampler, opt, path, RecordVertices{});
        return;
    }
    if (!(ls.pdf_a > 0.f) || is_black(ls.radiance)) return;
    Vertex l;
    l.type = VertexType::Light;
    l.si.p = ls.p;
    l.si.ng = ls.n;
    l.si.frame = Frame(ls.n);
    l.si.prim = ls.prim;
    l.le = ls.radiance;
    l.pdf_fwd = ls.pdf_a;
    l.beta = ls.radiance / ls.pdf_a;
    const Vec3 local = warp::square_to_cosine_hemisphere(sampler.at2(b + dims::kEmitDir));
    const float pdf_dir = warp::cosine_hemisphere_pdf(local);
    path.v.push_back(l);
    if (!(pdf_dir > 0.f)) return;
    const Vec3 w = l.si.frame.to_world(local);
    const Ray ray{offset_ray_origin(ls.p, ls.n, w), w, 0.f, kInf};
    // |cos| / pdf of a cosine-distributed direction is pi.
    walk_subpath(scene, ray, l.beta * (abs_cos_theta(local) / pdf_dir), Color(1.f), pdf_dir, sampler, opt, path,
                 RecordVertices{});
}

template double pdf_area(const Scene&, const Vertex*, const Vertex&, const Vertex&);
template double pdf_light_origin(const Scene&, const Vertex&);
template double pdf_light_direction(const Scene&, const Vertex&, const Vertex&);
template double pdf_light_direction(const Vertex&, const Vertex&);
template Color vertex_f(const Scene&, const Vertex&, const Vec3&, TransportMode);
template float abs_cos_shading(const Vertex&, const Vec3&);

}  // namespace gdr
