// Data set rendering, training and checkpoints of the neural reconstructor
// (gdr/neural/training.h).

#include "gdr/neural/training.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>

#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/texture.h"

namespace gdr::neural {
namespace {

namespace fs = std::filesystem;

/// SplitMix64 of a and b: independent streams per view, noise level, step.
uint64_t mix(uint64_t a, uint64_t b) {
    uint64_t z = a * 0x9e3779b97f4a7c15ull + b + 0x632be59bd9b4e019ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/// A tensor entry of an archive. (InputArchive::read into a Tensor calls
/// .device() on its argument, which fails on an undefined tensor.)
torch::Tensor read_tensor(torch::serialize::InputArchive& ar, const std::string& key) {
    c10::IValue v;
    ar.read(key, v);
    return v.toTensor();
}

/// An integer entry that older files may lack (then 0).
torch::Tensor read_optional(torch::serialize::InputArchive& ar, const std::string& key) {
    std::vector<std::string> keys = ar.keys();
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) return torch::tensor(int64_t(0));
    return read_tensor(ar, key);
}

const char* const kFrameLayers[] = {"primal", "dx", "dy", "albedo", "normal", "depth"};
// Kept beside them for the reconstructions that weigh by variance
// (poisson-weighted in `gdr_train validate`); the network does not read them.
const char* const kVarianceLayers[] = {"primal_variance", "dx_variance", "dy_variance", "spp"};

torch::Tensor planar(const Image& img, int channels) {
    torch::Tensor t = torch::empty({img.height(), img.width(), channels}, torch::kFloat32);
    float* o = t.data_ptr<float>();
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x)
            for (int c = 0; c < channels; ++c) *o++ = img.at(x, y, c);
    return t.permute({2, 0, 1}).contiguous();
}

/// A random view near the scene's own camera: the eye and the look-at
/// point moved by up to 10% of their distance, the field of view narrowed
/// log-uniformly to 12-50% (a zoomed-in crop has about the pixel footprint
/// of the full-resolution frame), square, `size` pixels.
CameraDesc random_view(const CameraDesc& base, int size, std::mt19937_64& rng) {
    std::uniform_real_distribution<float> u(-1.f, 1.f), l(std::log(0.12f), std::log(0.5f));
    CameraDesc d = base;
    const float dist = glm::length(base.target - base.position);
    const auto jitter = [&] {
        Vec3 v;
        do v = Vec3(u(rng), u(rng), u(rng));
        while (glm::dot(v, v) > 1.f);
        return v * (0.1f * dist);
    };
    d.position = base.position + jitter();
    d.target = base.target + jitter();
    d.fov_deg = base.fov_deg * std::exp(l(rng));
    d.width = d.height = size;
    return d;
}

/// Distances (scene units) from the eye to the first surface along 16 rays
/// through a 4x4 grid of jittered film points of `camera`; misses are +inf.
std::vector<float> probe_distances(const Scene& scene, const Camera& camera, std::mt19937_64& rng) {
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const CameraDesc& cd = camera.desc();
    std::vector<float> d;
    for (int k = 0; k < 16; ++k) {
        const Vec2 film((float(k % 4) + u(rng)) * 0.25f * float(cd.width), (float(k / 4) + u(rng)) * 0.25f * float(cd.height));
        SurfaceInteraction si;
        d.push_back(scene.intersect(camera.generate_ray(film), si) ? si.t : kInf);
    }
    std::sort(d.begin(), d.end());
    return d;
}

/// DatasetOptions::roam: a view from the scene's open space (see there);
/// `seen` is the median probe distance of the scene's own camera.
CameraDesc roam_view(const Scene& scene, const CameraDesc& base, float seen, int size, std::mt19937_64& rng) {
    std::uniform_real_distribution<float> u(-1.f, 1.f), l(std::log(0.12f), std::log(0.5f));
    const Vec3 up = glm::normalize(base.up);
    const Vec3 fwd = glm::normalize(base.target - base.position);
    const float reach = 0.5f * (std::isfinite(seen) ? seen : glm::length(base.target - base.position));
    // The scene camera's heading (f0, with s0 to its side) and elevation.
    const Vec3 flat = fwd - glm::dot(fwd, up) * up;
    if (glm::dot(flat, flat) < 1e-6f) return base;  // looking straight up or down: keep the scene's view
    const Vec3 f0 = glm::normalize(flat), s0 = glm::cross(f0, up);
    const float elev0 = std::asin(std::clamp(glm::dot(fwd, up), -1.f, 1.f));
    for (int attempt = 0; attempt < 100; ++attempt) {
        Vec3 v;
        do v = Vec3(u(rng), u(rng), u(rng));
        while (glm::dot(v, v) > 1.f);
        CameraDesc d = base;
        d.position = base.position + reach * v;
        // Turned about up (yaw), then tilted towards up (pitch), clamped off the poles.
        const float yaw = glm::radians(60.f) * u(rng), pitch = glm::radians(20.f) * u(rng);
        const float elev = std::clamp(elev0 + pitch, -1.3f, 1.3f);
        const Vec3 h = std::cos(yaw) * f0 + std::sin(yaw) * s0;
        d.target = d.position + std::cos(elev) * h + std::sin(elev) * up;
        d.fov_deg = base.fov_deg * std::exp(l(rng));
        d.width = d.height = size;
        // In the same open space as the scene's eye: nothing between them.
        const Vec3 step = d.position - base.position;
        const float len = glm::length(step);
        SurfaceInteraction si;
        if (len > 0.f && scene.intersect(Ray{base.position, step / len}, si) && si.t < len) continue;
        const std::vector<float> probe = probe_distances(scene, Camera(d), rng);
        if (!std::isfinite(probe[7])) continue;  // half the rays or more see nothing
        if (std::isfinite(seen) && (probe[7] < 0.2f * seen || probe[3] < 0.05f * seen)) continue;
        return d;
    }
    return random_view(base, size, rng);
}

/// A BSDF whose every value is another's times a fixed colour (each channel
/// in [0, 1]): the same lobes and densities, so every integrator and shift
/// treats it as the original, only the reflectance is recoloured.
class TintedBsdf final : public Bsdf {
public:
    TintedBsdf(std::shared_ptr<Bsdf> inner, const Color& tint) : inner_(std::move(inner)), tint_(tint) {}
    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        auto s = inner_->sample(wo, uv, u_lobe, u);
        if (s) s->f *= tint_;
        return s;
    }
    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override { return tint_ * inner_->eval(wo, wi, uv); }
    float pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override { return inner_->pdf(wo, wi, uv); }
    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        BsdfEval e = inner_->eval_pdf(wo, wi, uv);
        e.f *= tint_;
        return e;
    }
    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        auto s = inner_->eval_delta(wo, wi, uv);
        if (s) s->f *= tint_;
        return s;
    }
    uint32_t flags() const override { return inner_->flags(); }
    Color albedo(const Vec2& uv) const override { return tint_ * inner_->albedo(uv); }
    float min_roughness() const override { return inner_->min_roughness(); }
    float eta() const override { return inner_->eta(); }
    bool wo_side_only() const override { return inner_->wo_side_only(); }
    bool is_black() const override { return inner_->is_black(); }

