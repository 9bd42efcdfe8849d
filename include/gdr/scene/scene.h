// The scene: triangle meshes in an Embree BVH, materials, area lights and a
// camera. Owns its Embree device and scene; Embree errors become exceptions.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "gdr/detail/prefetch.h"
#include "gdr/core/math.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/camera.h"
#include "gdr/scene/delta_light.h"
#include "gdr/scene/environment.h"
#include "gdr/scene/light_sample.h"
#include "gdr/path/host.h"

namespace gdr {

/// A material: its BSDF and the radiance it emits from its front side.
struct Material {
    std::string name;             ///< Name from the MTL file.
    std::shared_ptr<Bsdf> bsdf;   ///< Scattering (never null).
    Color emission{0.f};          ///< Emitted radiance, W/(m^2 sr), front side (CCW winding) only.
    /// Opacity (Mitsuba's mask): a ray passes through the surface with
    /// probability 1 - luminance(opacity(uv)), decided by a hash of the hit
    /// point, so the same ray always meets the same decision (shifts stay
    /// reversible) and an opacity of 0 or 1 is an exact cut-out; null for an
    /// opaque surface.
    std::shared_ptr<Texture> opacity = nullptr;
    /// Bump map (Mitsuba's bumpmap): a height field over uv, the luminance of
    /// the texture in scene units along the shading normal, that tilts the
    /// shading normal by its gradient (Blinn, "Simulation of wrinkled
    /// surfaces", 1978) without moving the surface; null for none.
    std::shared_ptr<Texture> bump = nullptr;
    /// Tangent-space normal map (Mitsuba's normalmap): rgb in [0, 1] encodes
    /// the shading normal 2 rgb - 1 in the frame of dp/du, dp/dv and the
    /// normal; null for none. A material has at most one of bump and normal_map.
    std::shared_ptr<Texture> normal_map = nullptr;
    /// bsdf->min_roughness() and bsdf->is_pure_delta(), filled in by the Scene:
    /// shift mappings classify every vertex they visit, and a field read is
    /// cheaper than a virtual call on that path.
    float min_roughness = 1.f;
    bool pure_delta = false;      ///< See min_roughness.
    bool wo_side_only = false;    ///< bsdf->wo_side_only(), likewise.
    bool black = false;           ///< bsdf->is_black(), likewise.
};

/// A triangle soup ready for the BVH: three corners per triangle.
struct TriangleMesh {
    std::vector<Vec3> positions;        ///< 3 per triangle, world space.
    std::vector<Vec3> normals;          ///< 3 per triangle, or empty (flat shading).
    std::vector<Vec2> uvs;              ///< 3 per triangle, or empty.
    std::vector<uint32_t> material_ids; ///< 1 per triangle, index into Scene materials.
    /// 1 per triangle, or empty (every triangle object 0): the scene-file
    /// mesh entry it came from, which temporal methods match across frames.
    std::vector<uint32_t> object_ids;
    /// Number of triangles.
    size_t size() const { return material_ids.size(); }
};

/// Everything known about a ray's hit point. Directions are unit vectors.
struct SurfaceInteraction {
    Vec3 p{0.f};          ///< Position (scene units).
    Vec3 ng{0.f, 0.f, 1.f};  ///< Geometric normal from the winding (front side = emitting side).
    Frame frame;          ///< Shading frame; frame.n is on the same side of the surface as ng.
    Vec2 uv{0.f};         ///< Texture coordinates.
    float t = kInf;       ///< Ray parameter of the hit (scene units for unit directions).
    uint32_t prim = 0;    ///< Triangle index.
    const Material* material = nullptr;  ///< Material at the hit.

