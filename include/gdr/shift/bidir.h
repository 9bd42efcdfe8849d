// Shift mappings on bidirectional paths (Manzi et al., "Gradient-Domain
// Bidirectional Path Tracing", 2015): the camera side of a path built from a
// camera subpath and a light subpath is shifted by an ordinary shift mapping
// (shift.h), walked vertex by vertex as gpt's offsets are, and the light
// subpath is shared. What gbdpt and its validator both use.
#pragma once

#include <limits>
#include <vector>

#include "gdr/path/trace.h"
#include "gdr/shift/shift.h"

namespace gdr {

/// A depth that is not there (no reconnection, no merge).
constexpr int kNoDepth = std::numeric_limits<int>::max();

/// The offset of a camera subpath, y_0 (the camera) .. y_m, as a subpath the
/// core's connect() and connection_densities() evaluate like a camera
/// subpath: Vertex::beta is the offset's throughput in the base's measure,
/// f(y)|J|/p(x) of its prefix, and the densities (pdf_fwd, pdf_rev, 1/m^2)
/// are the offset's own.
struct CameraOffset {
    Subpath p;                    ///< y_0 .. y_m.
    std::vector<OffsetVertex> y;  ///< y_k as shift steps read it (y[0] unused).
    std::vector<double> r;        ///< r[k]: |J| p(y)/p(x) of the camera walk up to y_k (1 at y_1), unitless.
    std::vector<ShiftStep> steps; ///< steps[k]: how y_k was left (kind Fail at the last vertex).
    int b = kNoDepth;             ///< Depth of the reconnection y_b -> x_{b+1}.
    /// That reconnection's segment is blocked: the path y exists (a strategy
    /// connecting across the segment samples it) and f(y) = 0.
    bool blocked = false;
    int merged = kNoDepth;        ///< First depth whose vertex is x's, entered from x's own previous vertex.
    /// Number of offset vertices, the camera included (0: no offset).
    int size() const { return p.size(); }
};

/// Shifts camera subpath `x` (x.film set) towards the pixel displaced by
/// `delta` (pixel units) with `shift`, until the offset ends, fails or merges
/// with x (whose vertices it then copies). A reconnection's segment is tested
/// here and, if blocked, marked rather than ending the offset. Adds the rays
/// cast to `rays`.
void shift_camera_subpath(const Scene& scene, const Shift& shift, const ShiftConfig& config, const CameraPath& x,
                          const Vec2& delta, CameraOffset& out, uint64_t& rays);

/// The step of `shift` at depth k of a base path whose vertices 0..k are
/// prefix[0..k] and whose next vertex is `next`, a light-side vertex (a light
/// subpath's surface vertex, or an emitter point): how the offset vertex `y`
/// continues when the connection x_k -> next is the reconnection.
/// `scratch` holds the base path the step reads. The reconnection's
/// visibility is left to the caller (ShiftStep::Kind::Reconnect).
ShiftStep shift_onto(const Scene& scene, const Shift& shift, const ShiftConfig& config, const Vertex* prefix, int k,
                     const Vertex& next, const OffsetVertex& y, CameraPath& scratch);

/// Light-subpath vertex q as a camera walk would have recorded it: entered
/// from the camera-side vertex `towards`, leaving towards `away`. Its
/// sampled direction has density 1 (sr^-1), because a reconnection at q, the
/// one step that reads this record, uses positions only.
Vertex camera_side_vertex(const Vertex& q, const Vertex& towards, const Vertex& away);

}  // namespace gdr
