// The scene: triangle meshes in an Embree BVH, materials, area lights and a
// camera. Owns its Embree device and scene; Embree errors become exceptions.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gdr/core/math.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/camera.h"

namespace gdr {

/// A material: its BSDF and the radiance it emits from its front side.
struct Material {
    std::string name;             ///< Name from the MTL file.
    std::shared_ptr<Bsdf> bsdf;   ///< Scattering (never null).
    Color emission{0.f};          ///< Emitted radiance, W/(m^2 sr), front side (CCW winding) only.
};

/// A triangle soup ready for the BVH: three corners per triangle.
struct TriangleMesh {
    std::vector<Vec3> positions;        ///< 3 per triangle, world space.
    std::vector<Vec3> normals;          ///< 3 per triangle, or empty (flat shading).
    std::vector<Vec2> uvs;              ///< 3 per triangle, or empty.
    std::vector<uint32_t> material_ids; ///< 1 per triangle, index into Scene materials.
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

/// A point sampled on an emitter.
struct LightSample {
    Vec3 p{0.f};         ///< Position on the emitter.
    Vec3 n{0.f};         ///< Emitter's geometric (front) normal.
    Color radiance{0.f}; ///< Emitted radiance towards the reference point (0 if it sees the back side).
    float pdf_a = 0.f;   ///< Area-measure density including light selection (1/m^2).
    uint32_t prim = 0;   ///< Emitting triangle.
};

/// Counters gathered while loading (reported by the CLI).
struct SceneStats {
    size_t triangles = 0;           ///< Triangles in the BVH.
    size_t degenerate_skipped = 0;  ///< Zero-area triangles dropped at load.
    size_t emitters = 0;            ///< Emitting triangles.
};

/// An immutable, thread-safe scene for intersection and light sampling.
class Scene {
public:
    /// Builds the BVH; throws InputError if the mesh is empty or holds non-finite
    /// vertices, RuntimeFailure on an Embree error. `origin` names the source for messages.
    Scene(TriangleMesh mesh, std::vector<Material> materials, const Camera& camera, const std::string& origin);
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    /// Closest hit along the ray within [tmin, tmax]; false on a miss.
    bool intersect(const Ray& ray, SurfaceInteraction& si) const;
    /// True if anything blocks the ray within [tmin, tmax].
    bool occluded(const Ray& ray) const;
    /// True if the straight segment between two surface points is unblocked
    /// (ends offset along their normals to avoid self-hits).
    bool visible(const Vec3& p0, const Vec3& n0, const Vec3& p1, const Vec3& n1) const;

    /// Samples a point on an emitter by power then area (u_sel picks the triangle, u the point).
    LightSample sample_light(const Vec3& ref, float u_sel, const Vec2& u) const;
    /// Area density (1/m^2) with which sample_light picks `prim` at any point on it.
    float light_pdf_a(uint32_t prim) const;
    /// True if the scene has any emitter.
    bool has_lights() const { return !light_tris_.empty(); }

    const Camera& camera() const { return camera_; }                   ///< The camera.
    const std::vector<Material>& materials() const { return materials_; }  ///< All materials.
    const TriangleMesh& mesh() const { return mesh_; }                    ///< The geometry.
    const SceneStats& stats() const { return stats_; }                    ///< Load counters.
    /// Radius of a sphere around the scene's bounds centre that holds it (scene units).
    float bounding_radius() const { return radius_; }

    /// The Embree scene handle (RTCScene), for benchmarks that cast bare rays.
    void* embree_scene() const { return rtc_scene_; }

private:
    void build_lights();
    TriangleMesh mesh_;
    std::vector<Material> materials_;
    Camera camera_;
    SceneStats stats_;
    float radius_ = 1.f;
    std::vector<uint32_t> light_tris_;   // emitting triangle ids
    std::vector<float> light_cdf_;       // power CDF over light_tris_
    std::vector<float> light_pdf_by_prim_;  // area pdf per triangle (0 for non-emitters)
    void* rtc_device_ = nullptr;
    void* rtc_scene_ = nullptr;
};

/// Offset of a ray origin along the geometric normal that escapes the surface's
/// own float rounding (relative to the point's magnitude), scene units.
inline Vec3 offset_ray_origin(const Vec3& p, const Vec3& ng, const Vec3& dir) {
    const float scale = 1e-4f * std::max(1.f, std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z))));
    return p + (glm::dot(ng, dir) >= 0.f ? scale : -scale) * ng;
}

/// A ray leaving surface point `si` in unit direction `dir`.
inline Ray spawn_ray(const SurfaceInteraction& si, const Vec3& dir) {
    return Ray{offset_ray_origin(si.p, si.ng, dir), dir, 0.f, kInf};
}

}  // namespace gdr