    /// Emitted radiance towards unit direction w (zero from the back side).
    Color emitted(const Vec3& w) const {
        return glm::dot(ng, w) > 0.f ? material->emission : Color(0.f);
    }
    /// True if the surface emits light.
    bool is_emitter() const { return !is_black(material->emission); }
};

/// True if a triangle has no area a ray can hit (zero, or overflowing float):
/// the Scene drops such triangles, and loaders count them with this same test.
inline bool zero_area_triangle(const Vec3& p0, const Vec3& p1, const Vec3& p2) {
    const float len = glm::length(glm::cross(p1 - p0, p2 - p0));
    return !(len > 0.f) || !std::isfinite(len);
}

/// Checks delta lights as Scene::set_delta_lights() takes them and makes
/// their directions unit vectors: InputError naming `origin` and the light's
/// index on a non-finite or negative intensity, a non-finite position, a
/// zero direction or a spot whose angles are not 0 < beam_width <= cutoff <= pi.
void check_delta_lights(std::vector<DeltaLight>& lights, const std::string& origin);
/// Step (uv units) of the central differences that give a bump map's height
/// gradient: 2^-12, a texel of a 4096-wide image, small enough to resolve the
/// images scenes use and large enough that float uv near 1 (spacing 6e-8)
/// rounds the difference by under 1e-3 of itself.
inline constexpr float kBumpStep = 1.f / 4096.f;

/// The shading normal that material m's bump or normal map makes of unit
/// normal n at uv, where dpdu and dpdv (scene units per uv unit) are the
/// surface's derivatives: a deterministic function of the hit, so that every
/// integrator and shift mapping sees the same frame there. Returns n itself
/// (bit for bit) where the height gradient is zero, the uv map is degenerate
/// or the material has neither map. The result is on n's side of the
/// surface for a bump map; a normal map may give any unit vector.
Vec3 perturbed_normal(const Material& m, const Vec3& n, const Vec3& dpdu, const Vec3& dpdv, const Vec2& uv);

/// dp/du and dp/dv (scene units per uv unit) of the triangle with corners p
/// and texture coordinates uv; false (and both zero) if its uv map is
/// degenerate (zero or non-finite uv area).
bool triangle_uv_derivatives(const Vec3 p[3], const Vec2 uv[3], Vec3& dpdu, Vec3& dpdv);

/// Counters gathered while loading (reported by the CLI).
struct SceneStats {
    size_t triangles = 0;           ///< Triangles in the BVH.
    size_t degenerate_skipped = 0;  ///< Zero-area triangles dropped at load.
    size_t emitters = 0;            ///< Emitting triangles.
};

/// Sees every ray a Scene traces: instrumentation, e.g. a benchmark recording the
/// ray distribution of a render. Called concurrently from worker threads.
class RayObserver {
public:
    virtual ~RayObserver() = default;
    /// A closest-hit query (Scene::intersect), before it is traced.
    virtual void on_intersect(const Ray& ray) = 0;
    /// An any-hit (shadow) query (Scene::occluded, Scene::visible), before it is
    /// traced. Scene::visible's rays span their segment as t in [0, 1): their
    /// direction is not a unit vector.
    virtual void on_occluded(const Ray& ray) = 0;
};

/// Up to 8 segments for Scene::visible8(), kept in the structure-of-arrays
/// layout of Embree's packets: segment i joins surface points p0 and p1
/// (world space; coordinate c of p0 is p0[c][i]) whose geometric normals n0
/// and n1 offset its ends. Lanes from n on are ignored (and not initialised).
struct VisibilityBatch {
    static constexpr int kLanes = 8;
    alignas(16) float p0[3][kLanes], n0[3][kLanes], p1[3][kLanes], n1[3][kLanes];
    int n = 0;  ///< Segments in use.
    /// Appends the segment a -> b with normals na and nb; the batch must not be full.
    void add(const Vec3& a, const Vec3& na, const Vec3& b, const Vec3& nb) {
        for (int c = 0; c < 3; ++c) p0[c][n] = a[c], n0[c][n] = na[c], p1[c][n] = b[c], n1[c][n] = nb[c];
        ++n;
    }
};

/// A BVH over triangles that several Scenes share: the geometry that stays
/// put in every frame of an animation, built once. Each frame's Scene refers
/// to it through an Embree instance (an identity transform, so its hits need
/// no transformation) and builds a BVH only over its other triangles.
class SharedGeometry {
public:
    /// Builds the BVH over `mesh`'s triangles (world space), which must be
    /// finite and of non-zero area (InputError naming `origin` otherwise).
    SharedGeometry(const TriangleMesh& mesh, const std::string& origin);
    ~SharedGeometry();
    SharedGeometry(const SharedGeometry&) = delete;
    SharedGeometry& operator=(const SharedGeometry&) = delete;
    /// Number of triangles it holds.
    size_t triangles() const { return triangles_; }

private:
    friend class Scene;
    void* device_ = nullptr;  // RTCDevice, shared with every Scene built on it
    void* scene_ = nullptr;   // RTCScene of the triangles
    size_t triangles_ = 0;
    std::mutex mutex_;        // Scenes are built on the device one at a time
    std::string last_error_;  // the device's last error message
};

/// An immutable, thread-safe scene for intersection and light sampling.
class Scene {
public:
    /// Builds the BVH; throws InputError if the mesh is empty or holds non-finite
    /// vertices, RuntimeFailure on an Embree error. `origin` names the source for messages.
    /// With `shared`, the mesh's first shared->triangles() triangles must be
    /// exactly the shared ones: only the rest get a BVH of their own (no
    /// alpha cut-outs then: ParameterError).
    Scene(TriangleMesh mesh, std::vector<Material> materials, const Camera& camera, const std::string& origin,
          std::shared_ptr<SharedGeometry> shared = nullptr);
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    /// Closest hit along the ray within [tmin, tmax]; false on a miss.
    bool intersect(const Ray& ray, SurfaceInteraction& si) const;
    /// Closest hits of up to 4 rays traced together as one Embree packet
    /// (coherent rays, e.g. a path's offsets into neighbouring pixels, share
    /// traversal work). Ray i is traced if active[i]; its hit record is
    /// written through si[i] (a record of the caller's, e.g. a path vertex, so
    /// that none is copied). hit[i] is false for an inactive ray or a miss, and
    /// *si[i] is then unspecified. The hits are intersect()'s up to rounding
    /// in the last bits and the choice between coincident triangles.
    void intersect4(const Ray rays[4], const bool active[4], SurfaceInteraction* const si[4], bool hit[4]) const;
    /// intersect4() for up to 8 rays in one packet (e.g. a base path's camera
    /// ray with its four offsets'); as two 4-ray packets where Embree has no
    /// native 8-wide kernel.
    void intersect8(const Ray rays[8], const bool active[8], SurfaceInteraction* const si[8], bool hit[8]) const;
    /// True if anything blocks the ray within [tmin, tmax].
    bool occluded(const Ray& ray) const;
    /// True if the straight segment between two surface points is unblocked
    /// (ends offset along their normals to avoid self-hits).
    bool visible(const Vec3& p0, const Vec3& n0, const Vec3& p1, const Vec3& n1) const;
    /// visible() of a batch's segments traced as one Embree packet: out[i]
    /// is visible() of segment i, up to the packet kernel's rounding.
    /// Segments from neighbouring points to shared ends (a base path's four
    /// offsets towards its light point and its next vertex) share traversal.
    /// Up to four segments go as a 4-ray packet; single queries where Embree
    /// has no native packet kernel.
    void visible8(const VisibilityBatch& b, bool out[8]) const;

