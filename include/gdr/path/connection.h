// Connections between a light subpath and a camera subpath: the (s, t)
// strategies of bidirectional path tracing (Veach and Guibas,
// "Bidirectional Estimators for Light Transport", 1994; Lafortune and
// Willems, "Bi-Directional Path Tracing", 1993), with their MIS weights.
// Strategy (s, t) joins the light subpath's first s vertices to the camera
// subpath's first t vertices: s = 0 is a camera walk that hits an emitter,
// s = 1 next-event estimation (a fresh light sample, from the camera
// vertex's own light numbers, as a path tracer draws them), t = 1 light
// tracing (the light subpath seen by the camera, splatted where it lands).
#pragma once

#include <optional>
#include <type_traits>
#include <span>
#include <string_view>

#include "gdr/path/mis.h"
#include "gdr/path/subpath.h"

namespace gdr {

/// One (s, t) strategy: s light-subpath vertices, t camera-subpath vertices.
/// Its paths have s + t vertices and s + t - 1 segments.
struct Connection {
    int s = 0;  ///< Vertices taken from the light subpath.
    int t = 0;  ///< Vertices taken from the camera subpath (>= 1).
};

/// The densities of one full path z_0 (camera) .. z_{n-1} (light end) under
/// every strategy, in the area measure (1/m^2): the representation the MIS
/// weight of any (s, t) strategy reads.
struct PathDensities {
    std::vector<double> fwd;  ///< fwd[i]: density of a camera-direction walk producing z_i from z_{i-1} (i >= 1).
    std::vector<double> rev;  ///< rev[i]: density of a light-direction walk producing z_i from z_{i+1}; rev[n-1] the light's origin density.
    std::vector<uint8_t> delta;  ///< delta[i]: z_i scattered through a Dirac lobe (no strategy connects at it).
    /// The light end z_{n-1} is on a delta light (a point, spot or
    /// directional light): no camera walk reaches it, so s = 0 is impossible.
    bool delta_light = false;
    /// Number of vertices n.
    int size() const { return int(fwd.size()); }
    /// Resizes to n vertices, all densities 0, no delta and no delta light.
    void resize(int n) { fwd.assign(n, 0.0), rev.assign(n, 0.0), delta.assign(n, 0), delta_light = false; }
};

/// The strategies an estimator combines, and how.
struct StrategySet {
    MisHeuristic heuristic = MisHeuristic::Power;  ///< Heuristic of the MIS weights.
    /// Most light-subpath vertices of a strategy: -1 any (bidirectional path
    /// tracing), 1 a path tracer's (emitters hit by the camera walk, s = 0,
    /// and next-event estimation, s = 1), 0 emitters hit only.
    int max_s = -1;
};

/// True if strategy t (camera vertices z_0 .. z_{t-1}) can sample a path of
/// `d` and is in a set with at most `max_s` light vertices (-1: any): its
/// connecting vertices are not delta (for s = 0, the light is not a delta
/// light: PathDensities::delta_light), and a two-vertex path (the camera
/// sees the light) has only s = 0, since a pinhole cannot be hit.
inline bool strategy_possible(const PathDensities& d, int t, int max_s = -1);
/// MIS weight of strategy t for the path of `d` among the possible
/// strategies of `set`, by its heuristic over their full-path densities
/// (Veach 1997, section 10.2: a strategy's density over another's is a
/// product of rev / fwd ratios, a zero density of a delta step counting as 1).
inline double strategy_weight(const StrategySet& set, const PathDensities& d, int t);
/// Parses "s,t" into a strategy with s >= 0, t >= 1, (s, t) != (1, 1) and
/// s + t >= min_vertices; nullopt for any other text.
std::optional<Connection> parse_connection(std::string_view text, int min_vertices = 2);

/// The densities of every strategy of the path of `d` relative to strategy
/// t's own: out[t'] = p_t'(z) / p_t(z) for t' = 1 .. n (out has n + 1
/// entries, out[0] unused), 0 where strategy t' cannot sample the path
/// (strategy_possible without a light-vertex limit). Unitless. What an
/// estimator that restricts or pairs the strategies (gradient-domain
/// bidirectional path tracing) sums its own MIS weights from.
inline void strategy_density_ratios(const PathDensities& d, int t, std::vector<double>& out);

/// The densities of the path that strategy `c` forms from the two
/// subpaths: the subpaths' own, with those of the (up to) four vertices
/// around the connection recomputed for the joined path. `light_end` is the
/// light-side end z_t: light.v[c.s - 1], or for s = 1 the sampled light
/// vertex; ignored for s = 0.
template <PathHost H>
void connection_densities(const H& scene, const BasicSubpath<H>& light, const BasicSubpath<H>& camera, Connection c,
                          std::type_identity_t<const BasicVertex<H>*> light_end, PathDensities& d);

/// What a connection contributes.
struct ConnectionResult {
    Color value{0.f};     ///< Unweighted estimate f / p of the path's measurement contribution (W/(m^2 sr)); 0 if none.
    double weight = 0.0;  ///< Its MIS weight.
    bool splat = false;   ///< t = 1: the value belongs to raster point `film`, not to the sample's pixel.
    Vec2 film{0.f};       ///< Raster point (pixel units) of a t = 1 connection.
    /// The connection's segment was blocked (value 0): the path exists, and
    /// only this strategy samples it (every other one would trace the segment).
    bool occluded = false;
};

/// Evaluates strategy `c` for a sample's `light` and `camera` subpaths
/// (camera_sampler is the camera subpath's stream, for s = 1's light
/// numbers): the unweighted estimate (visibility tested), its raster point for
/// t = 1, and, if asked (a weight is wanted and the value is not 0), its MIS
/// weight among the strategies of `set`. Requires c.t >= 1, c.t <=
/// camera.size(), c.s <= light.size() (or c.s = 1, which samples its own
/// light), and (s, t) != (1, 1). Adds the shadow rays cast to `rays`.
template <PathHost H>
ConnectionResult connect(const H& scene, const BasicSubpath<H>& light, const BasicSubpath<H>& camera, Connection c,
                         const Sampler& camera_sampler, const StrategySet& set, bool want_weight, uint64_t& rays);

}  // namespace gdr

#include "gdr/path/detail/connection_impl.h"
