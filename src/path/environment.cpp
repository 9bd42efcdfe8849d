#include "gdr/path/environment.h"

#include "gdr/core/error.h"
#include "gdr/scene/warp.h"

namespace gdr {

void append_escape_vertex(const Scene& scene, const Ray& ray, const Color& beta, double pdf_w, Subpath& path) {
    const Environment* env = scene.environment();
    if (!env) return;
    Vertex& x = path.v.emplace_back();
    x.type = VertexType::Light;
    x.infinite = true;
    x.si.ng = -ray.d;
    x.si.frame = Frame(x.si.ng);
    x.si.p = scene.beyond_scene(ray.o, ray.d);
    x.si.t = kInf;
    x.wo = -ray.d;
    x.beta = beta;
    x.le = env->eval(ray.d);
    x.pdf_fwd = pdf_w;  // solid angle: the measure of an environment vertex
}

bool start_environment_subpath(const Scene& scene, const LightSample& ls, const Vec2& u_disk, Subpath& path,
                               Ray& ray, Color& beta, double& pdf_disk) {
    if (!ls.infinite || !(ls.pdf_w > 0.f) || is_black(ls.radiance)) return false;
    const Vec3 w_env = -ls.n;
    const float r = scene.bounding_radius();
    const Frame f(w_env);
    const Vec2 c = warp::square_to_uniform_disk(u_disk);
    const Vec3 on_disk = scene.bounds_center() + r * (c.x * f.s + c.y * f.t);
    Vertex& l = path.v.emplace_back();
    l.type = VertexType::Light;
    l.infinite = true;
    l.si.ng = ls.n;
    l.si.frame = Frame(ls.n);
    l.si.p = on_disk + 2.f * r * w_env;
    l.le = ls.radiance;
    l.pdf_fwd = ls.pdf_w;
    l.beta = ls.radiance / ls.pdf_w;
    pdf_disk = environment_disk_pdf(scene);
    // The ray starts outside the bounding sphere, so it meets everything the disk sees.
    ray = Ray{on_disk + r * w_env, ls.n, 0.f, kInf};
    beta = l.beta / float(pdf_disk);
    return true;
}

bool connect_environment(const Scene& scene, const Vertex& pt, const LightSample& ls, Color& value,
                         double& nee_pdf_w, Vertex& q, uint64_t& rays) {
    if (!ls.infinite || !(ls.pdf_w > 0.f) || is_black(ls.radiance) || pt.type != VertexType::Surface) return false;
    const Vec3 w = -ls.n;
    const SurfaceInteraction& si = pt.si;
    const BsdfEval fe = si.material->bsdf->eval_pdf(si.frame.to_local(pt.wo), si.frame.to_local(w), si.uv);
    if (is_black(fe.f)) return false;
    value = pt.beta * fe.f * ls.radiance * (abs_cos_shading(pt, w) / ls.pdf_w);
    if (is_black(value)) return false;
    ++rays;
    if (scene.occluded(spawn_ray(si, w))) return false;
    nee_pdf_w = fe.pdf;
    q.type = VertexType::Light;
    q.infinite = true;
    q.si.p = ls.p, q.si.ng = ls.n, q.si.frame = Frame(ls.n);
    q.le = ls.radiance;
    q.pdf_fwd = ls.pdf_w;
    return true;
}

void require_no_environment(const Scene& scene, const std::string& integrator) {
    if (scene.environment())
        throw InputError(integrator + " does not support environment lights yet: the scene has one (constant or "
                                      "envmap); remove it to use " + integrator);
}

}  // namespace gdr