    /// Samples a point on an emitter by power then area (u_sel picks the
    /// triangle, u the point), or with the environment's share of the power
    /// (see environment_selection()) a direction to the environment (an
    /// infinite LightSample, u picking the direction), or with the delta
    /// lights' share (delta_selection()) one of them by its power (a delta
    /// LightSample, u unused).
    LightSample sample_light(const Vec3& ref, float u_sel, const Vec2& u) const;
    /// The point sample_light() would pick with the same numbers, with the
    /// radiance its front side emits: where a light subpath starts.
    LightSample sample_emitter_point(float u_sel, const Vec2& u) const;
    /// Light-sample prefetching: for a sample_light(ref, u_sel, u) coming up
    /// soon (best a vertex ahead, at least before the cast that reaches the
    /// vertex), starts loading the alias-table bucket u_sel picks, which
    /// holds both emitters it may take. Nothing is read, so nothing stalls.
    /// A hint only: results never change.
    void prefetch_light(float u_sel) const {
        if (buckets_.empty()) return;
        const char* b = reinterpret_cast<const char*>(&buckets_[light_pick(u_sel).bucket]);
        detail::prefetch(b);
        detail::prefetch(b + 64);
    }
    /// True if the point of triangle `prim` at barycentrics (b1, b2) is cut
    /// out by its material's opacity (Material::opacity), so rays pass it.
    bool cut_out(uint32_t prim, float b1, float b2) const;
    /// Area density (1/m^2) with which sample_light picks `prim` at any point on it.
    float light_pdf_a(uint32_t prim) const;
    /// True if the scene has any emitter (an environment and delta lights count).
    bool has_lights() const { return !buckets_.empty() || env_ != nullptr || !delta_lights_.empty(); }

