// Applying a shift mapping to a whole recorded base path: the offset path's
// vertices, its light connections and the per-step Jacobians, pdfs and BSDF
// values an estimator or a validator needs.
#pragma once

#include <vector>

#include "gdr/path/trace.h"
#include "gdr/shift/shift.h"

namespace gdr {

/// The offset path at one depth k: its vertex, its shifted light connection,
/// and how it leaves towards depth k+1.
template <class H>
struct BasicOffsetRecord {
    BasicOffsetVertex<H> y;         ///< y_k.
    bool nee = false;               ///< The base's light sample at x_k was shifted to y_k.
    Color nee_f{0.f};               ///< BSDF value at y_k towards the light point (1/sr).
    float nee_cos = 0.f;            ///< |cos| at y_k towards the light point.
    Color nee_radiance{0.f};        ///< Radiance from the light point towards y_k (0 if blocked or back side).
    double nee_jacobian = 0.0;      ///< d omega_y / d omega_x of the light direction (the point is shared).
    double nee_pdf_light_w = 0.0;   ///< Offset's own light-sampling density of that direction (1/sr).
    float nee_pdf_bsdf = 0.f;       ///< Offset's own BSDF density of that direction (1/sr).
    ShiftStep step;                 ///< How the offset leaves y_k (kind Fail if it does not).
};
/// An offset record on gdr's own Scene.
using OffsetRecord = BasicOffsetRecord<Scene>;

/// An offset path y = T(x). It ends where the base ends or where a step failed
/// (f(y) = 0 beyond). Once y has reconnected and its incoming direction at a
/// shared vertex equals the base's, it is the base from there on: those
/// vertices get no records (merged_from marks where they begin).
template <class H>
struct BasicOffsetPath {
    std::vector<BasicOffsetRecord<H>> v;          ///< Records of the offset's own vertices; v[k] pairs with base.v[k] (v[0]: the camera, shared).
    size_t length = 0;                    ///< Number of offset vertices, camera and shared suffix included (0: no offset path).
    size_t merged_from = size_t(-1);      ///< First depth where y equals x; no records from there on.
    /// Depth k (merged_from - 1) at which y reconnected onto x_k and takes
    /// x_k's BSDF values for its light sample and its scattering, because
    /// the BSDF sees only which side wo is on: from x_k's light sample on,
    /// y's terms are the base's times y's throughput (size_t(-1) if not).
    size_t base_values_from = size_t(-1);
    uint64_t rays = 0;                    ///< Rays cast to build it.
    /// Number of offset vertices.
    size_t size() const { return length; }
    /// True if depth k belongs to the shared suffix.
    bool merged(size_t k) const { return k >= merged_from; }
};
/// An offset path on gdr's own Scene.
using OffsetPath = BasicOffsetPath<Scene>;

/// Shifts `base` to the pixel displaced by `pixel_offset` (pixel units, e.g. (1,0))
/// with `shift`, tracing the offset's own rays where needed.
template <PathHost H>
void shift_camera_path(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config,
                       const BasicCameraPath<H>& base, const Vec2& pixel_offset, BasicOffsetPath<H>& out);

}  // namespace gdr

#include "gdr/shift/detail/offset_walk.h"

namespace gdr {

template <PathHost H>
void shift_camera_path(const H& scene, const BasicShift<H>& shift, const ShiftConfig& config,
                       const BasicCameraPath<H>& base, const Vec2& pixel_offset, BasicOffsetPath<H>& out) {
    detail::reset(out);
    if (base.size() <= 1) return;
    Ray ray;
    typename H::Interaction* si = detail::start_offset(scene, base.film, pixel_offset, out, ray);
    detail::complete_offset(scene, shift, config, base, ray, scene.intersect(ray, *si), out);
}

// gdr's own Scene's is compiled once, in the library.
extern template void shift_camera_path(const Scene&, const Shift&, const ShiftConfig&, const CameraPath&, const Vec2&,
                                       OffsetPath&);

}  // namespace gdr
