#include "gdr/scene/scene.h"

#include <algorithm>
#include <bit>
#include <mutex>

#include <embree3/rtcore.h>
#ifdef GDR_SIMD
#include <xmmintrin.h>
#include <emmintrin.h>
#endif

#include "gdr/core/error.h"
#include "gdr/scene/coordinates.h"

#include <fmt/format.h>

namespace gdr {

namespace {
void embree_error(void* user, RTCError code, const char* msg) {
    // Embree calls this from inside its API; the flag is checked after each call that may fail.
    auto* last = static_cast<std::string*>(user);
    *last = "Embree error " + std::to_string(int(code)) + ": " + (msg ? msg : "");
}

// Embree's filter for every hit candidate, of single rays and packets alike,
// on geometry with alpha cut-outs: a candidate the mask cuts out is rejected,
// and traversal goes on to the next surface, so every query (closest hit,
// shadow ray, packet) sees the same holes without the integrators knowing.
void alpha_filter(const RTCFilterFunctionNArguments* args) {
    const auto* scene = static_cast<const Scene*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        if (scene->cut_out(RTCHitN_primID(args->hit, args->N, i), RTCHitN_u(args->hit, args->N, i),
                           RTCHitN_v(args->hit, args->N, i)))
            args->valid[i] = 0;
    }
}
// A new triangle geometry on `dev` holding triangles [first, first + count) of
// `m`; throws RuntimeFailure naming `origin` if Embree cannot allocate it.
RTCGeometry triangle_geometry(RTCDevice dev, const TriangleMesh& m, size_t first, size_t count,
                              const std::string& last_error, const std::string& origin) {
    RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* verts = static_cast<float*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * count));
    auto* idx = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), count));
    if (!verts || !idx) {
        rtcReleaseGeometry(geom);
        throw RuntimeFailure(origin + ": " + (last_error.empty() ? "Embree buffer allocation failed" : last_error));
    }
    for (size_t i = 0; i < 3 * count; ++i) {
        const Vec3& p = m.positions[3 * first + i];
        verts[3 * i + 0] = p.x, verts[3 * i + 1] = p.y, verts[3 * i + 2] = p.z;
        idx[i] = uint32_t(i);
    }
    return geom;
}
}  // namespace

SharedGeometry::SharedGeometry(const TriangleMesh& mesh, const std::string& origin) : triangles_(mesh.size()) {
    if (mesh.positions.size() != 3 * mesh.size() || mesh.size() == 0)
        throw InputError(origin + ": shared geometry needs three positions per triangle, and a triangle");
    for (size_t t = 0; t < mesh.size(); ++t) {
        const Vec3* p = &mesh.positions[3 * t];
        if (!within_coordinate_range(p[0]) || !within_coordinate_range(p[1]) || !within_coordinate_range(p[2]) ||
            zero_area_triangle(p[0], p[1], p[2]))
            throw InputError(origin + ": shared triangle " + std::to_string(t) +
                             " is degenerate, not finite or beyond the coordinate range (see kMaxCoordinate)");
    }
    RTCDevice dev = rtcNewDevice("threads=0");
    if (!dev) throw RuntimeFailure("cannot create an Embree device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    device_ = dev;
    rtcSetDeviceErrorFunction(dev, embree_error, &last_error_);
    RTCScene scene = rtcNewScene(dev);
    scene_ = scene;
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = triangle_geometry(dev, mesh, 0, mesh.size(), last_error_, origin);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);
    if (!last_error_.empty()) throw RuntimeFailure(origin + ": " + last_error_);
}

SharedGeometry::~SharedGeometry() {
    if (scene_) rtcReleaseScene(static_cast<RTCScene>(scene_));
    if (device_) rtcReleaseDevice(static_cast<RTCDevice>(device_));
}

namespace {
// Fills the BSDF flags a Material caches (see Material::min_roughness).
void cache_bsdf_flags(Material& m) {
    m.min_roughness = m.bsdf->min_roughness();
    m.pure_delta = m.bsdf->is_pure_delta();
    m.wo_side_only = m.bsdf->wo_side_only();
    m.black = m.bsdf->is_black();
}

// Unit vertex normal `n`, or the face's where `n` is missing or broken;
// `face` is the triangle's cross product and `face_len` its length.
Vec3 vertex_normal(const Vec3& n, const Vec3& face, float face_len) {
    const float nl = glm::length(n);
    return nl > 0.f && std::isfinite(nl) ? n / nl : face / face_len;
}
}  // namespace