    /// Installs the scene's delta lights (point, spot, directional; none
    /// removes them) and recomputes the light selection: each is one more
    /// light, picked by its power (DeltaLight::power). InputError naming
    /// `origin` on a non-finite or negative intensity, a zero direction or a
    /// spot whose angles are not 0 < beam_width <= cutoff <= pi. Not
    /// synchronised: set them only while no render runs.
    void set_delta_lights(std::vector<DeltaLight> lights, const std::string& origin = "scene");
    /// The delta lights (pointers into this stay valid until set_delta_lights()).
    const std::vector<DeltaLight>& delta_lights() const { return delta_lights_; }
    /// Probability (unitless) with which sample_light() picks one of the delta lights.
    float delta_selection() const { return delta_select_; }
    /// True if u_sel, a light-selection number of sample_light(), picks a delta light.
    bool picks_delta(float u_sel) const { return delta_select_ > 0.f && u_sel >= env_select_ && u_sel < env_select_ + delta_select_; }
    /// Discrete probability (unitless) with which sample_light() picks delta light `l` (one of delta_lights()).
    float delta_light_pdf(const DeltaLight& l) const { return delta_pick_[size_t(&l - delta_lights_.data())]; }

    /// Installs an environment emitter (nullptr removes it) and recomputes
    /// the light selection: the environment is one more light, picked with
    /// probability environment_selection(). Not synchronised: set it only
    /// while no render runs.
    void set_environment(std::shared_ptr<const Environment> env);
    /// The environment emitter, or nullptr.
    const Environment* environment() const { return env_.get(); }
    /// The environment emitter as set_environment() took it, to install in another scene; or nullptr.
    std::shared_ptr<const Environment> shared_environment() const { return env_; }
    /// Probability (unitless) with which sample_light() picks the environment:
    /// its estimated power over the scene's total. An environment's power is
    /// taken as that crossing the scene's bounding disk, pi r^2 times the
    /// integral of its radiance over the sphere, against pi L A for an
    /// emitting triangle (as pbrt-v4's power light sampler estimates them),
    /// both in luminance. This over-estimates an environment seen only
    /// through windows, which then gets more samples than it earns.
    float environment_selection() const { return env_select_; }
    /// True if u_sel, a light-selection number of sample_light(), picks the environment.
    bool picks_environment(float u_sel) const { return env_ && u_sel < env_select_; }
    /// Solid-angle density (1/sr) with which sample_light() picks direction w
    /// (unit, towards the environment) from any point: selection included; 0 without an environment.
    float environment_pdf(const Vec3& w) const { return env_ ? env_select_ * env_->pdf(w) : 0.f; }
    /// Centre of the bounding sphere of bounding_radius() (scene units).
    const Vec3& bounds_center() const { return center_; }
    /// A point along unit direction `dir` from `from` that lies outside the
    /// bounding sphere (scene units): the far end of a shadow ray towards the
    /// environment, and the stand-in position of a vertex at infinity.
    Vec3 beyond_scene(const Vec3& from, const Vec3& dir) const {
        return from + dir * (2.f * (radius_ + glm::length(from - center_)));
    }
    /// True if light-sample prefetching pays: the emitters and their alias
    /// table exceed what stays in the first-level cache. With a few emitters
    /// the prefetches only cost instructions.
    bool light_prefetch_pays() const { return light_prefetch_pays_; }

