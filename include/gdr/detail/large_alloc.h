// Allocation of large work buffers (frame-sized planes of solvers and
// network activations) backed by transparent huge pages where the kernel
// offers them. Not part of the public interface.
//
// Why: the first write to each 4 KiB page of a fresh allocation is a page
// fault, and glibc returns every block above 32 MiB (and, after a free,
// many above 128 KiB) to the kernel, so a reconstruction that allocates a
// few hundred frame-sized buffers pays the faults again for each. On a
// virtual machine a fault costs microseconds: on a 2-core one, a 1280x720
// poisson-weighted solve spent about half its time in them (4.8 s end to
// end, 2.8 s with 2 MiB pages). With a 2 MiB-aligned mapping and
// madvise(MADV_HUGEPAGE) each fault fills 512 pages at once. Where huge
// pages are not available (kernel setting "never", other systems) the
// buffers are ordinary ones.
//
// Freed mappings are kept (up to kLargeCacheBytes in all) and handed out
// again for a request of the same mapped length: a solver or a network pass
// frees and allocates buffers of a few sizes over and over, and the kernel
// zeroes every fresh page, huge or not (a quarter of a single 1280x720
// neural reconstruction's time went to that before the cache).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace gdr::detail {

/// Blocks at least this large (bytes) are mapped on their own, 2 MiB-aligned, with huge-page advice.
inline constexpr std::size_t kLargeBlock = std::size_t(1) << 20;
/// The huge page size the mappings are aligned to (bytes).
inline constexpr std::size_t kHugePage = std::size_t(2) << 20;

/// Most bytes of freed mappings kept for reuse (process-wide, per binary).
inline constexpr std::size_t kLargeCacheBytes = std::size_t(512) << 20;

/// Mapped length of a block of `bytes` (a whole number of huge pages).
inline std::size_t large_length(std::size_t bytes) { return (bytes + kHugePage - 1) / kHugePage * kHugePage; }

/// Freed mappings by length, for reuse.
struct LargeBlockCache {
    std::mutex mutex;
    std::map<std::size_t, std::vector<void*>> free;  ///< Mapped length (bytes) -> mappings.
    std::size_t bytes = 0;                           ///< Sum of the lengths held.
};

/// The cache; never destroyed, so that buffers freed during static destruction still find it.
inline LargeBlockCache& large_block_cache() {
    static auto* cache = new LargeBlockCache;
    return *cache;
}

/// `bytes` of uninitialised memory, aligned to 64 bytes at least; throws std::bad_alloc.
/// Free with large_free(p, bytes) and the same `bytes`.
inline void* large_alloc(std::size_t bytes) {
#if defined(__linux__)
    if (bytes >= kLargeBlock) {
        const std::size_t len = large_length(bytes);
        {
            LargeBlockCache& cache = large_block_cache();
            std::lock_guard<std::mutex> lock(cache.mutex);
            auto it = cache.free.find(len);
            if (it != cache.free.end() && !it->second.empty()) {
                void* p = it->second.back();
                it->second.pop_back();
                cache.bytes -= len;
                return p;
            }
        }
        // Over-map by one huge page, then unmap the unaligned head and the tail.
        void* raw = mmap(nullptr, len + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (raw == MAP_FAILED) throw std::bad_alloc();
        const auto base = reinterpret_cast<std::uintptr_t>(raw);
        const std::uintptr_t aligned = (base + kHugePage - 1) / kHugePage * kHugePage;
        if (aligned > base) munmap(raw, aligned - base);
        const std::size_t tail = base + len + kHugePage - (aligned + len);
        if (tail > 0) munmap(reinterpret_cast<void*>(aligned + len), tail);
        void* p = reinterpret_cast<void*>(aligned);
#if defined(MADV_HUGEPAGE)
        madvise(p, len, MADV_HUGEPAGE);  // advice only: refused where huge pages are off, harmlessly
#endif
        return p;
    }
#endif
    return ::operator new(bytes, std::align_val_t(64));
}

/// Frees a block of large_alloc(bytes).
inline void large_free(void* p, std::size_t bytes) noexcept {
    if (!p) return;
#if defined(__linux__)
    if (bytes >= kLargeBlock) {
        const std::size_t len = large_length(bytes);
        {
            LargeBlockCache& cache = large_block_cache();
            std::lock_guard<std::mutex> lock(cache.mutex);
            if (cache.bytes + len <= kLargeCacheBytes) {
                try {
                    cache.free[len].push_back(p);
                    cache.bytes += len;
                    return;
                } catch (...) {  // no memory for the list: unmap instead
                }
            }
        }
        munmap(p, len);
        return;
    }
#endif
    ::operator delete(p, std::align_val_t(64));
}

/// A standard allocator over large_alloc, for std::vector work buffers.
template <class T>
struct LargeAllocator {
    using value_type = T;
    LargeAllocator() = default;
    template <class U>
    LargeAllocator(const LargeAllocator<U>&) noexcept {}
    T* allocate(std::size_t n) {
        if (n > std::size_t(-1) / sizeof(T)) throw std::bad_alloc();
        return static_cast<T*>(large_alloc(n * sizeof(T)));
    }
    void deallocate(T* p, std::size_t n) noexcept { large_free(p, n * sizeof(T)); }
    template <class U>
    bool operator==(const LargeAllocator<U>&) const noexcept { return true; }
    template <class U>
    bool operator!=(const LargeAllocator<U>&) const noexcept { return false; }
};

}  // namespace gdr::detail