Scene::Scene(TriangleMesh mesh, std::vector<Material> materials, const Camera& camera, const std::string& origin,
             std::shared_ptr<SharedGeometry> shared)
    : materials_(std::move(materials)), camera_(camera) {
    for (Material& mat : materials_) {
        if (!mat.bsdf) throw InputError(origin + ": material '" + mat.name + "' has no BSDF");
        cache_bsdf_flags(mat);
    }
    // Inconsistent arrays (a caller building the mesh itself) would be read out of bounds.
    const auto sizes = [&] {
        return " (" + std::to_string(mesh.positions.size()) + " positions, " + std::to_string(mesh.normals.size()) +
               " normals, " + std::to_string(mesh.uvs.size()) + " uvs, " + std::to_string(mesh.material_ids.size()) +
               " material ids)";
    };
    if (mesh.positions.size() != 3 * mesh.material_ids.size())
        throw InputError(origin + ": a mesh needs three positions per material id" + sizes());
    if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
        throw InputError(origin + ": a mesh's normals, if any, must match its positions one to one" + sizes());
    if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size())
        throw InputError(origin + ": a mesh's uvs, if any, must match its positions one to one" + sizes());
    if (!mesh.object_ids.empty() && mesh.object_ids.size() != mesh.material_ids.size())
        throw InputError(origin + ": a mesh's object ids, if any, must match its material ids one to one" + sizes());
    // Validate and compact: non-finite vertices are an error, zero-area triangles are dropped.
    TriangleMesh m;
    const bool has_n = !mesh.normals.empty(), has_uv = !mesh.uvs.empty();
    for (size_t t = 0; t < mesh.size(); ++t) {
        const Vec3* p = &mesh.positions[3 * t];
        for (int k = 0; k < 3; ++k) {
            if (!is_finite(p[k]))
                throw InputError(origin + ": triangle " + std::to_string(t) + " has a non-finite vertex");
            // Rays from such a point are invalid to Embree (see kMaxCoordinate).
            if (!within_coordinate_range(p[k]))
                throw InputError(fmt::format("{}: triangle {} has a vertex at ({}, {}, {}), beyond +-{:g} on an axis",
                                             origin, t, p[k].x, p[k].y, p[k].z, kMaxCoordinate));
        }
        if (mesh.material_ids[t] >= materials_.size())
            throw InputError(origin + ": triangle " + std::to_string(t) + " has no material");
        if (zero_area_triangle(p[0], p[1], p[2])) {
            stats_.degenerate_skipped++;
            continue;
        }
        const Vec3 c = glm::cross(p[1] - p[0], p[2] - p[0]);
        const float len = glm::length(c);
        for (int k = 0; k < 3; ++k) {
            m.positions.push_back(p[k]);
            if (has_n) m.normals.push_back(vertex_normal(mesh.normals[3 * t + k], c, len));
            if (has_uv) m.uvs.push_back(is_finite(Vec3(mesh.uvs[3 * t + k], 0.f)) ? mesh.uvs[3 * t + k] : Vec2(0.f));
        }
        m.material_ids.push_back(mesh.material_ids[t]);
        if (!mesh.object_ids.empty()) m.object_ids.push_back(mesh.object_ids[t]);
    }
    if (m.size() == 0) throw InputError(origin + ": the scene has no (non-degenerate) triangles");
    mesh_ = std::move(m);
    stats_.triangles = mesh_.size();

    compute_bounds();

    if (shared) {
        build_on_shared(std::move(shared), origin);
    } else {
        static thread_local std::string last_error;
        last_error.clear();
        RTCDevice dev = rtcNewDevice("threads=0");
        if (!dev) throw RuntimeFailure("cannot create an Embree device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
        rtc_device_ = dev;
        rtcSetDeviceErrorFunction(dev, embree_error, &last_error);
        // An Embree built without ray packets (EMBREE_RAY_PACKETS off) rejects
        // rtcIntersect4/8; intersect4() then traces its rays one by one.
        packets4_ = rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) != 0;
        packets8_ = rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) != 0;
        RTCScene scene = rtcNewScene(dev);
        rtc_scene_ = scene;
        rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
        RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* verts = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                  3 * sizeof(float), mesh_.positions.size()));
        auto* idx = static_cast<uint32_t*>(
            rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), mesh_.size()));
        if (!verts || !idx) {
            rtcReleaseGeometry(geom);
            throw RuntimeFailure(origin + ": " + (last_error.empty() ? "Embree buffer allocation failed" : last_error));
        }
        for (size_t i = 0; i < mesh_.positions.size(); ++i) {
            verts[3 * i + 0] = mesh_.positions[i].x;
            verts[3 * i + 1] = mesh_.positions[i].y;
            verts[3 * i + 2] = mesh_.positions[i].z;
            idx[i] = uint32_t(i);
        }
        if (std::any_of(materials_.begin(), materials_.end(), [](const Material& m) { return m.opacity != nullptr; })) {
            rtcSetGeometryUserData(geom, this);
            rtcSetGeometryIntersectFilterFunction(geom, alpha_filter);
            rtcSetGeometryOccludedFilterFunction(geom, alpha_filter);
        }
        rtcCommitGeometry(geom);
        rtcAttachGeometry(scene, geom);
        rtcReleaseGeometry(geom);
        rtcCommitScene(scene);
        if (!last_error.empty()) throw RuntimeFailure(origin + ": " + last_error);
    }

    hit_info_.resize(mesh_.size());
    // Flat triangles' frames, when the table stays small enough to be cached:
    // a hit then reads its frame instead of computing it (a square root and
    // two divisions on the way from the hit to the next ray). Big scenes keep
    // computing it: there a table read would often miss the cache.
    constexpr size_t kFrameTableBytes = size_t(1) << 20;
    if (mesh_.size() * sizeof(Frame) <= kFrameTableBytes) flat_frames_.resize(mesh_.size());
    for (size_t t = 0; t < mesh_.size(); ++t) {
        if (mesh_.material_ids[t] > kMaterialMask) throw InputError(origin + ": too many materials");
        classify_triangle(t);
    }
    build_lights();
}