private:
    std::shared_ptr<Bsdf> inner_;
    Color tint_;
};

/// DatasetOptions::vary: the scene's geometry, environment and delta lights
/// with recoloured materials and rescaled emitters, seen by `camera`.
std::unique_ptr<Scene> varied_scene(const Scene& scene, const std::string& origin, const Camera& camera,
                                    std::mt19937_64& rng) {
    std::uniform_real_distribution<float> tint(0.45f, 1.f), light(0.6f, 1.f), scale(std::log(1.f / 3.f), std::log(3.f));
    std::vector<Material> mats = scene.materials();
    for (Material& m : mats) {
        const Color t(tint(rng), tint(rng), tint(rng));
        if (!m.bsdf->is_black()) m.bsdf = std::make_shared<TintedBsdf>(m.bsdf, t);
        if (!is_black(m.emission)) {
            Color c(light(rng), light(rng), light(rng));
            c /= std::max({c.r, c.g, c.b});
            m.emission *= c * std::exp(scale(rng));
        }
    }
    auto out = std::make_unique<Scene>(scene.mesh(), std::move(mats), camera, origin + " (varied)");
    if (scene.environment()) out->set_environment(scene.shared_environment());
    if (!scene.delta_lights().empty()) out->set_delta_lights(scene.delta_lights(), origin);
    return out;
}

/// A random material for an inserted mesh: diffuse, plastic, rough metal,
/// glass or rough glass, in random colours (the shift mappings' whole range
/// of roughness).
Material random_material(std::mt19937_64& rng) {
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const auto colour = [&](float lo) { return Color(lo + (1 - lo) * u(rng), lo + (1 - lo) * u(rng), lo + (1 - lo) * u(rng)); };
    const float alpha = std::exp(std::log(0.02f) + u(rng) * (std::log(0.5f) - std::log(0.02f)));
    Material m;
    switch (int(rng() % 5)) {
        case 0: m.name = "inserted diffuse", m.bsdf = make_lambertian(make_constant_texture(0.85f * colour(0.05f))); break;
        case 1:
            m.name = "inserted plastic";
            m.bsdf = make_plastic(make_constant_texture(0.8f * colour(0.05f)), Color(0.04f), alpha);
            break;
        case 2: m.name = "inserted metal", m.bsdf = make_rough_conductor(colour(0.3f), alpha); break;
        case 3: m.name = "inserted glass", m.bsdf = make_dielectric(1.5f); break;
        default: m.name = "inserted rough glass", m.bsdf = make_rough_dielectric(1.5f, alpha); break;
    }
    return m;
}

