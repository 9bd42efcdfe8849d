// Shift mappings: how a base path x of one pixel becomes the offset path
// y = T(x) of a neighbouring pixel. A shift is applied vertex by vertex:
// at each base vertex x_k it decides how the offset leaves its own vertex y_k
// (a direction of its own, or a reconnection onto the base's next vertex
// x_{k+1}) and returns the Jacobian |d omega_y / d omega_x| of that step.
//
// A new shift is any type satisfying the ShiftMapping concept; add it to
// shift_registry() with register_shift<S>() (under S::kName) to use it in the
// `gpt` and `gbdpt` integrators and the validator, without touching gdr. A
// shift constructible from `const Params&` takes parameters: a render's
// shift.<key>=value reaches it, and a key it does not read is refused.
#pragma once

#include <concepts>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "gdr/core/params.h"
#include "gdr/path/trace.h"
#include "gdr/registry.h"

namespace gdr {

/// How vertices are classified as connectable (rough enough to reconnect at).
struct ShiftConfig {
    float threshold = 0.001f;    ///< Roughness (GGX alpha) above which a vertex is connectable.
    bool probabilistic = false;  ///< Thesis 4.3.5: classify with a probability instead of a hard threshold.
};

/// True if a vertex with BSDF roughness `roughness` counts as connectable. With
/// probabilistic classification the probability rises from 0 at threshold/4 to
/// 1 at 4*threshold (linear in log roughness) and `u` (fixed per path depth,
/// shared by base and offset) decides, so the shift stays invertible.
inline bool is_connectable(float roughness, float u, const ShiftConfig& c) {
    if (!c.probabilistic) return roughness > c.threshold;
    if (roughness <= 0.f) return false;
    const float t = (std::log(roughness / c.threshold) + std::log(4.f)) / (2.f * std::log(4.f));
    return u < std::clamp(t, 0.f, 1.f);
}

/// Draws the numbers probabilistic classification reads (Vertex::u_classify,
/// the dims::kClassify number of each vertex's block) into a traced camera
/// path whose walk took `max_vertices` (WalkOptions::max_vertices): at every
/// surface vertex the walk continued from (not its last allowed vertex, not a
/// black surface), as the walk draws its other numbers there. The base path's
/// numbers are then its offsets' (thesis 4.3.5). Hard classification reads
/// none and the vertices keep 0.5.
template <PathHost H>
void draw_classification_numbers(const H& host, const Sampler& sampler, int max_vertices, BasicSubpath<H>& path) {
    for (int k = 1; k < path.size(); ++k) {
        BasicVertex<H>& x = path.v[size_t(k)];
        if (x.infinite || (max_vertices >= 0 && k == max_vertices) || host.surface(x.si).black) continue;
        x.u_classify = sampler.at(vertex_block(path.mode, k) + dims::kClassify);
    }
}

/// The offset path's current vertex y_k, on host H (gdr/path/host.h).
template <class H>
struct BasicOffsetVertex {
    typename H::Interaction si;  ///< y_k (equals x_k once the offset has reconnected).
    Vec3 wo{0.f};                ///< Local direction from y_k towards y_{k-1}.
    Color emitted{0.f};          ///< Radiance emitted from y_k towards y_{k-1}.
    bool on_base = false;        ///< y_k is the base vertex x_k (reconnected just before k).
    /// y_k is on the environment: the offset's ray left the scene along
    /// -si.ng (environment.h's convention), and the offset ends here.
    bool infinite = false;
};
/// An offset vertex on gdr's own Scene.
using OffsetVertex = BasicOffsetVertex<Scene>;

/// Everything a shift step may look at: the base path, the current depth
/// and the offset's vertex, on host H.
template <class H>
struct BasicShiftStepInput {
    const H& scene;            ///< For visibility, tracing and BSDF values.
    const ShiftConfig& config; ///< Classification settings.
    const BasicCameraPath<H>& base;  ///< The recorded base path.
    size_t k;                  ///< Index of the current base vertex x_k in base.v (1 = the first hit; v[0] is the camera).
    const BasicOffsetVertex<H>& y;   ///< The offset's vertex at the same depth.
};

/// The result of shifting the base's scattering at x_k onto y_k.
struct ShiftStep {
    /// How the offset leaves y_k.
    enum class Kind {
        Fail,       ///< No offset path: f(y) = 0 from here on.
        Direction,  ///< The offset continues along `wi` with a ray of its own.
        /// The offset connects y_k -> x_{k+1} and shares the base's vertices
        /// after it. The caller tests the segment's visibility (the offset
        /// walk batches it with other offsets' segments) and fails the offset
        /// there if it is blocked: a step need not trace it.
        Reconnect,
    };
    Kind kind = Kind::Fail;
    Vec3 wi{0.f};           ///< Offset direction at y_k (local frame of y_k).
    double jacobian = 0.0;  ///< |d omega_y / d omega_x| of this step (solid angle at y_k over solid angle at x_k).
    Color f{0.f};           ///< Offset BSDF value along wi (the delta-lobe weight for a delta lobe).
    float pdf = 0.f;        ///< Offset's own solid-angle pdf of wi (discrete lobe probability for delta lobes).
    bool delta = false;     ///< The offset scattered through a delta lobe.
    /// The Jacobian is a ratio of sampling densities in primary-sample space
    /// (random replay), not a geometric one: at BSDFs that mix lobes it differs
    /// from the direction-to-direction Jacobian by the lobe-selection terms.
    bool sample_space = false;
    /// The step is only valid if the vertex it reaches is NOT connectable (otherwise
    /// the inverse shift would have reconnected there, and T would not be invertible).
    bool reject_if_connectable = false;
    /// The step is only valid if its ray does not leave the scene (otherwise the
    /// inverse shift would have copied the direction onto the environment there).
    bool reject_if_escapes = false;
};
/// A shift step's input on gdr's own Scene.
using ShiftStepInput = BasicShiftStepInput<Scene>;

/// A shift mapping on host H: a type with a name and a step() that shifts
/// one vertex of H's paths. The built-in shifts' step() is a template, so
/// they are shift mappings on every host.
template <typename S, typename H>
concept ShiftMappingOn = requires(const S& s, const BasicShiftStepInput<H>& in) {
    { S::kName } -> std::convertible_to<std::string_view>;
    { s.step(in) } -> std::same_as<ShiftStep>;
};
/// A shift mapping on gdr's own Scene.
template <typename S>
concept ShiftMapping = ShiftMappingOn<S, Scene>;

/// Type-erased shift mapping on host H, as stored in a registry and used by integrators.
template <class H>
class BasicShift {
public:
    virtual ~BasicShift() = default;
    /// Shifts the base's scattering at vertex in.k onto the offset vertex in.y.
    virtual ShiftStep step(const BasicShiftStepInput<H>& in) const = 0;
    /// Registered name.
    virtual std::string name() const = 0;
};
/// A type-erased shift mapping on gdr's own Scene.
using Shift = BasicShift<Scene>;

/// Wraps a shift mapping value S as a BasicShift on host H.
template <class S, class H = Scene>
    requires ShiftMappingOn<S, H>
class ShiftModel final : public BasicShift<H> {
public:
    explicit ShiftModel(S s) : s_(std::move(s)) {}
    ShiftStep step(const BasicShiftStepInput<H>& in) const override { return s_.step(in); }
    std::string name() const override { return std::string(S::kName); }

private:
    S s_;
};

/// Makes a heap-allocated shift on host H (gdr's Scene by default) from a shift mapping value.
template <class H = Scene, class S>
    requires ShiftMappingOn<S, H>
std::unique_ptr<BasicShift<H>> make_shift(S s) {
    return std::make_unique<ShiftModel<S, H>>(std::move(s));
}

/// Registers shift mapping S under its S::kName with a one-line description:
/// made from the render's shift parameters if S is constructible from
/// `const Params&` (every key it does not read is then refused), else
/// default-constructed (any parameter is refused).
template <class S, class H>
    requires ShiftMappingOn<S, H>
void register_shift(Registry<BasicShift<H>>& registry, const std::string& description) {
    registry.add(std::string(S::kName), description, [](const Params& p) -> std::unique_ptr<BasicShift<H>> {
        if constexpr (std::is_constructible_v<S, const Params&>) return make_shift<H>(S(p));
        else return (void)p, make_shift<H>(S{});
    });
}

/// Makes shifts `names` of shift_registry() for an integrator with
/// parameters `p`: shift.<key>=value goes to the one shift, or
/// shift.<name>.<key>=value to shift `name` of several (Params::parts), and a
/// key no shift reads is refused (ParameterError naming it). Appends the
/// given shift parameters to `stored` as "key=value" lines, for describe().
std::vector<std::unique_ptr<Shift>> make_shifts(const Params& p, const std::vector<std::string>& names,
                                                std::string& stored);

/// The process-wide shift registry (reconnection, half-vector, replay, replay-reconnect built in).
Registry<Shift>& shift_registry();
/// Adds gdr's built-in shifts to a registry.
void register_builtin_shifts(Registry<Shift>& r);

}  // namespace gdr
