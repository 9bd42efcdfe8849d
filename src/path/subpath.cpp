#include "gdr/path/subpath.h"

#include "gdr/path/walk.h"

#include "gdr/path/vertex.h"
#include "gdr/path/dims.h"
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

double pdf_area(const Scene& scene, const Vertex* prev, const Vertex& cur, const Vertex& next) {
    if (cur.infinite) return area_density(environment_disk_pdf(scene), cur, next);
    if (next.infinite || (prev && prev->infinite)) {
        // Directions to vertices at infinity are theirs, not their far points'.
        if (cur.type != VertexType::Surface || !prev) return 0.0;
        const SurfaceInteraction& si = cur.si;
        const double pdf_w = si.material->bsdf->pdf(si.frame.to_local(vertex_direction(cur, *prev)),
                                                    si.frame.to_local(vertex_direction(cur, next)), si.uv);
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
            const SurfaceInteraction& si = cur.si;
            pdf_w = si.material->bsdf->pdf(si.frame.to_local(to_prev), si.frame.to_local(w), si.uv);
            break;
        }
    }
    return area_density(pdf_w, cur, next);
}

double pdf_light_origin(const Scene& scene, const Vertex& v) {
    if (v.delta_light) return scene.delta_light_pdf(*v.delta_light);
    if (v.infinite) return scene.environment_pdf(-v.si.ng);
    if (v.type == VertexType::Light) return v.pdf_fwd;
    if (v.type != VertexType::Surface || !v.si.is_emitter()) return 0.0;
    return scene.light_pdf_a(v.si.prim);
}

double pdf_light_direction(const Scene& scene, const Vertex& v, const Vertex& next) {
    return v.infinite ? area_density(environment_disk_pdf(scene), v, next) : pdf_light_direction(v, next);
}

double pdf_light_direction(const Vertex& v, const Vertex& next) {
    if (v.infinite) return 0.0;  // needs the scene's disk: the overload above
    const Vec3 d = next.si.p - v.si.p;
    const float len = glm::length(d);
    if (!(len > 0.f)) return 0.0;
    if (v.delta_light) return area_density(v.delta_light->emission_pdf_w(d / len), v, next);
    return area_density(std::max(0.f, glm::dot(v.si.ng, d / len)) * kInvPi, v, next);
}

Color vertex_f(const Vertex& v, const Vec3& w, TransportMode mode) {
    if (v.type != VertexType::Surface) return Color(0.f);
    const SurfaceInteraction& si = v.si;
    const Bsdf& bsdf = *si.material->bsdf;
    const Vec3 wo = si.frame.to_local(v.wo), wi = si.frame.to_local(w);
    return bsdf.eval(wo, wi, si.uv) * (transport_factor(bsdf, wo, wi, mode) * shading_correction(si, v.wo, w, mode));
}

float abs_cos_shading(const Vertex& v, const Vec3& w) {
    return v.type == VertexType::Camera ? 1.f : std::abs(glm::dot(v.si.frame.n, w));
}

}  // namespace gdr