/// DatasetOptions::meshes: `scene` with the OBJ `obj` standing on a surface
/// seen by `camera` (the first of 32 camera rays through random pixels that
/// hits one facing up), or, if none does, floating in front of the first
/// surface hit; nullptr if no ray hits anything.
std::unique_ptr<Scene> scene_with_mesh(const Scene& scene, const std::string& origin, const std::string& obj,
                                       const Camera& camera, std::mt19937_64& rng, bool& standing) {
    std::uniform_real_distribution<float> u(0.f, 1.f);
    const CameraDesc& cd = camera.desc();
    const Vec3 up = glm::normalize(cd.up);
    SurfaceInteraction si, first;
    Vec3 first_dir(0.f);
    bool any = false;
    standing = false;
    for (int k = 0; k < 32 && !standing; ++k) {
        // The inner 80% of the frame, so that the object is in view.
        const Vec2 film((0.1f + 0.8f * u(rng)) * float(cd.width), (0.1f + 0.8f * u(rng)) * float(cd.height));
        const Ray ray = camera.generate_ray(film);
        if (!scene.intersect(ray, si) || si.is_emitter()) continue;
        if (!any) first = si, first_dir = ray.d, any = true;
        // The side the camera sees (the winding's front may face away).
        const Vec3 n = glm::dot(si.ng, ray.d) < 0.f ? si.ng : -si.ng;
        standing = glm::dot(n, up) > 0.7f;
    }
    if (!any) return nullptr;
    if (!standing) si = first;
    TriangleMesh part;
    std::vector<Material> part_mats;
    load_obj(obj, Mat4(1.f), part, part_mats);
    if (part.size() == 0) throw InputError(obj + ": no triangles to place into the data set's views (not an OBJ mesh?)");
    Vec3 lo(kInf), hi(-kInf);
    for (const Vec3& p : part.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    // The view's width at the hit's distance; the object spans 30-70% of it.
    const float width = 2.f * si.t * std::tan(0.5f * glm::radians(cd.fov_deg));
    const float scale = (0.3f + 0.4f * u(rng)) * width / std::max(1e-6f, glm::length(hi - lo));
    // Local y up (both shared meshes), base centre at the origin, turned about
    // up, then y mapped onto the scene's up and the base onto the anchor: the
    // hit point, or for a floating object a point in front of it by the
    // object's size, lowered by half its height so that its middle is there.
    const Vec3 base(0.5f * (lo.x + hi.x), lo.y, 0.5f * (lo.z + hi.z));
    const float size = scale * glm::length(hi - lo);
    const Vec3 anchor = standing ? si.p : si.p - first_dir * (0.6f * size) - up * (0.5f * scale * (hi.y - lo.y));
    const float turn = 6.2831853f * u(rng);
    const Vec3 side = glm::normalize(std::abs(up.x) < 0.9f ? glm::cross(up, Vec3(1, 0, 0)) : glm::cross(up, Vec3(0, 0, 1)));
    const Vec3 fwd = glm::cross(side, up);
    // A local direction turned about local y, in the scene's frame (side, up, fwd).
    const auto orient = [&](const Vec3& q) {
        const float x = std::cos(turn) * q.x + std::sin(turn) * q.z, z = -std::sin(turn) * q.x + std::cos(turn) * q.z;
        return x * side + q.y * up + z * fwd;
    };
    const auto place = [&](const Vec3& p) { return anchor + orient((p - base) * scale); };
    TriangleMesh mesh = scene.mesh();
    std::vector<Material> mats = scene.materials();
    const uint32_t id = uint32_t(mats.size());
    mats.push_back(random_material(rng));
    uint32_t object = 0;
    for (uint32_t o : mesh.object_ids) object = std::max(object, o + 1);
    if (mesh.object_ids.empty() && mesh.size() > 0) mesh.object_ids.assign(mesh.size(), 0), object = 1;
    // Shading normals: where only one of the two meshes has them, the other's
    // triangles get their face normals (their flat shading, unchanged). UVs:
    // the inserted material is constant, so the part's are not needed.
    const auto face_normal = [](const Vec3* p) {
        const Vec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
        return glm::length(n) > 0.f ? glm::normalize(n) : Vec3(0, 0, 1);
    };
    const bool normals = !mesh.normals.empty() || !part.normals.empty();
    if (normals && mesh.normals.empty())
        for (size_t t = 0; t < mesh.size(); ++t) mesh.normals.insert(mesh.normals.end(), 3, face_normal(&mesh.positions[3 * t]));
    for (size_t t = 0; t < part.size(); ++t) {
        const size_t first = mesh.positions.size();
        for (int v = 0; v < 3; ++v) mesh.positions.push_back(place(part.positions[3 * t + v]));
        for (int v = 0; v < 3 && normals; ++v) {
            if (part.normals.empty()) {
                mesh.normals.push_back(face_normal(&mesh.positions[first]));
                continue;
            }
            mesh.normals.push_back(glm::normalize(orient(part.normals[3 * t + v])));
        }
        if (!mesh.uvs.empty()) mesh.uvs.insert(mesh.uvs.end(), 3, Vec2(0.f));
        mesh.material_ids.push_back(id);
        mesh.object_ids.push_back(object);
    }
    auto out = std::make_unique<Scene>(std::move(mesh), std::move(mats), camera, origin + " + " + obj);
    if (scene.environment()) out->set_environment(scene.shared_environment());
    if (!scene.delta_lights().empty()) out->set_delta_lights(scene.delta_lights(), origin);
    return out;
}

/// A scene of the data set as loaded, with what its views need.
struct DataScene {
    SceneFile file;
    CameraDesc camera;           ///< The scene's own camera.
    float seen = kInf;           ///< Median probe distance of that camera (DatasetOptions::roam).
    std::unique_ptr<Integrator> gpt;  ///< With the scene file's integrator parameters.
    std::unique_ptr<Integrator> reference;  ///< The targets' integrator (DatasetOptions::target_integrator).
};

}  // namespace

