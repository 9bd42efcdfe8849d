// A validator for shift mappings: samples base paths of a scene, shifts them
// to the right-hand neighbour and checks what every shift must satisfy:
// failures are counted, shifting back returns the base path, and the
// analytic Jacobian of every step matches a finite-difference one.
#pragma once

#include <string>

#include "gdr/shift/shift.h"

namespace gdr {

/// What and how much to check.
struct ValidateOptions {
    int paths = 20000;              ///< Base paths to sample.
    uint64_t seed = 1;              ///< Sampler seed.
    int max_depth = 8;              ///< Longest base path (segments).
    double position_tolerance = 1e-3;  ///< Reversibility: allowed vertex distance, relative to the scene's radius.
    double jacobian_tolerance = 0.02;  ///< Allowed relative error of an analytic Jacobian.
    float fd_step = 2e-4f;          ///< Central-difference step in primary-sample space.
    double required_fraction = 0.99;   ///< Share of checks that must pass.
};

/// The outcome of validating one shift on one scene.
struct ShiftReport {
    std::string shift;                 ///< Name of the shift.
    size_t sampled = 0;                ///< Camera paths sampled (ValidateOptions::paths).
    size_t base_paths = 0;             ///< ...with at least two vertices: the ones a shift can act on.
    size_t complete = 0;               ///< Offsets as long as their base path (the shift never failed).
    size_t reverse_checked = 0;        ///< Complete offsets shifted back.
    size_t reverse_ok = 0;             ///< ...that returned to their base path.
    size_t reverse_failed_shift = 0;   ///< ...whose inverse shift failed instead (a mismatch of conditions).
    size_t jacobian_checked = 0;       ///< Steps whose Jacobian was compared with finite differences.
    size_t jacobian_ok = 0;            ///< ...within tolerance.
    size_t jacobian_skipped = 0;       ///< Replay steps at multi-lobe BSDFs (density-ratio Jacobians, see ShiftStep).
    double jacobian_median_error = 0.0;   ///< Median relative error of the analytic Jacobians.
    double jacobian_worst_error = 0.0;    ///< Largest relative error seen.
    bool passed = false;               ///< All checks passed at the required fraction.
    /// Base paths join a camera and a light subpath (validate_bidirectional_shift).
    bool bidirectional = false;

    /// Share of base paths whose shift failed somewhere (in [0,1]).
    double failure_rate() const { return base_paths ? 1.0 - double(complete) / double(base_paths) : 0.0; }
    /// A human-readable report ending in one PASS/FAIL line.
    std::string summary() const;
};

/// Validates `shift` on `scene` (see ShiftReport for what is measured).
ShiftReport validate_shift(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                           const ValidateOptions& options = {});

/// Validates `shift` as gbdpt applies it (gdr/shift/bidir.h), on paths that
/// join a camera subpath to a light subpath: each sample picks one
/// connection strategy (light tracing included), shifts it to the right-hand
/// neighbour, counts undefined offsets as failures, shifts the offset back,
/// and compares the Jacobians the bidirectional shift adds (a reconnection
/// onto a light-side vertex, light tracing's film shift in area measure)
/// with finite differences. base_paths counts the connection paths tried.
ShiftReport validate_bidirectional_shift(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                                         const ValidateOptions& options = {});

}  // namespace gdr