void Scene::compute_bounds() {
    Vec3 lo(kInf), hi(-kInf);
    for (const auto& p : mesh_.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    radius_ = std::max(1e-3f, 0.5f * glm::length(hi - lo));
    center_ = 0.5f * (lo + hi);
}

void Scene::classify_triangle(size_t t) {
    const Vec3* p = &mesh_.positions[3 * t];
    const Vec3 ng = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
    uint32_t info = mesh_.material_ids[t];
    if (info < materials_.size() && (materials_[info].bump || materials_[info].normal_map)) info |= kPerturbed;
    for (int k = 0; k < 3; ++k) {
        if (!mesh_.normals.empty()) {
            // Flat faces (vertex normals equal to the face normal) skip interpolation.
            const Vec3& n = mesh_.normals[3 * t + k];
            if (std::abs(n.x - ng.x) + std::abs(n.y - ng.y) + std::abs(n.z - ng.z) > 1e-6f) info |= kSmooth;
        }
        if (!mesh_.uvs.empty() && (mesh_.uvs[3 * t + k].x != 0.f || mesh_.uvs[3 * t + k].y != 0.f)) info |= kHasUv;
    }
    hit_info_[t] = info;
    if (!flat_frames_.empty()) flat_frames_[t] = Frame(ng);
}

void Scene::set_material(size_t index, std::shared_ptr<Bsdf> bsdf, const Color& emission) {
    if (index >= materials_.size())
        throw ParameterError(fmt::format("set_material: no material {} (the scene has {})", index, materials_.size()));
    if (!bsdf) throw ParameterError("set_material: material '" + materials_[index].name + "' needs a BSDF");
    for (int c = 0; c < 3; ++c)
        if (!(emission[c] >= 0.f) || !std::isfinite(emission[c]))
            throw ParameterError("set_material: material '" + materials_[index].name +
                                 "': emitted radiance must be finite and not negative");
    Material& m = materials_[index];
    m.bsdf = std::move(bsdf);
    cache_bsdf_flags(m);
    const bool relight = m.emission != emission;
    m.emission = emission;
    if (relight) build_lights();
}

size_t Scene::object_triangles(uint32_t object_id) const {
    if (mesh_.object_ids.empty()) return object_id == 0 ? mesh_.size() : 0;
    return size_t(std::count(mesh_.object_ids.begin(), mesh_.object_ids.end(), object_id));
}

void Scene::set_object_geometry(uint32_t object_id, const std::vector<Vec3>& positions, const std::vector<Vec3>& normals) {
    const std::string what = fmt::format("set_object_geometry: object {}", object_id);
    if (shared_) throw ParameterError(what + ": the scene is built on shared geometry (an animation frame)");
    const size_t n = object_triangles(object_id);
    if (n == 0) throw ParameterError(what + ": the scene has no such object");
    if (positions.size() != 3 * n)
        throw ParameterError(fmt::format("{}: {} positions given for its {} triangles (3 each)", what, positions.size(), n));
    if (normals.size() != (mesh_.normals.empty() ? 0 : positions.size()))
        throw ParameterError(fmt::format("{}: {} normals given; the scene needs {}", what, normals.size(),
                                         mesh_.normals.empty() ? 0 : positions.size()));
    // Checked before anything changes, so a refused edit leaves the scene as it was.
    for (size_t i = 0; i < n; ++i) {
        const Vec3* p = &positions[3 * i];
        for (int k = 0; k < 3; ++k)
            if (!within_coordinate_range(p[k]))
                throw ParameterError(fmt::format("{}: triangle {} has a vertex at ({}, {}, {}), not finite or beyond "
                                                 "+-{:g} on an axis", what, i, p[k].x, p[k].y, p[k].z, kMaxCoordinate));
        if (zero_area_triangle(p[0], p[1], p[2]))
            throw ParameterError(fmt::format("{}: triangle {} would have zero area", what, i));
    }
    RTCGeometry geom = rtcGetGeometry(static_cast<RTCScene>(rtc_scene_), 0);
    auto* verts = static_cast<float*>(rtcGetGeometryBufferData(geom, RTC_BUFFER_TYPE_VERTEX, 0));
    if (!verts) throw RuntimeFailure(what + ": the Embree vertex buffer is not accessible");
    size_t i = 0;
    for (size_t t = 0; t < mesh_.size(); ++t) {
        if (this->object_id(uint32_t(t)) != object_id) continue;
        const Vec3* p = &positions[3 * i];
        const Vec3 c = glm::cross(p[1] - p[0], p[2] - p[0]);
        const float len = glm::length(c);
        for (int k = 0; k < 3; ++k) {
            const size_t v = 3 * t + k;
            mesh_.positions[v] = p[k];
            verts[3 * v + 0] = p[k].x, verts[3 * v + 1] = p[k].y, verts[3 * v + 2] = p[k].z;
            if (!normals.empty()) mesh_.normals[v] = vertex_normal(normals[3 * i + k], c, len);
        }
        classify_triangle(t);
        ++i;
    }
    rtcUpdateGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(geom);
    rtcCommitScene(static_cast<RTCScene>(rtc_scene_));
    // The device's error callback writes to a string of the thread that built the scene; ask the device itself.
    if (const RTCError e = rtcGetDeviceError(static_cast<RTCDevice>(rtc_device_)); e != RTC_ERROR_NONE)
        throw RuntimeFailure(fmt::format("{}: Embree error {} while rebuilding the BVH", what, int(e)));
    compute_bounds();
    build_lights();  // emitter corners, areas and the power distribution; the environment's share depends on the bounds
}

void Scene::build_on_shared(std::shared_ptr<SharedGeometry> shared, const std::string& origin) {
    if (std::any_of(materials_.begin(), materials_.end(), [](const Material& m) { return m.opacity != nullptr; }))
        throw ParameterError(origin + ": alpha cut-outs need a scene of its own, not shared geometry");
    if (shared->triangles_ > mesh_.size())
        throw ParameterError(origin + ": the shared geometry has more triangles than the scene");
    // Embree calls on one device from several threads would share its error string.
    std::lock_guard<std::mutex> lock(shared->mutex_);
    shared->last_error_.clear();
    RTCDevice dev = static_cast<RTCDevice>(shared->device_);
    rtcRetainDevice(dev);
    rtc_device_ = dev;
    packets4_ = rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) != 0;
    packets8_ = rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) != 0;
    RTCScene scene = rtcNewScene(dev);
    rtc_scene_ = scene;
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    // The shared triangles, in place (an identity instance: its hits' normals
    // are in world space), then the rest as a geometry of this scene's own.
    RTCGeometry inst = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(inst, static_cast<RTCScene>(shared->scene_));
    const float identity[12] = {1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f};
    rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, identity);
    rtcCommitGeometry(inst);
    rtcAttachGeometry(scene, inst);
    rtcReleaseGeometry(inst);
    const size_t base = shared->triangles_;
    if (mesh_.size() > base) {
        RTCGeometry geom = triangle_geometry(dev, mesh_, base, mesh_.size() - base, shared->last_error_, origin);
        rtcCommitGeometry(geom);
        rtcAttachGeometry(scene, geom);
        rtcReleaseGeometry(geom);
    }
    rtcCommitScene(scene);
    if (!shared->last_error_.empty()) throw RuntimeFailure(origin + ": " + shared->last_error_);
    unshared_base_ = uint32_t(base);
    shared_ = std::move(shared);
}

Scene::~Scene() {
    if (rtc_scene_) rtcReleaseScene(static_cast<RTCScene>(rtc_scene_));
    if (rtc_device_) rtcReleaseDevice(static_cast<RTCDevice>(rtc_device_));
}