DatasetReport generate_dataset(const DatasetOptions& o, const std::string& dir,
                               const std::function<void(int, int)>& progress) {
    if (o.scenes.empty()) throw ParameterError("data set: no scenes given");
    if (o.crops < 1 || o.size < 2 || o.spp.empty() || o.target_spp < 1)
        throw ParameterError("data set: crops >= 1, size >= 2, at least one spp and target_spp >= 1 are needed");
    if (o.target_integrator != "gpt" && o.target_integrator != "bdpt")
        throw ParameterError("data set: the target integrator must be gpt or bdpt, got '" + o.target_integrator + "'");
    fs::create_directories(dir);
    DatasetReport report;
    std::map<size_t, DataScene> scenes;
    for (int i = 0; i < o.crops; ++i) {
        const std::string path = fmt::format("{}/crop-{:05d}.exr", dir, i);
        if (fs::exists(path)) {
            ++report.kept;
            if (progress) progress(i + 1, o.crops);
            continue;
        }
        const size_t si = size_t(i) % o.scenes.size();
        const std::string& name = o.scenes[si];
        if (report.skipped.count(name)) {
            ++report.skipped_views;
            if (progress) progress(i + 1, o.crops);
            continue;
        }
        if (!scenes.count(si)) {
            DataScene ds;
            try {
                SceneFileOptions lo;
                lo.lenient = o.lenient;
                ds.file = load_scene_file(name, lo);
            } catch (const InputError& e) {
                report.skipped[name] = e.what();
                ++report.skipped_views;
                if (progress) progress(i + 1, o.crops);
                continue;
            }
            ds.camera = ds.file.scene->camera().desc();
            if (o.roam) {
                std::mt19937_64 probe_rng(mix(o.seed, 0x70726f6265ull));  // "probe"
                ds.seen = probe_distances(*ds.file.scene, ds.file.scene->camera(), probe_rng)[7];
            }
            // The file's integrator parameters (a Mitsuba scene's maxDepth,
            // say), as `gdr render --integrator gpt` of the file takes them.
            Params gp(name + " (data set gpt)");
            for (const auto& [k, v] : ds.file.defaults.params.values()) gp.set(k, v);
            gp.set("reconstruct", std::string("none"));
            ds.gpt = integrator_registry().create("gpt", gp);
            if (o.target_integrator == "bdpt") {
                Params bp(name + " (data set target)");
                for (const auto& [k, v] : ds.file.defaults.params.values()) bp.set(k, v);
                bp.set("hide_emitters", true);
                ds.reference = integrator_registry().create("bdpt", bp);
            }
            scenes.emplace(si, std::move(ds));
        }
        DataScene& ds = scenes.at(si);
        Scene& base = *ds.file.scene;
        std::mt19937_64 rng(mix(o.seed, uint64_t(i)));
        const Camera camera(o.roam ? roam_view(base, ds.camera, ds.seen, o.size, rng) : random_view(ds.camera, o.size, rng));
        std::unique_ptr<Scene> varied;
        const bool vary = o.vary && i % 2 == 1;
        if (vary) {
            std::mt19937_64 vary_rng(mix(mix(o.seed, uint64_t(i)), 0x76617279ull));  // "vary"
            varied = varied_scene(base, name, camera, vary_rng);
        } else {
            base.set_camera(camera);
        }
        std::unique_ptr<Scene> with_mesh;
        std::string inserted;
        bool standing = false;
        if (!o.meshes.empty() && i % 4 >= 2) {
            std::mt19937_64 mesh_rng(mix(mix(o.seed, uint64_t(i)), 0x6d657368ull));  // "mesh"
            inserted = o.meshes[size_t(i / 4) % o.meshes.size()];
            with_mesh = scene_with_mesh(varied ? *varied : base, name, inserted, camera, mesh_rng, standing);
            if (!with_mesh) inserted.clear();
        }
        Scene& scene = with_mesh ? *with_mesh : varied ? *varied : base;
        RenderSettings st;
        st.threads = o.threads;
        FrameBuffer out(o.size, o.size), fb;
        st.spp = o.target_spp, st.seed = mix(mix(o.seed, uint64_t(i)), 0);
        if (ds.reference) {
            ds.reference->render(scene, st, fb);
            out.set("target", fb.get("color"));
        } else {
            ds.gpt->render(scene, st, fb);
            out.set("target", fb.get("primal"));
        }
        std::string levels;
        for (int s : o.spp) {
            st.spp = s, st.seed = mix(mix(o.seed, uint64_t(i)), uint64_t(s));
            ds.gpt->render(scene, st, fb);
            for (const char* layer : kFrameLayers) out.set(fmt::format("s{}_{}", s, layer), fb.get(layer));
            for (const char* layer : kVarianceLayers) out.set(fmt::format("s{}_{}", s, layer), fb.get(layer));
            levels += (levels.empty() ? "" : ",") + std::to_string(s);
        }
        out.metadata()["scene"] = name;
        if (vary) out.metadata()["varied"] = "true";
        if (!inserted.empty()) {
            out.metadata()["inserted_mesh"] = inserted;
            out.metadata()["inserted_mesh_placement"] = standing ? "standing" : "floating";
        }
        out.metadata()["spp"] = levels;
        out.metadata()["target_spp"] = std::to_string(o.target_spp);
        out.metadata()["target_integrator"] = o.target_integrator;
        if (o.roam) out.metadata()["view"] = "roam";
        if (!ds.file.warnings.empty()) out.metadata()["load_warnings"] = std::to_string(ds.file.warnings.size());
        // Written aside and renamed: an interrupted view leaves no file that looks finished.
        const std::string tmp = fmt::format("{}/.partial-crop-{:05d}.exr", dir, i);
        write_exr(tmp, out);
        fs::rename(tmp, path);
        ++report.written;
        if (progress) progress(i + 1, o.crops);
    }
    return report;
}