    // The path-space core's host interface (gdr/path/host.h), over the
    // Scene's own hit records and materials.
    using Interaction = SurfaceInteraction;  ///< The hit record the core reads.
    /// light_pdf_a() of the emitting triangle `hit` lies on (1/m^2).
    float light_pdf_a(const SurfaceInteraction& hit) const { return light_pdf_a(hit.prim); }
    /// Radiance of the sampled emitter point along w (W/(m^2 sr)): area
    /// lights are diffuse, and the core asks only on their front side.
    Color light_radiance(const LightSample& ls, const Vec3& w) const {
        return (void)w, materials_[mesh_.material_ids[ls.prim]].emission;
    }
    /// True if the surface at `hit` emits.
    bool is_emitter(const SurfaceInteraction& hit) const { return hit.is_emitter(); }
    /// Radiance the surface at `hit` emits along unit world direction w (W/(m^2 sr)).
    Color emitted(const SurfaceInteraction& hit, const Vec3& w) const { return hit.emitted(w); }
    /// Bsdf::sample() of the material at `hit` (local directions).
    std::optional<BsdfSample> sample_bsdf(const SurfaceInteraction& hit, const Vec3& wo, float u_lobe,
                                          const Vec2& u) const {
        return hit.material->bsdf->sample(wo, hit.uv, u_lobe, u);
    }
    /// Bsdf::eval_pdf() of the material at `hit` (1/sr each).
    BsdfEval eval_bsdf(const SurfaceInteraction& hit, const Vec3& wo, const Vec3& wi) const {
        return hit.material->bsdf->eval_pdf(wo, wi, hit.uv);
    }
    /// Bsdf::eval() of the material at `hit` (1/sr, no cosine).
    Color bsdf_f(const SurfaceInteraction& hit, const Vec3& wo, const Vec3& wi) const {
        return hit.material->bsdf->eval(wo, wi, hit.uv);
    }
    /// Bsdf::pdf() of the material at `hit` (1/sr).
    float pdf_bsdf(const SurfaceInteraction& hit, const Vec3& wo, const Vec3& wi) const {
        return hit.material->bsdf->pdf(wo, wi, hit.uv);
    }
    /// Bsdf::eval_delta() of the material at `hit`.
    std::optional<BsdfSample> eval_delta(const SurfaceInteraction& hit, const Vec3& wo, const Vec3& wi) const {
        return hit.material->bsdf->eval_delta(wo, wi, hit.uv);
    }
    /// Bsdf::albedo() of the material at `hit` (unitless RGB; an auxiliary feature, optional in a host).
    Color albedo(const SurfaceInteraction& hit) const { return hit.material->bsdf->albedo(hit.uv); }
    /// Bsdf::flags() of the material at `hit` (LobeFlags).
    uint32_t bsdf_flags(const SurfaceInteraction& hit) const { return hit.material->bsdf->flags(); }
    /// The material at `hit` (its SurfaceTraits fields are cached from its BSDF).
    const Material& surface(const SurfaceInteraction& hit) const { return *hit.material; }
    /// gdr::transport_factor() of the material at `hit`.
    float transport_factor(const SurfaceInteraction& hit, const Vec3& wo, const Vec3& wi, TransportMode mode) const {
        return gdr::transport_factor(*hit.material->bsdf, wo, wi, mode);
    }

    const Camera& camera() const { return camera_; }                   ///< The camera.
    const std::vector<Material>& materials() const { return materials_; }  ///< All materials.
    const TriangleMesh& mesh() const { return mesh_; }                    ///< The geometry.
    /// Object id (scene-file mesh entry index) of triangle `prim`, e.g. of a hit's SurfaceInteraction::prim.
    uint32_t object_id(uint32_t prim) const { return mesh_.object_ids.empty() ? 0u : mesh_.object_ids[prim]; }
    const SceneStats& stats() const { return stats_; }                    ///< Load counters.
    /// Radius of a sphere around the scene's bounds centre that holds it (scene units).
    float bounding_radius() const { return radius_; }

