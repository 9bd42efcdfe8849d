// Environment emitters: light arriving from infinitely far away, the same
// radiance along every ray that leaves the scene in a given direction.
// Two kinds: `constant` (uniform radiance) and `envmap` (a latitude-longitude
// RGB map, importance-sampled by a piecewise-constant 2-D distribution of its
// luminance weighted by sin(theta)).
//
// Direction convention (that of Mitsuba 0.6 and 3's `envmap`, so imported
// scenes look as their authors saw them): directions point from the scene
// towards the environment. A world direction w is first taken to the
// emitter's local frame, d = to_world^-1 w; then, with +y up,
//   u = atan2(d.x, -d.z) / (2 pi)  wrapped to [0, 1)   (map column, left to right)
//   v = acos(d.y) / pi                                  (map row, top = +y)
// and inversely d = (sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi))
// with phi = 2 pi u, theta = pi v. So the map's left edge looks along local
// -z, u = 1/4 along +x, its centre column along +z and u = 3/4 along -x.
// The radiance between texels is interpolated bilinearly, as Mitsuba's
// envmap does: texel (x, y) is the value at its centre ((x + 0.5) / W,
// (y + 0.5) / H), u wraps around and v is clamped at the poles. Sampling is
// piecewise constant over the texels' cells, each weighted by the integral
// of that interpolant over it (3/4 of its own texel and 1/8 of each
// neighbour's per axis) times sin(theta).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <glm/mat3x3.hpp>

#include "gdr/core/image.h"
#include "gdr/core/math.h"

namespace gdr {

/// A direction sampled towards an environment.
struct EnvironmentSample {
    Vec3 wi{0.f, 0.f, 1.f};  ///< Unit world direction from the scene towards the environment.
    Color radiance{0.f};     ///< Radiance arriving from there, W/(m^2 sr).
    float pdf_w = 0.f;       ///< Solid-angle density of wi (1/sr); 0 if nothing was sampled.
};

/// An infinitely distant emitter: constant or a lat-long map (see the file comment
/// for the mapping). Immutable and thread-safe once built.
class Environment {
public:
    /// A uniform environment of radiance `radiance` (W/(m^2 sr), every component >= 0).
    static std::shared_ptr<Environment> constant(const Color& radiance);
    /// A lat-long map: texel (x, y) of `map` (RGB, radiance in W/(m^2 sr)
    /// before `scale`) covers u in [x/W, (x+1)/W), v in [y/H, (y+1)/H).
    /// `to_world` takes local directions to world ones and must be a rotation
    /// (orthonormal, a reflection allowed); `origin` names the source in errors.
    /// Throws InputError on negative, non-finite or all-black maps and on a
    /// to_world that is not orthonormal.
    static std::shared_ptr<Environment> from_map(const Image& map, const glm::mat3& to_world, float scale,
                                                 const std::string& origin);

    /// Radiance (W/(m^2 sr)) arriving from unit world direction w (pointing away from the scene).
    Color eval(const Vec3& w) const;
    /// Solid-angle density (1/sr) with which sample() produces unit direction w.
    float pdf(const Vec3& w) const;
    /// Samples a direction from two uniform numbers: the constant kind uniformly
    /// over the sphere, the map by cell (the luminance of the interpolated
    /// radiance integrated over the texel's cell, times sin(theta)), then
    /// uniformly in (u, v) within the cell.
    EnvironmentSample sample(const Vec2& u) const;
    /// Integral over the sphere of the luminance of eval(), in W/(m^2) (radiance
    /// times solid angle): the environment's power per unit area of a plane it
    /// lights (for a map: each cell's mean times its solid angle).
    double luminance_integral() const { return luminance_integral_; }
    /// True for the constant kind.
    bool is_constant() const { return map_.empty(); }
    /// The lat-long map's (u, v) coordinates of unit world direction w (see the file comment).
    Vec2 direction_to_uv(const Vec3& w) const;
    /// The unit world direction of lat-long coordinates (u, v) in [0, 1]^2.
    Vec3 uv_to_direction(const Vec2& uv) const;

private:
    Environment() = default;
    Color constant_{0.f};        // constant kind: the radiance
    Image map_;                  // envmap kind: scaled RGB radiance
    glm::mat3 to_world_{1.f}, to_local_{1.f};
    // Sampling of cells: row_cdf_ over rows (H + 1 entries, 0 .. 1), and per
    // row a cdf over its columns (W + 1 entries each) in col_cdf_; weight_ is
    // each cell's mean interpolated luminance times the sin(theta) of its row
    // centre, and weight_sum_ their total.
    std::vector<double> row_cdf_, col_cdf_;
    std::vector<float> weight_;
    double weight_sum_ = 0.0;
    double luminance_integral_ = 0.0;
    // Cell (texel) of (u, v), clamped into the map.
    int texel(const Vec2& uv, int& x, int& y) const;
    // The bilinearly interpolated radiance at (u, v) (see the file comment).
    Color lookup(const Vec2& uv) const;
};

}  // namespace gdr