Sample make_sample(const GradientBuffers& noisy, const Image& target, const UNetConfig& config, int spp) {
    if (target.width() != noisy.primal->width() || target.height() != noisy.primal->height() || target.channels() < 3)
        throw InputError("training sample: the target's shape differs from the noisy frame's");
    check_gradient_buffers(noisy);
    return Sample{make_input(noisy, config)[0].clone(), planar(target, 3), spp};
}

FrameBuffer view_frame(const FrameBuffer& view, int spp) {
    FrameBuffer frame(view.width(), view.height());
    for (const char* name : kFrameLayers) {
        const std::string layer = fmt::format("s{}_{}", spp, name);
        if (!view.has(layer)) throw InputError("missing layer '" + layer + "'");
        frame.set(name, view.get(layer));
    }
    // All or none: data sets made before they were kept have none.
    if (view.has(fmt::format("s{}_{}", spp, kVarianceLayers[0])))
        for (const char* name : kVarianceLayers) frame.set(name, view.get(fmt::format("s{}_{}", spp, name)));
    return frame;
}

std::vector<Sample> load_dataset(const std::string& dir, const UNetConfig& config) {
    std::vector<std::string> files;
    if (fs::is_directory(dir))
        for (const auto& e : fs::recursive_directory_iterator(dir)) {
            const std::string name = e.path().filename().string();
            if (name.rfind("crop-", 0) == 0 && e.path().extension() == ".exr") files.push_back(e.path().string());
        }
    if (files.empty()) throw InputError("data set " + dir + ": no crop-*.exr files (render them with gdr_train data)");
    std::sort(files.begin(), files.end());
    std::vector<Sample> samples;
    for (const std::string& f : files) {
        const FrameBuffer fb = read_exr(f);
        if (!fb.has("target") || !fb.metadata().count("spp"))
            throw InputError(f + ": not a gdr_train data set file (no 'target' layer or 'spp' entry)");
        std::string list = fb.metadata().at("spp");
        for (size_t pos = 0; pos <= list.size();) {
            const size_t comma = std::min(list.find(',', pos), list.size());
            const int s = std::stoi(list.substr(pos, comma - pos));
            pos = comma + 1;
            FrameBuffer frame;
            try {
                frame = view_frame(fb, s);
            } catch (const InputError& e) {
                throw InputError(f + ": " + e.what());
            }
            if (config.weighted && !frame.has("primal_variance"))
                throw InputError(f + ": missing layer 's" + std::to_string(s) +
                                 "_primal_variance' (the weighted Poisson input needs it; render the data set again)");
            samples.push_back(make_sample(gradient_buffers(frame), fb.get("target"), config, s));
        }
    }
    return samples;
}

