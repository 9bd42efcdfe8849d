// Fixed layout of random-number dimensions along a camera path. Each vertex
// owns a fixed block, so a path's k-th vertex always consumes the same
// numbers whatever happened earlier: the precondition of random-replay
// shifts and of seed sharing between frames.
#pragma once

#include <cstdint>

namespace gdr::dims {

inline constexpr uint32_t kFilm = 0;         ///< 2 numbers: sub-pixel position.
inline constexpr uint32_t kFirstVertex = 2;  ///< Start of the per-vertex blocks.
inline constexpr uint32_t kPerVertex = 8;    ///< Numbers per vertex block.

// Numbers drawn together share an even-odd pair (one hash, see Sampler::at):
// the light point, the emitter choice with the lobe choice (both known a
// vertex ahead, for prefetching), the BSDF direction, roulette with classification.
inline constexpr uint32_t kLightPoint = 0;   ///< 2 numbers: point on the emitter.
inline constexpr uint32_t kLightSelect = 2;  ///< 1 number: which emitter triangle.
inline constexpr uint32_t kBsdfLobe = 3;     ///< 1 number: BSDF lobe choice.
inline constexpr uint32_t kBsdfDir = 4;      ///< 2 numbers: BSDF direction.
inline constexpr uint32_t kRoulette = 6;     ///< 1 number: Russian roulette.
inline constexpr uint32_t kClassify = 7;     ///< 1 number: probabilistic vertex classification.

/// First dimension of the block of the vertex at path depth `depth` (1 = first hit).
constexpr uint32_t vertex(int depth) { return kFirstVertex + uint32_t(depth - 1) * kPerVertex; }

// A light subpath (bidirectional methods) draws from its own range, far
// above any camera path's blocks, with the same per-vertex layout after an
// origin block: the camera subpath of a sample keeps the numbers a path
// tracer's path would use, and the two subpaths are independent.
inline constexpr uint32_t kLightSubpath = 1u << 30;  ///< Start of the light subpath's range.
inline constexpr uint32_t kEmitPoint = 0;    ///< 2 numbers: point on the emitter (origin block).
inline constexpr uint32_t kEmitSelect = 2;   ///< 1 number: which emitter triangle (origin block).
inline constexpr uint32_t kEmitDir = 4;      ///< 2 numbers: emitted direction (origin block).

/// First dimension of the light subpath's origin block.
constexpr uint32_t light_origin() { return kLightSubpath; }
/// First dimension of the block of the light subpath's vertex `k` (1 = first hit after the emitter).
constexpr uint32_t light_vertex(int k) { return kLightSubpath + uint32_t(k) * kPerVertex; }

}  // namespace gdr::dims
