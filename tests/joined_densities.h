// The check shared by the bidirectional tests: an (s, t) connection's
// densities, as connection_densities() assembles them from the subpaths'
// records, against the densities computed from scratch along the joined
// path, and its strategies' balance weights summing to one.
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "gdr/path/connection.h"
#include "gdr/path/environment.h"

namespace gdr::test {

/// Running totals of check_joined_densities().
struct DensityTally {
    int checked = 0;     ///< Connections checked.
    int compared = 0;    ///< Densities compared.
    int loose = 0;       ///< Of those, off by more than 1e-3 (relative).
    double worst = 0.0;  ///< Largest relative difference.
};

/// Checks connection `c` of the two subpaths if it contributes and no two
/// of its finite vertices are closer than 1e-2 (in a corner the rays'
/// origin offsets are not small against the segment); returns whether it
/// was checked. The walk's densities are of its sampled directions, those
/// from scratch of the directions between the stored (offset) hit points,
/// so a glossy lobe turns the offsets into percents: each density must be
/// within 10%, and `tally` counts how many are looser than 1e-3. A
/// bookkeeping error (a wrong vertex, a missing cosine) is off by far more,
/// and everywhere. With `positive`, every density must also be > 0.
inline bool check_joined_densities(const Scene& scene, const Subpath& light, const Subpath& camera, Connection c,
                                   const Sampler& sampler, DensityTally& tally, bool positive = false) {
    const int s = c.s, t = c.t;
    uint64_t rays = 0;
    const ConnectionResult r = connect(scene, light, camera, c, sampler, {MisHeuristic::Power, -1}, true, rays);
    if (is_black(r.value)) return false;
    PathDensities d;
    connection_densities(scene, light, camera, c, s > 0 ? &light.v[s - 1] : nullptr, d);
    // The joined path z_0 .. z_{n-1}.
    std::vector<const Vertex*> z;
    for (int k = 0; k < t; ++k) z.push_back(&camera.v[k]);
    for (int k = s - 1; k >= 0; --k) z.push_back(&light.v[k]);
    const int n = int(z.size());
    for (int k = 1; k < n; ++k)
        if (!z[k]->infinite && !z[k - 1]->infinite && glm::length(z[k]->si.p - z[k - 1]->si.p) < 1e-2f) return false;
    const auto rel = [](double a, double b) { return std::abs(a - b) / std::max({std::abs(a), std::abs(b), 1e-30}); };
    for (int k = 1; k < n; ++k) {
        const double fwd = pdf_area(scene, k >= 2 ? z[k - 2] : nullptr, *z[k - 1], *z[k]);
        const double rev = k == n - 1   ? pdf_light_origin(scene, *z[k])
                           : k == n - 2 ? pdf_light_direction(scene, *z[n - 1], *z[k])
                                        : pdf_area(scene, z[k + 2], *z[k + 1], *z[k]);
        INFO("(s, t) = (" << s << ", " << t << ") vertex " << k);
        tally.worst = std::max({tally.worst, rel(d.fwd[k], fwd), rel(d.rev[k], rev)});
        REQUIRE(rel(d.fwd[k], fwd) < 0.1);
        REQUIRE(rel(d.rev[k], rev) < 0.1);
        if (positive) {
            REQUIRE(d.fwd[k] > 0.0);
            REQUIRE(d.rev[k] > 0.0);
        }
        tally.compared += 2;
        tally.loose += (rel(d.fwd[k], fwd) > 1e-3) + (rel(d.rev[k], rev) > 1e-3);
    }
    double sum = 0.0;
    for (int u = 1; u <= n; ++u)
        if (strategy_possible(d, u)) sum += strategy_weight({MisHeuristic::Balance, -1}, d, u);
    REQUIRE(sum == Approx(1.0).epsilon(1e-9));
    ++tally.checked;
    return true;
}

}  // namespace gdr::test