torch::Tensor training_loss(const torch::Tensor& p, const torch::Tensor& t, double relmse_weight) {
    // v / (1 + |v|): Reinhard's tone map, odd-extended so that slightly
    // negative predictions still get gradients.
    const auto tone = [](const torch::Tensor& v) { return v / (1 + torch::abs(v)); };
    const torch::Tensor l1 = torch::abs(tone(p) - tone(t)).mean();
    const torch::Tensor rel = ((p - t).square() / (t.square() + 0.01)).mean();
    return l1 + relmse_weight * rel;
}

double rel_mse(const torch::Tensor& x, const torch::Tensor& r) {
    const torch::Tensor xd = x.to(torch::kFloat64), rd = r.to(torch::kFloat64);
    return ((xd - rd).square() / (rd.square() + 0.01)).mean().item<double>();
}

namespace {

/// Training-time output: exp(y) - 1 with y clamped only above (so negative
/// corrections keep their gradients), cropped to the target's size.
torch::Tensor train_output(UNet& net, const torch::Tensor& x, int H, int W) {
    torch::Tensor y = net->forward(x).slice(2, kMargin, kMargin + H).slice(3, kMargin, kMargin + W);
    return torch::expm1(torch::clamp_max(y, 80.0));
}

}  // namespace

torch::Tensor predict(UNet& net, const Sample& s) {
    torch::NoGradGuard guard;
    const int H = int(s.target.size(1)), W = int(s.target.size(2));
    torch::Tensor y = net->forward(s.input.unsqueeze(0)).slice(2, kMargin, kMargin + H).slice(3, kMargin, kMargin + W);
    return decode_colour(y)[0];
}

Sample augment(const Sample& s, const UNetConfig& config, const Augmentation& a) {
    const InputLayout l = input_layout(config);
    const int H = int(s.target.size(1)), W = int(s.target.size(2));
    const int Hp = int(s.input.size(1)), Wp = int(s.input.size(2));
    if (a.transpose && (H != W || Hp != Wp)) throw ParameterError("augmentation: only a square sample can be transposed");
    if ((a.flip_x && Wp - W != 2 * kMargin) || (a.flip_y && Hp - H != 2 * kMargin))
        throw ParameterError("augmentation: a flipped axis needs equal padding on both sides (size + " +
                             std::to_string(2 * kMargin) + " a multiple of the network's stride)");
    if (a.permutation < 0 || a.permutation > 5) throw ParameterError("augmentation: permutation must be in 0..5");
    constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    const int* perm = kPerm[a.permutation];
    // Channel c of the result comes from channel from[c] of the input.
    std::vector<int64_t> from(size_t(s.input.size(0)));
    for (size_t c = 0; c < from.size(); ++c) from[c] = int64_t(c);
    const auto triple = [&](int first) {
        if (first >= 0)
            for (int j = 0; j < 3; ++j) from[size_t(first + j)] = first + perm[j];
    };
    triple(l.poisson), triple(l.primal), triple(l.albedo);
    if (l.dx >= 0)
        for (int j = 0; j < 3; ++j) {
            // A transpose turns dy into dx and dx into dy.
            from[size_t(l.dx + j)] = (a.transpose ? l.dy : l.dx) + perm[j];
            from[size_t(l.dy + j)] = (a.transpose ? l.dx : l.dy) + perm[j];
        }
    const torch::Tensor index = torch::tensor(from);
    torch::Tensor x = s.input.index_select(0, index);
    torch::Tensor t = s.target.index_select(0, torch::tensor(std::vector<int64_t>{perm[0], perm[1], perm[2]}));
    if (a.transpose) x = x.transpose(1, 2), t = t.transpose(1, 2);
    // dx(x) = I(x+1) - I(x): mirrored, the difference at x' = W-1-x belongs
    // to the pair (x'-1, x'), so it is negated and moves one pixel left; the
    // value rolled in at the far end is the padding's zero.
    const auto mirror = [&](int dim, int gradient) {
        x = x.flip({dim});
        if (gradient >= 0) {
            const torch::Tensor g = -x.slice(0, gradient, gradient + 3).roll({-1}, {dim});
            x = x.clone();
            x.slice(0, gradient, gradient + 3).copy_(g);
        }
        t = t.flip({dim});
    };
    if (a.flip_x) mirror(2, l.dx);
    if (a.flip_y) mirror(1, l.dy);
    return Sample{x.contiguous(), t.contiguous(), s.spp};
}