void Scene::build_lights() {
    // Selection by power then uniform by area gives pdf_a = luminance(Le) / total
    // power: one value per material, so an emitter hit finds its pdf in a
    // small table instead of a per-triangle array (a cache miss in big scenes).
    light_pdf_by_material_.assign(materials_.size(), 0.f);
    std::vector<Emitter> emitters;
    std::vector<double> power;
    double total = 0.0;
    for (uint32_t t = 0; t < mesh_.size(); ++t) {
        const uint32_t mid = mesh_.material_ids[t];
        const Material& mat = materials_[mid];
        if (is_black(mat.emission)) continue;
        const Vec3* p = &mesh_.positions[3 * t];
        const Vec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
        const double area = 0.5 * glm::length(glm::cross(e1, e2));
        const double pw = double(luminance(mat.emission)) * area;
        if (!(pw > 0.0)) continue;
        emitters.push_back(Emitter{p[0], e1, e2, glm::normalize(glm::cross(e1, e2)), mid, t});
        power.push_back(pw);
        total += pw;
    }
    stats_.emitters = emitters.size();
    // The environment's share of the power (environment_selection()); the
    // triangles share the rest, so their densities are scaled by it.
    // And the delta lights' share, each by its own power.
    env_select_ = 0.f;
    delta_select_ = 0.f;
    const double env_power = env_ ? double(radius_) * double(radius_) * env_->luminance_integral() : 0.0;
    double delta_power = 0.0;
    std::vector<double> delta_powers;
    for (const DeltaLight& l : delta_lights_) {
        delta_powers.push_back(std::max(0.0, l.power(radius_)));
        delta_power += delta_powers.back();
    }
    const double all = total + std::max(0.0, env_power) + delta_power;
    if (all > 0.0) {
        if (env_power > 0.0) env_select_ = float(env_power / all);
        if (delta_power > 0.0) delta_select_ = float(delta_power / all);
        if (total == 0.0) {
            // No triangle takes the rest: rounding must not leave a gap.
            if (delta_power > 0.0) delta_select_ = 1.f - env_select_;
            else env_select_ = 1.f;
        }
    } else if (env_) {
        env_select_ = 1.f;  // as before: an environment of no power still is the only light
        if (!(env_power > 0.0)) env_select_ = 0.f;
    }
    delta_pick_.assign(delta_lights_.size(), 0.f);
    delta_cdf_.assign(delta_lights_.size() + 1, 0.f);
    for (size_t i = 0; i < delta_lights_.size(); ++i) {
        const double share = delta_power > 0.0 ? delta_powers[i] / delta_power : 0.0;
        delta_pick_[i] = float(double(delta_select_) * share);
        delta_cdf_[i + 1] = delta_cdf_[i] + float(share);
    }
    if (!delta_lights_.empty()) delta_cdf_.back() = 1.f;
    const double tri_share = 1.0 - double(env_select_) - double(delta_select_);
    // Half of a typical 32 KiB first-level data cache: beyond it, a bucket
    // picked at random is often not cached when its light sample is drawn.
    constexpr size_t kCachedLightBytes = size_t(16) << 10;
    light_prefetch_pays_ = emitters.size() * sizeof(LightBucket) > kCachedLightBytes;
    buckets_.clear();
    if (emitters.empty()) return;
    for (const Emitter& e : emitters)
        light_pdf_by_material_[e.material] = float(tri_share * double(luminance(materials_[e.material].emission)) / total);
    // Walker/Vose alias table: bucket i holds emitter i with probability keep
    // and its alias otherwise; every bucket is drawn with probability 1/n.
    const size_t n = emitters.size();
    buckets_.resize(n);
    std::vector<double> scaled(n);
    std::vector<uint32_t> small, large;
    for (size_t i = 0; i < n; ++i) {
        scaled[i] = power[i] / total * double(n);
        buckets_[i].e[0] = buckets_[i].e[1] = emitters[i];  // keep 1: its own emitter either way
        (scaled[i] < 1.0 ? small : large).push_back(uint32_t(i));
    }
    while (!small.empty() && !large.empty()) {
        const uint32_t s = small.back(), l = large.back();
        small.pop_back();
        buckets_[s].e[0].keep = float(scaled[s]), buckets_[s].e[1] = emitters[l];
        scaled[l] -= 1.0 - scaled[s];
        if (scaled[l] < 1.0) large.pop_back(), small.push_back(l);
    }
    // Whatever is left holds 1 up to rounding and keeps its own emitter.
}

bool Scene::intersect(const Ray& ray, SurfaceInteraction& si) const {
    if (observer_) [[unlikely]]
        observer_->on_intersect(ray);
    RTCRayHit rh;
    rh.ray.org_x = ray.o.x, rh.ray.org_y = ray.o.y, rh.ray.org_z = ray.o.z;
    rh.ray.dir_x = ray.d.x, rh.ray.dir_y = ray.d.y, rh.ray.dir_z = ray.d.z;
    rh.ray.tnear = ray.tmin, rh.ray.tfar = ray.tmax;
    rh.ray.time = 0.f, rh.ray.mask = 0xffffffffu, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(static_cast<RTCScene>(rtc_scene_), &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;

    fill_hit(ray, global_prim(rh.hit.primID, rh.hit.instID[0]), rh.hit.u, rh.hit.v,
             Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z), rh.ray.tfar, si);
    return true;
}

namespace {
// visible()'s segments are o + t v for t in [0, kSegmentEnd): shortened by a
// relative 1e-4 so that the far end's surface is not hit.
constexpr float kSegmentEnd = 1.f - 1e-4f;

// Lanes b..b+3 of a packet's fields that every gdr query sets alike (no
// motion blur, all geometry masks, no ids or flags).
template <class RayN>
inline void store_fixed_fields(RayN& r, int b) {
#ifdef GDR_SIMD
    _mm_store_ps(r.time + b, _mm_setzero_ps());
    _mm_store_si128(reinterpret_cast<__m128i*>(r.mask + b), _mm_set1_epi32(-1));
    _mm_store_si128(reinterpret_cast<__m128i*>(r.id + b), _mm_setzero_si128());
    _mm_store_si128(reinterpret_cast<__m128i*>(r.flags + b), _mm_setzero_si128());
#else
    for (int i = b; i < b + 4; ++i) r.time[i] = 0.f, r.mask[i] = ~0u, r.id[i] = 0, r.flags[i] = 0;
#endif
}

}  // namespace

