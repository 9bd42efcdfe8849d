// libtorch's CPU allocator over gdr::detail::large_alloc (tensor_memory.h).

#include "tensor_memory.h"

#include <c10/core/CPUAllocator.h>

#include <cstring>
#include <mutex>

#include "gdr/detail/large_alloc.h"

namespace gdr::neural {
namespace {

// Every block carries its size in a 64-byte header: libtorch's oneDNN
// kernels free through raw_deleter(), which gets the data pointer alone.
constexpr std::size_t kHeader = 64;

void free_block(void* data) {
    if (!data) return;
    char* block = static_cast<char*>(data) - kHeader;
    std::size_t bytes;
    std::memcpy(&bytes, block, sizeof bytes);
    detail::large_free(block, bytes);
}

class LargePageAllocator final : public c10::Allocator {
public:
    c10::DataPtr allocate(std::size_t bytes) const override {
        // Small blocks too (large_alloc gives them to operator new): one deleter for all.
        const std::size_t total = bytes + kHeader;
        char* block = static_cast<char*>(detail::large_alloc(total));
        std::memcpy(block, &total, sizeof total);
        void* data = block + kHeader;
        return {data, data, &free_block, c10::Device(c10::DeviceType::CPU)};
    }
    c10::DeleterFnPtr raw_deleter() const override { return &free_block; }
};

}  // namespace

void use_large_page_tensors() {
    static std::once_flag once;
    std::call_once(once, [] {
        // Never destroyed: tensors that outlive static destruction still free through it.
        static auto* allocator = new LargePageAllocator();
        // Priority 1: above libtorch's default registration (0).
        c10::SetCPUAllocator(allocator, 1);
    });
}

}  // namespace gdr::neural