    /// The Embree scene handle (RTCScene), for benchmarks that cast bare rays.
    void* embree_scene() const { return rtc_scene_; }
    /// Replaces the camera (e.g. a resolution or field of view chosen after
    /// loading); the geometry does not depend on it. Not synchronised: set it
    /// only while no render runs.
    void set_camera(const Camera& camera) { camera_ = camera; }
    /// Replaces material `index`'s BSDF and emitted radiance (W/(m^2 sr),
    /// front side) in place, for editing a loaded scene: the cached BSDF
    /// flags are refreshed and, where the radiance changed, the light-selection
    /// distribution (power per emitting triangle) is rebuilt; geometry and BVH
    /// stay. ParameterError for an index out of range, a null BSDF, or a
    /// negative or non-finite radiance. Not synchronised: only while no render runs.
    void set_material(size_t index, std::shared_ptr<Bsdf> bsdf, const Color& emission);
    /// Number of triangles (after loading dropped zero-area ones) of object
    /// `object_id`, the scene-file mesh entry (see object_id()).
    size_t object_triangles(uint32_t object_id) const;
    /// Moves object `object_id`'s triangles in place: `positions` are their new
    /// world-space corners (scene units, 3 per triangle, in the scene's order
    /// of that object's triangles) and `normals` their vertex normals (any
    /// length; a zero or non-finite one falls back to the face normal, as at
    /// load), empty exactly when the scene has none. The triangles' vertices
    /// in the Embree geometry are updated and the BVH rebuilt (the scene is one
    /// Embree geometry, so its whole BVH: a rebuild, not a refit, so that the
    /// result is the BVH a fresh load builds), and the scene bounds and
    /// emitter areas (light distribution) recomputed. ParameterError for a
    /// count mismatch, a non-finite, out-of-range or zero-area triangle, or a
    /// scene built on shared geometry. Not synchronised: only while no render runs.
    void set_object_geometry(uint32_t object_id, const std::vector<Vec3>& positions, const std::vector<Vec3>& normals);
    /// Installs an observer of every traced ray (nullptr removes it). Not
    /// synchronised: set it only while no render runs. Costs one branch per ray.
    void set_ray_observer(RayObserver* observer) { observer_ = observer; }

private:
    void build_lights();
    // hit_info_'s kSmooth and kHasUv bits and flat_frames_ of triangle t, from mesh_.
    void classify_triangle(size_t t);
    // center_ and radius_ from mesh_'s positions.
    void compute_bounds();
    // visible() once its ends are offset: o = offset_ray_origin(p0, n0, p1 -
    // p0) and v = offset_ray_origin(p1, n1, p0 - p1) - o.
    bool segment_clear(const Vec3& o, const Vec3& v) const;
    // An emitting triangle as sample_light needs it, one cache line.
    struct alignas(64) Emitter {
        Vec3 p0, e1, e2;      // corner and edges
        Vec3 n;               // unit front normal
        uint32_t material;    // index into materials_ (emitted radiance, light_pdf_by_material_)
        uint32_t prim;        // triangle id
        float keep = 1.f;     // in a LightBucket's e[0]: the probability of keeping it
    };
    // Bucket i of Walker's alias table: emitter i, kept with probability
    // e[0].keep, and a copy of its alias, taken otherwise, on two adjacent
    // cache lines. A pick then reads one line that a single prefetch, a
    // vertex ahead, already asked for; with the alias stored by index, the
    // picks that take it (38% on veach-mis) waited for a second, dependent miss.
    struct alignas(128) LightBucket {
        Emitter e[2];  // this bucket's emitter, its alias
    };
    static_assert(sizeof(Emitter) == 64 && sizeof(LightBucket) == 128, "a bucket is two cache lines");
    // The alias-table bucket u_sel falls in, and u_sel's fraction within it,
    // in 32.32 fixed point: u_sel 2^32 is exact for the sampler's numbers
    // (multiples of 2^-24), so the product with the emitter count, and the
    // fraction's rounding to float, are exact too (a double-precision chain
    // of conversions would give the same bits, more slowly). The clamp only
    // matters for numbers outside [0, 1).
    struct LightPick {
        uint32_t bucket;
        float fraction;
    };
    LightPick light_pick(float u_sel) const {
        const uint64_t n = buckets_.size();
        const uint64_t fixed = uint64_t(int64_t(u_sel * 0x1p32f)) * n;
        return {uint32_t(std::min(fixed >> 32, n - 1)), float(int64_t(uint32_t(fixed))) * 0x1p-32f};
    }
    // The emitter sample_light picks with u_sel: the bucket's own, or (a
    // coin flip per sample, so an index, not a branch) its alias.
    const Emitter& light_select(float u_sel) const {
        const LightPick k = light_pick(u_sel);
        const LightBucket& b = buckets_[k.bucket];
        return b.e[!(k.fraction < b.e[0].keep)];
    }
    // The per-ray working set is kept small on purpose: beyond the L2 cache a
    // miss costs 150-450 ns on our machines, more than the BVH traversal, and
    // the bare-Embree bound keeps only the BVH hot. So a hit reads one word
    // per triangle (material and flags); position and normal come from the ray
    // and Embree's hit record; vertex normals and uvs only where they vary.
    static constexpr uint32_t kSmooth = 1u << 31;   // vertex normals differ from the face normal
    static constexpr uint32_t kHasUv = 1u << 30;    // texture coordinates are not all zero
    static constexpr uint32_t kPerturbed = 1u << 29; // the material has a bump or normal map
    static constexpr uint32_t kMaterialMask = kPerturbed - 1;
    TriangleMesh mesh_;
    std::vector<Material> materials_;
    Camera camera_;
    SceneStats stats_;
    float radius_ = 1.f;
    std::vector<uint32_t> hit_info_;        // per triangle: material | kSmooth | kHasUv
    std::vector<Frame> flat_frames_;        // per triangle: its face frame, or empty (a big scene)
    std::vector<LightBucket> buckets_;      // the alias table over the emitting triangles, for sample_light()
    bool light_prefetch_pays_ = false;      // see light_prefetch_pays()
    std::vector<float> light_pdf_by_material_;  // area pdf of the emitters of each material (0: not an emitter)
    void* rtc_device_ = nullptr;
    void* rtc_scene_ = nullptr;
    RayObserver* observer_ = nullptr;
    bool packets4_ = false;  // Embree traces 4-ray packets natively
    bool packets8_ = false;  // ... and 8-ray packets
    // Triangle index of Embree's hit: the shared triangles come first (hits
    // inside the instance), this scene's own after them (hits outside it);
    // 0 without shared geometry, where every hit is outside an instance.
    uint32_t unshared_base_ = 0;
    uint32_t global_prim(uint32_t prim, uint32_t inst) const { return prim + (inst == ~0u ? unshared_base_ : 0u); }
    // The environment's members come last: the ray and light-sample paths'
    // members keep their places (and cache lines).
    Vec3 center_{0.f};
    std::shared_ptr<const Environment> env_;  // see set_environment()
    std::shared_ptr<SharedGeometry> shared_;  // kept alive while its instance is in use
    void build_on_shared(std::shared_ptr<SharedGeometry> shared, const std::string& origin);
    float env_select_ = 0.f;                  // environment_selection()
    std::vector<DeltaLight> delta_lights_;    // see set_delta_lights()
    std::vector<float> delta_pick_;           // per delta light: its selection probability (delta share included)
    std::vector<float> delta_cdf_;            // cdf over the delta lights, within their share (n + 1 entries)
    float delta_select_ = 0.f;                // delta_selection()
    // sample_light() (ref given) and sample_emitter_point() (ref null) on a
    // delta light, u_sel rescaled to [0, 1) within the delta lights' share.
    LightSample sample_delta(const Vec3* ref, float u_sel) const;
    // sample_light()'s environment branch, u_sel already tested.
    LightSample sample_environment(const Vec3& ref, const Vec2& u) const;
    // sample_light() (ref given) and sample_emitter_point() (ref null) in a
    // scene with an environment or delta lights.
    [[gnu::noinline]] LightSample sample_with_environment(const Vec3* ref, float u_sel, const Vec2& u) const;
    // The triangle both pick with u_sel once past the environment's share.
    LightSample sample_triangle(float u_sel, const Vec2& u) const;
    template <int N, class RayHitN, class IntersectN>
    void intersect_packet(const Ray* rays, const bool* active, SurfaceInteraction* const* si, bool* hit,
                          IntersectN intersect_n) const;
    template <int N, class RayN, class OccludedN>
    void visible_packet(const VisibilityBatch& q, bool* out, OccludedN occluded_n) const;
    // The parts of a hit record that depend on the hit point: t, p, prim, uv, material.
    void fill_hit_point(const Ray& ray, uint32_t prim, float b1, float b2, float tfar, SurfaceInteraction& si) const;
    // Fills a hit record from Embree's hit (primitive, barycentrics, unnormalised Ng, distance).
    void fill_hit(const Ray& ray, uint32_t prim, float b1, float b2, const Vec3& ng, float t,
                  SurfaceInteraction& si) const;
    // fill_hit() for a hit on the flat triangle of `like`, reusing its normal and frame.
    void fill_hit_like(const Ray& ray, float b1, float b2, float tfar, const SurfaceInteraction& like,
                       SurfaceInteraction& si) const;
};

static_assert(PathHost<Scene>, "gdr's own Scene is a host of the path-space core");
static_assert(EnvironmentHost<Scene> && PrefetchingHost<Scene>);

}  // namespace gdr