// One Embree packet of N rays (RTCRayHitN of width N) with the coherent hint,
// written into the callers' hit records.
template <int N, class RayHitN, class IntersectN>
void Scene::intersect_packet(const Ray* rays, const bool* active, SurfaceInteraction* const* si, bool* hit,
                             IntersectN intersect_n) const {
    static_assert(sizeof(Ray) == 8 * sizeof(float), "Ray is loaded as two rows of four floats");
    alignas(32) RayHitN rh;
    alignas(32) int valid[N];
    if (observer_) [[unlikely]]
        for (int i = 0; i < N; ++i)
            if (active[i]) observer_->on_intersect(rays[i]);
    // Rays are (o.x o.y o.z d.x | d.y d.z tmin tmax): two 4x4 transposes per
    // 4 lanes give Embree's structure-of-arrays packet. Lane by lane, this
    // setup cost more than Embree's own traversal of the packet.
    const float* src = &rays[0].o.x;
    for (int b = 0; b < N; b += 4) {
#ifdef GDR_SIMD
        __m128 a0 = _mm_loadu_ps(src + 8 * (b + 0)), a1 = _mm_loadu_ps(src + 8 * (b + 1));
        __m128 a2 = _mm_loadu_ps(src + 8 * (b + 2)), a3 = _mm_loadu_ps(src + 8 * (b + 3));
        _MM_TRANSPOSE4_PS(a0, a1, a2, a3);
        _mm_store_ps(rh.ray.org_x + b, a0), _mm_store_ps(rh.ray.org_y + b, a1);
        _mm_store_ps(rh.ray.org_z + b, a2), _mm_store_ps(rh.ray.dir_x + b, a3);
        __m128 c0 = _mm_loadu_ps(src + 8 * (b + 0) + 4), c1 = _mm_loadu_ps(src + 8 * (b + 1) + 4);
        __m128 c2 = _mm_loadu_ps(src + 8 * (b + 2) + 4), c3 = _mm_loadu_ps(src + 8 * (b + 3) + 4);
        _MM_TRANSPOSE4_PS(c0, c1, c2, c3);
        _mm_store_ps(rh.ray.dir_y + b, c0), _mm_store_ps(rh.ray.dir_z + b, c1);
        _mm_store_ps(rh.ray.tnear + b, c2), _mm_store_ps(rh.ray.tfar + b, c3);
        store_fixed_fields(rh.ray, b);
        const __m128i ones = _mm_set1_epi32(-1);
        _mm_store_si128(reinterpret_cast<__m128i*>(rh.hit.geomID + b), ones);  // RTC_INVALID_GEOMETRY_ID
        _mm_store_si128(reinterpret_cast<__m128i*>(rh.hit.primID + b), ones);
        _mm_store_si128(reinterpret_cast<__m128i*>(rh.hit.instID[0] + b), ones);
#else
        for (int i = b; i < b + 4; ++i) {
            const float* row = src + 8 * i;  // o.x o.y o.z d.x d.y d.z tmin tmax
            rh.ray.org_x[i] = row[0], rh.ray.org_y[i] = row[1], rh.ray.org_z[i] = row[2];
            rh.ray.dir_x[i] = row[3], rh.ray.dir_y[i] = row[4], rh.ray.dir_z[i] = row[5];
            rh.ray.tnear[i] = row[6], rh.ray.tfar[i] = row[7];
            rh.hit.geomID[i] = rh.hit.primID[i] = rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
        }
        store_fixed_fields(rh.ray, b);
#endif
        for (int i = b; i < b + 4; ++i) valid[i] = active[i] ? -1 : 0;
    }
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    // Without the coherent hint Embree's packet kernel cost G-PT's four offset
    // primaries about as much as four single rays; with it about a third less.
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    intersect_n(valid, static_cast<RTCScene>(rtc_scene_), &ctx, &rh);
    for (int i = 0; i < N; ++i) {
        hit[i] = active[i] && rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
        if (!hit[i]) continue;
        const uint32_t prim = global_prim(rh.hit.primID[i], rh.hit.instID[0][i]);
        // Coherent rays often hit one triangle: a flat one's normal and frame
        // (a square root and two divisions) are then copied from an earlier lane.
        int same = -1;
        if (!(hit_info_[prim] & (kSmooth | kPerturbed)))
            for (int j = 0; j < i && same < 0; ++j)
                if (hit[j] && global_prim(rh.hit.primID[j], rh.hit.instID[0][j]) == prim) same = j;
        if (same >= 0)
            fill_hit_like(rays[i], rh.hit.u[i], rh.hit.v[i], rh.ray.tfar[i], *si[same], *si[i]);
        else
            fill_hit(rays[i], prim, rh.hit.u[i], rh.hit.v[i], Vec3(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]),
                     rh.ray.tfar[i], *si[i]);
    }
}

void Scene::intersect4(const Ray rays[4], const bool active[4], SurfaceInteraction* const si[4], bool hit[4]) const {
    if (!packets4_) {
        for (int i = 0; i < 4; ++i) hit[i] = active[i] && intersect(rays[i], *si[i]);
        return;
    }
    intersect_packet<4, RTCRayHit4>(rays, active, si, hit, rtcIntersect4);
}

void Scene::intersect8(const Ray rays[8], const bool active[8], SurfaceInteraction* const si[8], bool hit[8]) const {
    if (!packets8_) {
        intersect4(rays, active, si, hit);
        intersect4(rays + 4, active + 4, si + 4, hit + 4);
        return;
    }
    intersect_packet<8, RTCRayHit8>(rays, active, si, hit, rtcIntersect8);
}

void Scene::fill_hit_point(const Ray& ray, uint32_t t, float b1, float b2, float tfar,
                           SurfaceInteraction& si) const {
    const uint32_t info = hit_info_[t];
    // p from the ray, not from the corners: that would be a cache miss, and
    // its rounding (~1e-7 of the distance) is far below the 1e-4 relative
    // offset of spawned rays.
    si.t = tfar;
    si.p = ray.o + si.t * ray.d;
    si.prim = t;
    if (info & kHasUv) {
        const Vec2* uv = &mesh_.uvs[3 * t];
        si.uv = (1.f - b1 - b2) * uv[0] + b1 * uv[1] + b2 * uv[2];
    } else {
        si.uv = mesh_.uvs.empty() ? Vec2(b1, b2) : Vec2(0.f);
    }
    si.material = &materials_[info & kMaterialMask];
}

void Scene::fill_hit(const Ray& ray, uint32_t t, float b1, float b2, const Vec3& ng, float tfar,
                     SurfaceInteraction& si) const {
    fill_hit_point(ray, t, b1, b2, tfar, si);
    if (!flat_frames_.empty() && !(hit_info_[t] & (kSmooth | kPerturbed))) {
        si.frame = flat_frames_[t];
        si.ng = si.frame.n;
        return;
    }
    // Embree's Ng is cross(p1 - p0, p2 - p0), our winding.
    si.ng = glm::normalize(ng);
    Vec3 ns = si.ng;
    if (hit_info_[t] & kSmooth) {
        const Vec3* n = &mesh_.normals[3 * t];
        const Vec3 v = (1.f - b1 - b2) * n[0] + b1 * n[1] + b2 * n[2];
        const float l = glm::length(v);
        if (l > 0.f) ns = v / l;
        // Shading normals on the other side of the face than ng would let light leak.
        if (glm::dot(ns, si.ng) < 0.f) ns = -ns;
    }
    if (hit_info_[t] & kPerturbed) {
        // The derivatives of the uv map fill_hit_point() used: the corners'
        // uvs, or the barycentrics where the mesh has none.
        const Vec3* p = &mesh_.positions[3 * t];
        Vec2 uv[3] = {Vec2(0.f), Vec2(1.f, 0.f), Vec2(0.f, 1.f)};
        if (hit_info_[t] & kHasUv) for (int k = 0; k < 3; ++k) uv[k] = mesh_.uvs[3 * t + k];
        else if (!mesh_.uvs.empty()) uv[1] = uv[2] = Vec2(0.f);  // all-zero uvs: no gradient
        Vec3 dpdu, dpdv;
        if (triangle_uv_derivatives(p, uv, dpdu, dpdv)) {
            ns = perturbed_normal(*si.material, ns, dpdu, dpdv, si.uv);
            // As for interpolated normals: a perturbed normal behind the face
            // would let light leak, so it is mirrored to ng's side.
            if (glm::dot(ns, si.ng) < 0.f) ns = -ns;
        }
    }
    si.frame = Frame(ns);
}

