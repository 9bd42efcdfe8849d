// Support for equal-time comparisons of integrators (benchmarks/bench_equal_time):
// scenes re-rendered at a benchmark resolution, cached references, and the
// "time to reach an error" read off measured convergence curves.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gdr/core/params.h"
#include "gdr/integrators/integrator.h"
#include "gdr/scene/scene.h"

namespace gdr::eval {

/// Loads a scene file (JSON or Mitsuba XML) with its camera set to the same
/// pose at `width` pixels across, height scaled to keep the aspect ratio (at
/// least 1); its lights and environment are kept.
/// Benchmarks need this because the files' 512-1280 px cameras cost too much
/// time per sample pass. Throws what load_scene_file throws.
std::unique_ptr<Scene> load_scene_at_width(const std::string& path, int width);

/// Wall seconds of one `method` solve (with `params`) of a 1-spp render of
/// `scene` by `gpt` on `threads` threads: the solve time does not depend on
/// the sample count, so equal-time comparisons take it out of a gradient-domain
/// method's render budget.
double solve_seconds(Integrator& gpt, const Scene& scene, int threads, const std::string& method, const Params& params);

/// 64-bit FNV-1a hash of a file's bytes (cache keys); throws InputError if unreadable.
uint64_t hash_file(const std::string& path);

/// One measured point of a convergence curve: wall time (s) and error (unitless).
struct CurvePoint {
    double seconds = 0.0;  ///< Wall time including everything the method needs (render + solve), s.
    double error = 0.0;    ///< Error against the reference (e.g. relMSE), > 0.
};

/// How time_to_reach found its answer.
enum class Reach {
    Interpolated,           ///< Between two measured points (log-log linear).
    ExtrapolatedBelow,      ///< Already below the target at the first point: extended back along the first segment.
    ExtrapolatedAbove,      ///< Never reached: extended forward along the last segment.
    NotReached              ///< Never reached and the last segment does not descend.
};

/// The time (s) at which a curve reaches `target` error, with how it was found.
struct ReachTime {
    double seconds = 0.0;               ///< Estimated time, s (NaN if NotReached).
    Reach how = Reach::NotReached;      ///< Interpolated or extrapolated.
};

/// Time for a curve (any order; sorted by time inside) to first get down to
/// `target`: piecewise linear interpolation of log(error) against log(time)
/// between the last point above and the next at or below it; outside the
/// measured range the nearest segment's power law is extended (and flagged),
/// because log-log convergence curves are close to straight lines.
ReachTime time_to_reach(std::vector<CurvePoint> curve, double target);

/// Short text for a Reach ("interp", "extrap<", "extrap>", "never").
const char* to_string(Reach r);

/// The default reference cache directory: $GDR_REFERENCE_CACHE, else
/// $HOME/.cache/gdr-references, else /tmp/gdr-references. Outside git on purpose:
/// references are large and regenerated when missing.
std::string default_reference_cache();

}  // namespace gdr::eval
