// The accumulation storage of TiledIntegrator (gdr/integrators/tiled.h):
// large arrays on transparent huge pages, where each slot's channels sit in
// a pixel's accumulators, and the buffers kept from one render to the next.
// Shared by tiled.cpp (the integrator base) and tiled_run.cpp (one render).
#pragma once

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <new>
#include <vector>

#include <sys/mman.h>

#include "gdr/integrators/tiled.h"

namespace gdr {
namespace detail {

// Uninitialised values on transparent huge pages where the kernel offers them:
// a 1280x720 render accumulates 50 MB (pt) to 240 MB (gpt), and faulting that in as 4 KiB pages
// costs more than a sample per pixel on a virtual machine.
template <typename T>
struct HugeArray {
    explicit HugeArray(size_t n) : bytes((std::max<size_t>(n, 1) * sizeof(T) + kHuge - 1) / kHuge * kHuge) {
        void* p = std::aligned_alloc(kHuge, bytes);
        if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
        madvise(p, bytes, MADV_HUGEPAGE);  // a hint; failure just means small pages
#endif
        data = static_cast<T*>(p);
    }
    ~HugeArray() { std::free(data); }
    HugeArray(const HugeArray&) = delete;
    HugeArray& operator=(const HugeArray&) = delete;
    T& operator[](size_t i) { return data[i]; }
    static constexpr size_t kHuge = size_t(2) << 20;
    size_t bytes;
    T* data = nullptr;
};
using HugeFloats = HugeArray<float>;
using HugeDoubles = HugeArray<double>;
// Where each slot's channels sit in a pixel's accumulators.
struct SlotLayout {
    std::vector<int> offset;      // per slot: first channel among the means
    std::vector<int> var_offset;  // per slot: first channel among the squared deviations (-1: none)
    int stride = 0;               // channels per pixel
    int var_stride = 0;           // channels with a variance per pixel
    // The sample values whose squared deviations are kept, as runs of
    // consecutive channels (from, to, length) in squared-deviation order:
    // slots with a variance usually come first, so one run covers them and
    // its loop vectorises.
    struct Run {
        int from, to, n;
    };
    std::vector<Run> squared;
};

inline SlotLayout slot_layout(const std::vector<SlotSpec>& specs) {
    SlotLayout l;
    for (const auto& s : specs) {
        l.offset.push_back(l.stride), l.stride += s.channels;
        l.var_offset.push_back(s.variance ? l.var_stride : -1), l.var_stride += s.variance ? s.channels : 0;
    }
    for (size_t s = 0; s < specs.size(); ++s)
        if (specs[s].variance) {
            if (!l.squared.empty() && l.squared.back().from + l.squared.back().n == l.offset[s] &&
                l.squared.back().to + l.squared.back().n == l.var_offset[s])
                l.squared.back().n += specs[s].channels;
            else
                l.squared.push_back({l.offset[s], l.var_offset[s], specs[s].channels});
        }
    return l;
}

}  // namespace detail

struct TiledIntegrator::Buffers {
    std::unique_ptr<detail::HugeFloats> mean, m2;
    std::unique_ptr<detail::HugeDoubles> splat_sum, splat_sum2;  // per pixel and splat layer, 3 channels
    // A kept buffer is reused if it holds at least n values and not more
    // than four times that (a small render does not pin a big render's memory).
    template <typename T>
    static detail::HugeArray<T>& fit(std::unique_ptr<detail::HugeArray<T>>& b, size_t n) {
        const size_t need = std::max<size_t>(n, 1) * sizeof(T);
        if (!b || b->bytes < need || b->bytes > 4 * need + detail::HugeArray<T>::kHuge) {
            b.reset();  // free first: two large buffers need not coexist
            b = std::make_unique<detail::HugeArray<T>>(n);
        }
        return *b;
    }
    // Bytes held.
    size_t bytes() const {
        size_t n = 0;
        if (mean) n += mean->bytes;
        if (m2) n += m2->bytes;
        if (splat_sum) n += splat_sum->bytes + splat_sum2->bytes;
        return n;
    }
};

}  // namespace gdr