bool triangle_uv_derivatives(const Vec3 p[3], const Vec2 uv[3], Vec3& dpdu, Vec3& dpdv) {
    const Vec3 dp1 = p[1] - p[0], dp2 = p[2] - p[0];
    const Vec2 d1 = uv[1] - uv[0], d2 = uv[2] - uv[0];
    const float det = d1.x * d2.y - d1.y * d2.x;
    dpdu = dpdv = Vec3(0.f);
    if (!(std::abs(det) > 0.f) || !std::isfinite(det)) return false;
    const float inv = 1.f / det;
    dpdu = (d2.y * dp1 - d1.y * dp2) * inv;
    dpdv = (d1.x * dp2 - d2.x * dp1) * inv;
    if (is_finite(dpdu) && is_finite(dpdv)) return true;
    dpdu = dpdv = Vec3(0.f);
    return false;
}

Vec3 perturbed_normal(const Material& m, const Vec3& n, const Vec3& dpdu, const Vec3& dpdv, const Vec2& uv) {
    if (!m.bump && !m.normal_map) return n;
    // The uv derivatives projected onto the tangent plane of n, so that the
    // perturbation tilts n itself (an interpolated normal included).
    const Vec3 tu = dpdu - n * glm::dot(n, dpdu), tv = dpdv - n * glm::dot(n, dpdv);
    const float c = glm::dot(glm::cross(tu, tv), n);  // signed uv-to-area scale (negative for mirrored uv)
    if (!(std::abs(c) > 0.f) || !std::isfinite(c)) return n;
    if (m.bump) {
        // The displaced surface p + h n has tangents tu + h_u n and tv + h_v n
        // (the derivative of n itself neglected, as Blinn does); their cross
        // product is c n + h_v (tu x n) + h_u (n x tv), here divided by c so
        // that it points to n's side whichever way uv runs.
        const float h = kBumpStep;
        const float hu = (luminance(m.bump->eval(uv + Vec2(h, 0.f))) - luminance(m.bump->eval(uv - Vec2(h, 0.f)))) / (2.f * h);
        const float hv = (luminance(m.bump->eval(uv + Vec2(0.f, h))) - luminance(m.bump->eval(uv - Vec2(0.f, h)))) / (2.f * h);
        if (hu == 0.f && hv == 0.f) return n;
        const Vec3 g = n + (hv * glm::cross(tu, n) + hu * glm::cross(n, tv)) / c;
        const float l = glm::length(g);
        return l > 0.f && std::isfinite(l) ? g / l : n;
    }
    const Color rgb = m.normal_map->eval(uv);
    const Vec3 local = 2.f * Vec3(rgb.r, rgb.g, rgb.b) - 1.f;
    const Vec3 s = glm::normalize(tu);
    const Vec3 t = (c > 0.f ? 1.f : -1.f) * glm::cross(n, s);  // on dp/dv's side of the plane
    const Vec3 g = local.x * s + local.y * t + local.z * n;
    const float l = glm::length(g);
    return l > 0.f && std::isfinite(l) ? g / l : n;
}

void Scene::fill_hit_like(const Ray& ray, float b1, float b2, float tfar, const SurfaceInteraction& like,
                          SurfaceInteraction& si) const {
    fill_hit_point(ray, like.prim, b1, b2, tfar, si);
    // What fill_hit() computes from the triangle alone is taken from `like`.
    si.ng = like.ng;
    si.frame = like.frame;
}

namespace {
// One shadow query; an inline helper so that visible() builds the RTCRay
// directly instead of through a Ray and a call.
inline bool occluded_rtc(void* scene, const Vec3& o, const Vec3& d, float tmin, float tmax) {
    RTCRay r;
    r.org_x = o.x, r.org_y = o.y, r.org_z = o.z;
    r.dir_x = d.x, r.dir_y = d.y, r.dir_z = d.z;
    r.tnear = tmin, r.tfar = tmax;
    r.time = 0.f, r.mask = 0xffffffffu, r.id = 0, r.flags = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(static_cast<RTCScene>(scene), &ctx, &r);
    return r.tfar < 0.f;
}
}  // namespace

bool Scene::occluded(const Ray& ray) const {
    if (observer_) [[unlikely]]
        observer_->on_occluded(ray);
    return occluded_rtc(rtc_scene_, ray.o, ray.d, ray.tmin, ray.tmax);
}

bool Scene::visible(const Vec3& p0, const Vec3& n0, const Vec3& p1, const Vec3& n1) const {
    const Vec3 d = p1 - p0;
    const Vec3 o = offset_ray_origin(p0, n0, d);
    return segment_clear(o, offset_ray_origin(p1, n1, -d) - o);
}

bool Scene::segment_clear(const Vec3& o, const Vec3& v) const {
    if (!(glm::dot(v, v) > 0.f)) return true;
    // Embree needs no unit direction (see kSegmentEnd): a shadow ray thus
    // costs no square root and no division; G-PT casts about eight per sample.
    if (observer_) [[unlikely]]
        observer_->on_occluded(Ray{o, v, 0.f, kSegmentEnd});
    return !occluded_rtc(rtc_scene_, o, v, 0.f, kSegmentEnd);
}

#ifdef GDR_SIMD
namespace {
// The four-lane form of offset_ray_origin(p, ng, dir) with dot(ng, dir) = dn,
// in the same operations and order (so the same bits).
inline void offset_origin4(const __m128 p[3], const __m128 n[3], __m128 dn, __m128 o[3]) {
    const __m128 sign = _mm_set1_ps(-0.f);
    const __m128 ax = _mm_andnot_ps(sign, p[0]), ay = _mm_andnot_ps(sign, p[1]), az = _mm_andnot_ps(sign, p[2]);
    const __m128 scale =
        _mm_mul_ps(_mm_set1_ps(1e-4f), _mm_max_ps(_mm_set1_ps(1.f), _mm_max_ps(ax, _mm_max_ps(ay, az))));
    // scale where dn >= 0, else -scale (also for NaN, like the scalar compare).
    const __m128 s = _mm_xor_ps(scale, _mm_andnot_ps(_mm_cmpge_ps(dn, _mm_setzero_ps()), sign));
    for (int c = 0; c < 3; ++c) o[c] = _mm_add_ps(p[c], _mm_mul_ps(s, n[c]));
}

// (a.x b.x + a.y b.y) + a.z b.z, as glm::dot adds.
inline __m128 dot4(const __m128 a[3], const __m128 b[3]) {
    return _mm_add_ps(_mm_add_ps(_mm_mul_ps(a[0], b[0]), _mm_mul_ps(a[1], b[1])), _mm_mul_ps(a[2], b[2]));
}

}  // namespace
#endif

