// gdr/detail/large_alloc.h: the work buffers of the solvers and of the
// neural reconstructor's tensors.
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstring>
#include <vector>

#include "gdr/detail/large_alloc.h"

using namespace gdr::detail;

TEST_CASE("large_alloc: aligned, writable blocks of every size class, and freed large blocks are reused") {
    for (std::size_t bytes : {std::size_t(1), std::size_t(4096), kLargeBlock - 1, kLargeBlock, kHugePage + 12345,
                              std::size_t(11) << 20}) {
        auto* p = static_cast<unsigned char*>(large_alloc(bytes));
        REQUIRE(p != nullptr);
        CHECK(reinterpret_cast<std::uintptr_t>(p) % 64 == 0);
        std::memset(p, 0xAB, bytes);  // every byte writable (a short mapping would fault here)
        CHECK(p[0] == 0xAB);
        CHECK(p[bytes - 1] == 0xAB);
        if (bytes >= kLargeBlock) CHECK(reinterpret_cast<std::uintptr_t>(p) % kHugePage == 0);
        large_free(p, bytes);
    }
    // A block of the same mapped length comes back from the cache, one of
    // another length does not.
    void* a = large_alloc(3 << 20);
    large_free(a, 3 << 20);
    void* b = large_alloc((3 << 20) + 100);  // same length in huge pages (4 MiB)
    CHECK(b == a);
    void* c = large_alloc(9 << 20);
    CHECK(c != a);
    large_free(b, (3 << 20) + 100);
    large_free(c, 9 << 20);
    large_free(nullptr, 1 << 20);  // a no-op, as for operator delete
}

TEST_CASE("large_alloc: the cache holds at most kLargeCacheBytes") {
    // Free more than the cap of distinct blocks; the cache's total stays within it.
    std::vector<void*> blocks;
    const std::size_t bytes = std::size_t(64) << 20;
    for (std::size_t i = 0; i < kLargeCacheBytes / bytes + 3; ++i) blocks.push_back(large_alloc(bytes));
    for (void* p : blocks) large_free(p, bytes);
    LargeBlockCache& cache = large_block_cache();
    std::lock_guard<std::mutex> lock(cache.mutex);
    CHECK(cache.bytes <= kLargeCacheBytes);
    std::size_t held = 0;
    for (const auto& [len, list] : cache.free) held += len * list.size();
    CHECK(held == cache.bytes);
}

TEST_CASE("LargeAllocator: a std::vector over it behaves as one over std::allocator") {
    std::vector<float, LargeAllocator<float>> v(1 << 20, 1.5f);  // 4 MiB: a mapped block
    std::vector<float> ref(1 << 20, 1.5f);
    v.push_back(2.f), ref.push_back(2.f);  // reallocation: a copy into a new block
    v.resize(10), ref.resize(10);
    v.shrink_to_fit();
    REQUIRE(v.size() == ref.size());
    CHECK(std::equal(v.begin(), v.end(), ref.begin()));
}