Trainer::Trainer(const TrainOptions& options, std::vector<Sample> samples)
    : options_(options), samples_(std::move(samples)) {
    if (samples_.empty()) throw ParameterError("training: no samples");
    if (options_.batch < 1) throw ParameterError("training: batch must be >= 1");
    for (const Sample& s : samples_)
        if (s.input.size(0) != input_channels(options_.config) || !s.input.sizes().equals(samples_[0].input.sizes()))
            throw ParameterError("training: all samples need the same size and " +
                                 std::to_string(input_channels(options_.config)) + " input channels");
    torch::manual_seed(options_.seed);
    net_ = UNet(options_.config);
    optimizer_ = std::make_unique<torch::optim::Adam>(
        net_->parameters(), torch::optim::AdamOptions(options_.learning_rate).betas({0.9, 0.99}));
}

void Trainer::start_from(UNet& trained) {
    if (step_ != 0) throw ParameterError("training: start_from() after the first step");
    const UNetConfig& a = trained->config();
    const UNetConfig& b = options_.config;
    // The shape, not what the inputs hold: a network of the L1 Poisson input
    // can start one of the weighted input, whose first channels are alike.
    if (a.widths != b.widths || input_channels(a) != input_channels(b))
        throw ParameterError(fmt::format("training: the starting network has {} inputs and widths {}, this run {} and {}",
                                         input_channels(a), fmt::join(a.widths, ","), input_channels(b),
                                         fmt::join(b.widths, ",")));
    torch::NoGradGuard guard;
    const auto from = trained->named_parameters();
    for (auto& p : net_->named_parameters()) p.value().copy_(from[p.key()]);
}

double Trainer::step() {
    std::mt19937_64 rng(mix(options_.seed, uint64_t(step_)));
    std::uniform_int_distribution<size_t> pick(0, samples_.size() - 1);
    std::vector<torch::Tensor> xs, ts;
    for (int b = 0; b < options_.batch; ++b) {
        const Sample& s = samples_[pick(rng)];
        if (options_.augment) {
            Augmentation a;
            const bool square = s.target.size(1) == s.target.size(2);
            a.transpose = square && (rng() & 1);
            a.flip_x = rng() & 1, a.flip_y = rng() & 1;
            a.permutation = int(rng() % 6);
            const Sample v = augment(s, options_.config, a);
            xs.push_back(v.input), ts.push_back(v.target);
        } else {
            xs.push_back(s.input), ts.push_back(s.target);
        }
    }
    const torch::Tensor x = torch::stack(xs), t = torch::stack(ts);
    const double lr = options_.learning_rate * std::min(1.0, double(step_ + 1) / std::max(1, options_.warmup));
    for (auto& group : optimizer_->param_groups()) static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
    optimizer_->zero_grad();
    const torch::Tensor loss = training_loss(train_output(net_, x, int(t.size(2)), int(t.size(3))), t,
                                             options_.relmse_weight);
    loss.backward();
    torch::nn::utils::clip_grad_norm_(net_->parameters(), 1.0);
    optimizer_->step();
    ++step_;
    losses_.push_back(loss.item<double>());
    return losses_.back();
}

double Trainer::evaluate(const std::vector<Sample>& samples) {
    torch::NoGradGuard guard;
    double sum = 0.0;
    for (const Sample& s : samples) {
        const int H = int(s.target.size(1)), W = int(s.target.size(2));
        sum += training_loss(train_output(net_, s.input.unsqueeze(0), H, W), s.target.unsqueeze(0),
                             options_.relmse_weight)
                   .item<double>();
    }
    return samples.empty() ? 0.0 : sum / double(samples.size());
}