// visible8() as a packet of N = 4 or 8 lanes (RTCRayN).
template <int N, class RayN, class OccludedN>
void Scene::visible_packet(const VisibilityBatch& q, bool* out, OccludedN occluded_n) const {
    // visible()'s segments, four lanes at a time. Lane by lane (scalar loads
    // and stores), the packet's setup cost about what Embree saves by
    // tracing it as one.
    const int n = q.n;
    alignas(32) RayN r;
    alignas(32) int valid[N];
#ifdef GDR_SIMD
    for (int b = 0; b < N; b += 4) {
        const __m128 used = _mm_castsi128_ps(_mm_cmplt_epi32(_mm_setr_epi32(b, b + 1, b + 2, b + 3), _mm_set1_epi32(n)));
        // Unused lanes are zeroed: uninitialised, they could hold denormals, which are slow.
        __m128 p0[3], n0[3], p1[3], n1[3];
        for (int c = 0; c < 3; ++c) {
            p0[c] = _mm_and_ps(used, _mm_load_ps(q.p0[c] + b)), n0[c] = _mm_and_ps(used, _mm_load_ps(q.n0[c] + b));
            p1[c] = _mm_and_ps(used, _mm_load_ps(q.p1[c] + b)), n1[c] = _mm_and_ps(used, _mm_load_ps(q.n1[c] + b));
        }
        __m128 d[3], o[3], e[3], v[3];
        for (int c = 0; c < 3; ++c) d[c] = _mm_sub_ps(p1[c], p0[c]);
        offset_origin4(p0, n0, dot4(n0, d), o);
        // dot(n1, -d) is -dot(n1, d) exactly.
        offset_origin4(p1, n1, _mm_xor_ps(dot4(n1, d), _mm_set1_ps(-0.f)), e);
        for (int c = 0; c < 3; ++c) v[c] = _mm_sub_ps(e[c], o[c]);
        // Degenerate segments (and unused lanes) are not traced: visible, as in visible().
        const __m128 live = _mm_cmpgt_ps(dot4(v, v), _mm_setzero_ps());
        _mm_store_si128(reinterpret_cast<__m128i*>(valid + b), _mm_castps_si128(_mm_and_ps(live, used)));
        _mm_store_ps(r.org_x + b, o[0]), _mm_store_ps(r.org_y + b, o[1]), _mm_store_ps(r.org_z + b, o[2]);
        _mm_store_ps(r.dir_x + b, v[0]), _mm_store_ps(r.dir_y + b, v[1]), _mm_store_ps(r.dir_z + b, v[2]);
        _mm_store_ps(r.tnear + b, _mm_setzero_ps()), _mm_store_ps(r.tfar + b, _mm_set1_ps(kSegmentEnd));
        store_fixed_fields(r, b);
    }
#else
    // The same operations lane by lane: offset_ray_origin() is what the
    // vector code repeats, so the bits are the same.
    for (int i = 0; i < N; ++i) {
        const bool used = i < n;  // unused lanes are zeroed, as above
        const auto lane = [&](const float (&a)[3][VisibilityBatch::kLanes]) {
            return used ? Vec3(a[0][i], a[1][i], a[2][i]) : Vec3(0.f);
        };
        const Vec3 p0 = lane(q.p0), n0 = lane(q.n0), p1 = lane(q.p1), n1 = lane(q.n1);
        const Vec3 d = p1 - p0;
        const Vec3 o = offset_ray_origin(p0, n0, d), v = offset_ray_origin(p1, n1, -d) - o;
        valid[i] = used && glm::dot(v, v) > 0.f ? -1 : 0;
        r.org_x[i] = o.x, r.org_y[i] = o.y, r.org_z[i] = o.z;
        r.dir_x[i] = v.x, r.dir_y[i] = v.y, r.dir_z[i] = v.z;
        r.tnear[i] = 0.f, r.tfar[i] = kSegmentEnd;
    }
    for (int b = 0; b < N; b += 4) store_fixed_fields(r, b);
#endif
    if (observer_) [[unlikely]]
        for (int i = 0; i < n; ++i)
            if (valid[i])
                observer_->on_occluded(Ray{Vec3(r.org_x[i], r.org_y[i], r.org_z[i]),
                                           Vec3(r.dir_x[i], r.dir_y[i], r.dir_z[i]), 0.f, kSegmentEnd});
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    // No coherent hint: for shadow packets it made Embree's kernel slower.
    occluded_n(valid, static_cast<RTCScene>(rtc_scene_), &ctx, &r);
    for (int i = 0; i < n; ++i) out[i] = !(r.tfar[i] < 0.f);
}

void Scene::visible8(const VisibilityBatch& q, bool out[8]) const {
    if (q.n <= 1 || !packets4_ || (q.n > 4 && !packets8_)) {
        for (int i = 0; i < q.n; ++i)
            out[i] = visible(Vec3(q.p0[0][i], q.p0[1][i], q.p0[2][i]), Vec3(q.n0[0][i], q.n0[1][i], q.n0[2][i]),
                             Vec3(q.p1[0][i], q.p1[1][i], q.p1[2][i]), Vec3(q.n1[0][i], q.n1[1][i], q.n1[2][i]));
    } else if (q.n <= 4) {
        visible_packet<4, RTCRay4>(q, out, rtcOccluded4);
    } else {
        visible_packet<8, RTCRay8>(q, out, rtcOccluded8);
    }
}

void Scene::set_environment(std::shared_ptr<const Environment> env) {
    env_ = std::move(env);
    build_lights();
}

void check_delta_lights(std::vector<DeltaLight>& lights, const std::string& origin) {
    for (size_t i = 0; i < lights.size(); ++i) {
        DeltaLight& l = lights[i];
        const std::string what = origin + ": light " + std::to_string(i) + ": ";
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(l.intensity[c]) || l.intensity[c] < 0.f)
                throw InputError(what + "intensity must be finite and not negative");
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(l.position[c]) || !std::isfinite(l.direction[c]))
                throw InputError(what + "position and direction must be finite");
        if (l.kind != DeltaLight::Kind::Point) {
            const float len = glm::length(l.direction);
            if (!(len > 0.f) || !std::isfinite(len)) throw InputError(what + "direction must not be zero");
            l.direction /= len;
        }
        if (l.kind == DeltaLight::Kind::Spot &&
            !(l.beam_width > 0.f && l.beam_width <= l.cutoff && l.cutoff <= kPi))
            throw InputError(what + "a spot needs 0 < beam width <= cutoff angle <= 180 degrees");
        if (l.kind == DeltaLight::Kind::Spot && l.texture) {
            // A projected image needs a cone narrower than a hemisphere, and an
            // orthonormal frame about the axis (x and y keep their handedness).
            if (!(l.cutoff < 0.5f * kPi)) throw InputError(what + "a spot with a projected texture needs a cutoff below 90 degrees");
            const Vec3 x = l.axis_x - glm::dot(l.axis_x, l.direction) * l.direction;
            if (!(glm::length(x) > 1e-6f) || !is_finite(x)) throw InputError(what + "the spot's x axis is along its direction");
            l.axis_x = glm::normalize(x);
            const Vec3 y = glm::cross(l.direction, l.axis_x);
            l.axis_y = glm::dot(y, l.axis_y) >= 0.f ? y : -y;
        }
    }
}

