// Deterministic, addressable random numbers: every number is a pure function
// of (seed, pixel, sample index, dimension). This makes images bit-identical
// for any thread count, and lets shift mappings and temporal seed sharing
// replay exactly the numbers another pixel or frame used.
#pragma once

#include <cassert>
#include <cstdint>

#include "gdr/core/math.h"

namespace gdr {

/// 64-bit finaliser (splitmix64 / murmur3 style): a bijective avalanche mix.
constexpr uint64_t mix64(uint64_t z) {
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/// Maps the top 24 bits of a 64-bit hash to a float in [0, 1).
constexpr float to_unit_float(uint64_t h) { return float(h >> 40) * 0x1p-24f; }
/// Maps bits 8..31 of a 64-bit hash to a float in [0, 1) (the low half's top 24 bits).
constexpr float to_unit_float_low(uint64_t h) { return float(uint32_t(h) >> 8) * 0x1p-24f; }

/// Identifies one sample stream: seed (render or frame), pixel and sample number.
struct SampleKey {
    uint64_t seed = 0;    ///< Render seed (frames of an animation use distinct seeds).
    uint32_t px = 0;      ///< Pixel column.
    uint32_t py = 0;      ///< Pixel row.
    uint32_t index = 0;   ///< Sample number within the pixel.

    /// The 64-bit stream id of this key.
    constexpr uint64_t stream() const { return stream_of(pixel_stream(), index); }
    /// The part of stream() that does not depend on the sample index: a render
    /// loop computes it once per pixel and calls stream_of() per sample.
    constexpr uint64_t pixel_stream() const { return mix64(mix64(seed) ^ ((uint64_t(py) << 32) | px)); }
    /// stream() of the key with pixel_stream() `pixel` and sample number `index`.
    static constexpr uint64_t stream_of(uint64_t pixel, uint32_t index) { return mix64(pixel ^ index); }
};

/// A stream of uniform numbers in [0,1) addressed by dimension. Copying a
/// Sampler and replaying it reproduces the same numbers (random replay shift).
class Sampler {
public:
    Sampler() = default;
    /// Starts the stream of `key` at dimension 0.
    explicit Sampler(const SampleKey& key) : stream_(key.stream()) {}
    /// Starts the stream with id `stream` (a SampleKey::stream() value) at dimension 0.
    explicit Sampler(uint64_t stream) : stream_(stream) {}

    /// The number at an absolute dimension; does not advance. Dimensions 2i
    /// and 2i+1 are the two halves of one hash, so a 2-D draw at an even
    /// dimension costs one hash (and the compiler merges the two calls).
    float at(uint32_t dim) const {
        const uint64_t h = mix64(stream_ ^ (uint64_t(dim >> 1) * 0xd1b54a32d192ed03ull));
        return dim & 1u ? to_unit_float_low(h) : to_unit_float(h);
    }
    /// The numbers at an even dimension and the next one, {at(dim), at(dim
    /// + 1)}, from their one hash. Use it where dim is not a compile-time
    /// constant: the compiler cannot then see that the two at() calls share a
    /// hash, and computes it twice.
    Vec2 at2(uint32_t dim) const {
        assert((dim & 1u) == 0u);
        const uint64_t h = mix64(stream_ ^ (uint64_t(dim >> 1) * 0xd1b54a32d192ed03ull));
        return {to_unit_float(h), to_unit_float_low(h)};
    }
    /// Next uniform number in [0,1).
    float next1d() { return at(dim_++); }
    /// Next pair of uniform numbers in [0,1)^2.
    Vec2 next2d() {
        if ((dim_ & 1u) == 0u) {
            dim_ += 2;
            return at2(dim_ - 2);
        }
        const float a = next1d();
        return {a, next1d()};
    }
    /// Current dimension (how many numbers were drawn).
    uint32_t dimension() const { return dim_; }
    /// Jumps to an absolute dimension (e.g. a fixed block per path vertex).
    void set_dimension(uint32_t d) { dim_ = d; }

private:
    uint64_t stream_ = 0;
    uint32_t dim_ = 0;
};

}  // namespace gdr
