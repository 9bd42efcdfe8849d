// The building blocks the built-in shift mappings are made of: vertex
// classification, reconnection, half-vector copy and random-number replay.
// Each returns a ShiftStep for the base vertex in.k and offset vertex in.y.
#pragma once

#include "gdr/shift/shift.h"

namespace gdr::shift {

/// Connectability of base vertex i (by its BSDF's roughness and its classification number).
inline bool base_connectable(const ShiftStepInput& in, size_t i) {
    const Vertex& x = in.base.v[i];
    // A vertex on the environment is a direction: nothing reconnects to it.
    return !x.infinite && is_connectable(x.si.material->min_roughness, x.u_classify, in.config);
}

/// Connectability of the offset vertex y_k (classified with the base's number at the same depth).
inline bool offset_connectable(const ShiftStepInput& in) {
    return !in.y.infinite && is_connectable(in.y.si.material->min_roughness, in.base.v[in.k].u_classify, in.config);
}

/// True if the base continues to a vertex x_{k+1}.
inline bool base_has_next(const ShiftStepInput& in) { return in.base.v[in.k].scattered() && in.k + 1 < in.base.size(); }

/// True if reconnecting y_k -> x_{k+1} is allowed: x_k, y_k and x_{k+1} are all connectable.
inline bool can_reconnect(const ShiftStepInput& in) {
    return base_has_next(in) && base_connectable(in, in.k) && offset_connectable(in) && base_connectable(in, in.k + 1);
}

/// Reconnection y_k -> x_{k+1} (Kettunen et al., "Gradient-Domain Path Tracing" (2015)): fails if the segment is blocked, arrives from
/// the other side of x_{k+1}'s surface, or carries no throughput. With
/// in.defer_visibility the blocking test is left to the caller.
/// |J| = |cos_y| ||x_k - x_{k+1}||^2 / (|cos_x| ||y_k - x_{k+1}||^2), cosines at x_{k+1}.
ShiftStep reconnect(const ShiftStepInput& in);

/// Half-vector copy (Kettunen et al., "Gradient-Domain Path Tracing" (2015)): the offset keeps the base's half-vector in its local
/// frame (reflection, or generalised half-vector for refraction); delta lobes
/// map to delta lobes with J = 1. Fails on mismatched lobes, total internal
/// reflection, or a direction on the wrong side.
ShiftStep half_vector(const ShiftStepInput& in);

/// Random-number replay: the offset samples its BSDF with the base's numbers;
/// J = pdf_x / pdf_y. Fails if the offset's sample is missing or of another
/// kind (delta vs non-delta).
ShiftStep replay(const ShiftStepInput& in);

/// The pattern of the survey's shifts: reconnect as soon as x_k, y_k and x_{k+1}
/// are connectable, otherwise take `fallback`'s own direction. When only x_{k+1}
/// prevented the reconnection, the step is marked reject_if_connectable: the
/// inverse would reconnect at a connectable y_{k+1}, so T must not go there.
ShiftStep reconnect_or(const ShiftStepInput& in, ShiftStep (*fallback)(const ShiftStepInput&));

}  // namespace gdr::shift