void Trainer::save_checkpoint(const std::string& path) {
    torch::serialize::OutputArchive ar, net_ar, opt_ar;
    net_->save(net_ar);
    optimizer_->save(opt_ar);
    ar.write("net", net_ar);
    ar.write("optimizer", opt_ar);
    ar.write("step", torch::tensor(int64_t(step_)));
    ar.write("losses", torch::tensor(losses_, torch::kFloat64));
    std::vector<int64_t> widths(options_.config.widths.begin(), options_.config.widths.end());
    ar.write("option_widths", torch::tensor(widths));
    ar.write("option_gradients", torch::tensor(int64_t(options_.config.gradients)));
    ar.write("option_batch", torch::tensor(int64_t(options_.batch)));
    ar.write("option_learning_rate", torch::tensor(options_.learning_rate, torch::kFloat64));
    ar.write("option_warmup", torch::tensor(int64_t(options_.warmup)));
    ar.write("option_relmse_weight", torch::tensor(options_.relmse_weight, torch::kFloat64));
    ar.write("option_seed", torch::tensor(int64_t(options_.seed)));
    ar.write("option_poisson", torch::tensor(int64_t(options_.config.poisson)));
    ar.write("option_weighted", torch::tensor(int64_t(options_.config.weighted)));
    ar.write("option_augment", torch::tensor(int64_t(options_.augment)));
    const std::string tmp = path + ".partial";
    ar.save_to(tmp);
    fs::rename(tmp, path);
}

void Trainer::load_checkpoint(const std::string& path) {
    if (!fs::is_regular_file(path)) throw InputError("checkpoint " + path + " does not exist");
    torch::serialize::InputArchive ar, net_ar, opt_ar;
    torch::Tensor step, losses, widths, gradients, batch, lr, warmup, relw, seed, poisson, weighted, augment;
    try {
        ar.load_from(path);
        step = read_tensor(ar, "step");
        losses = read_tensor(ar, "losses");
        widths = read_tensor(ar, "option_widths");
        gradients = read_tensor(ar, "option_gradients");
        batch = read_tensor(ar, "option_batch");
        lr = read_tensor(ar, "option_learning_rate");
        warmup = read_tensor(ar, "option_warmup");
        relw = read_tensor(ar, "option_relmse_weight");
        seed = read_tensor(ar, "option_seed");
        // Added later: a checkpoint without them was made with both off.
        poisson = read_optional(ar, "option_poisson");
        weighted = read_optional(ar, "option_weighted");
        augment = read_optional(ar, "option_augment");
    } catch (const std::exception& e) {
        const std::string what = e.what();
        throw InputError("checkpoint " + path + " is not a gdr_train checkpoint or is corrupt: " +
                         what.substr(0, what.find('\n')));
    }
    const auto differs = [&](const char* key, const std::string& was, const std::string& now) {
        if (was != now)
            throw ParameterError("checkpoint " + path + " was made with " + key + "=" + was + ", this run has " + now);
    };
    std::string w_was, w_now;
    for (int64_t i = 0; i < widths.numel(); ++i) w_was += (i ? "," : "") + std::to_string(widths[i].item<int64_t>());
    for (size_t i = 0; i < options_.config.widths.size(); ++i)
        w_now += (i ? "," : "") + std::to_string(options_.config.widths[i]);
    differs("widths", w_was, w_now);
    differs("gradients", std::to_string(gradients.item<int64_t>()), std::to_string(int(options_.config.gradients)));
    differs("batch", std::to_string(batch.item<int64_t>()), std::to_string(options_.batch));
    differs("learning_rate", fmt::format("{}", lr.item<double>()), fmt::format("{}", options_.learning_rate));
    differs("warmup", std::to_string(warmup.item<int64_t>()), std::to_string(options_.warmup));
    differs("relmse_weight", fmt::format("{}", relw.item<double>()), fmt::format("{}", options_.relmse_weight));
    differs("seed", std::to_string(uint64_t(seed.item<int64_t>())), std::to_string(options_.seed));
    differs("poisson", std::to_string(poisson.item<int64_t>()), std::to_string(int(options_.config.poisson)));
    differs("weighted", std::to_string(weighted.item<int64_t>()), std::to_string(int(options_.config.weighted)));
    differs("augment", std::to_string(augment.item<int64_t>()), std::to_string(int(options_.augment)));
    try {
        ar.read("net", net_ar);
        ar.read("optimizer", opt_ar);
        net_->load(net_ar);
        optimizer_->load(opt_ar);
    } catch (const std::exception& e) {
        const std::string what = e.what();
        throw InputError("checkpoint " + path + ": cannot restore the network or optimiser: " +
                         what.substr(0, what.find('\n')));
    }
    step_ = step.item<int64_t>();
    losses_.assign(losses.data_ptr<double>(), losses.data_ptr<double>() + losses.numel());
}

}  // namespace gdr::neural