void Scene::set_delta_lights(std::vector<DeltaLight> lights, const std::string& origin) {
    check_delta_lights(lights, origin);
    delta_lights_ = std::move(lights);
    build_lights();
}

LightSample Scene::sample_environment(const Vec3& ref, const Vec2& u) const {
    LightSample ls;
    const EnvironmentSample es = env_->sample(u);
    if (!(es.pdf_w > 0.f)) return ls;
    ls.infinite = true;
    ls.n = -es.wi;
    ls.radiance = es.radiance;
    ls.pdf_w = env_select_ * es.pdf_w;
    // Beyond the bounding sphere whatever the reference point (a camera may be outside it).
    ls.p = beyond_scene(ref, es.wi);
    return ls;
}

// The triangle both samplers pick with u_sel (past the environment's share).
inline LightSample Scene::sample_triangle(float u_sel, const Vec2& u) const {
    LightSample ls;
    if (buckets_.empty()) return ls;
    // One number picks the bucket and, by its fraction, emitter or alias.
    const Emitter& e = light_select(u_sel);
    // Uniform point on the triangle (square-root parameterisation): barycentrics
    // (1 - sqrt(u.x), u.y sqrt(u.x), the rest) of the corners p0, p1, p2.
    const float su = std::sqrt(u.x);
    const float b1 = u.y * su, b2 = su - b1;
    ls.p = e.p0 + b1 * e.e1 + b2 * e.e2;
    ls.n = e.n;
    ls.prim = e.prim;
    ls.pdf_a = light_pdf_by_material_[e.material];
    ls.radiance = materials_[e.material].emission;
    return ls;
}

LightSample Scene::sample_delta(const Vec3* ref, float u_sel) const {
    LightSample ls;
    const size_t n = delta_lights_.size();
    size_t i = size_t(std::upper_bound(delta_cdf_.begin() + 1, delta_cdf_.end(), u_sel) - (delta_cdf_.begin() + 1));
    i = std::min(i, n - 1);
    while (i > 0 && !(delta_pick_[i] > 0.f)) --i;  // a light of no power is never picked
    const DeltaLight& l = delta_lights_[i];
    if (!(delta_pick_[i] > 0.f)) return ls;
    ls.delta = true;
    ls.delta_light = &l;
    if (l.kind == DeltaLight::Kind::Directional) {
        ls.infinite = true;
        ls.n = l.direction;
        ls.radiance = l.intensity;
        ls.pdf_w = delta_pick_[i];
        ls.p = beyond_scene(ref ? *ref : center_, -l.direction);
        return ls;
    }
    ls.p = l.position;
    ls.pdf_a = delta_pick_[i];
    if (!ref) {
        ls.n = l.direction;
        ls.radiance = l.intensity;
        return ls;
    }
    const Vec3 d = *ref - l.position;
    const float dist = glm::length(d);
    if (!(dist > 0.f)) return LightSample{};
    ls.n = d / dist;
    ls.radiance = l.intensity_towards(ls.n);
    return ls;
}

LightSample Scene::sample_with_environment(const Vec3* ref, float u_sel, const Vec2& u) const {
    if (u_sel < env_select_) return sample_environment(ref ? *ref : center_, u);
    if (u_sel < env_select_ + delta_select_) return sample_delta(ref, (u_sel - env_select_) / delta_select_);
    const float rest = 1.f - env_select_ - delta_select_;
    if (!(rest > 0.f)) return LightSample{};
    LightSample ls = sample_triangle((u_sel - env_select_ - delta_select_) / rest, u);
    if (ref && !(glm::dot(ls.n, *ref - ls.p) > 0.f)) ls.radiance = Color(0.f);
    return ls;
}

// Scenes without an environment take one predictable branch, and the
// triangle sampler stays inlined: out of line (a call and its result
// through memory) it cost the path tracer 8% on the Cornell box.
LightSample Scene::sample_emitter_point(float u_sel, const Vec2& u) const {
    if (env_ || !delta_lights_.empty()) [[unlikely]]
        return sample_with_environment(nullptr, u_sel, u);
    return sample_triangle(u_sel, u);
}

LightSample Scene::sample_light(const Vec3& ref, float u_sel, const Vec2& u) const {
    if (env_ || !delta_lights_.empty()) [[unlikely]]
        return sample_with_environment(&ref, u_sel, u);
    LightSample ls = sample_triangle(u_sel, u);
    if (!(glm::dot(ls.n, ref - ls.p) > 0.f)) ls.radiance = Color(0.f);
    return ls;
}

bool Scene::cut_out(uint32_t prim, float b1, float b2) const {
    if (prim >= hit_info_.size()) return false;
    const uint32_t info = hit_info_[prim];
    const Material& m = materials_[info & kMaterialMask];
    if (!m.opacity) return false;
    // The uv of fill_hit_point().
    Vec2 uv(0.f);
    if (info & kHasUv) {
        const Vec2* t = &mesh_.uvs[3 * prim];
        uv = (1.f - b1 - b2) * t[0] + b1 * t[1] + b2 * t[2];
    } else if (mesh_.uvs.empty()) {
        uv = Vec2(b1, b2);
    }
    const float opacity = luminance(m.opacity->eval(uv));
    if (opacity >= 1.f) return false;
    if (opacity <= 0.f) return true;
    // Stochastic pass-through with probability 1 - opacity, decided by a hash
    // of the hit point (triangle and barycentrics): the same ray meets the
    // same decision whenever it is traced (an intersection and an occlusion
    // query agree, a shift and its inverse see the same surface), and over
    // the many points of a pixel the surface transmits 1 - opacity on average.
    uint64_t h = (uint64_t(prim) << 32) ^ (uint64_t(std::bit_cast<uint32_t>(b1)) << 16) ^
                 uint64_t(std::bit_cast<uint32_t>(b2));
    // SplitMix64's finaliser (Steele, Lea and Flood, "Fast splittable
    // pseudorandom number generators", 2014): every input bit reaches every output bit.
    h += 0x9e3779b97f4a7c15ull;
    h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
    h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
    h ^= h >> 31;
    const float u = float(h >> 40) * 0x1p-24f;
    return u >= opacity;
}

float Scene::light_pdf_a(uint32_t prim) const {
    return prim < hit_info_.size() ? light_pdf_by_material_[hit_info_[prim] & kMaterialMask] : 0.f;
}

}  // namespace gdr
