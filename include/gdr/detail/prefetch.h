// A cache-line prefetch: a performance device of the scene's light sampling,
// internal to the library (the scene's inline functions use it, so it is
// installed, in gdr::detail).
#pragma once

namespace gdr::detail {

/// Starts loading the cache line holding `p` into every cache level. An
/// instruction the optimiser cannot drop: GCC discards __builtin_prefetch in
/// some inlined contexts at -O2.
inline void prefetch(const void* p) {
#if defined(__x86_64__) || defined(__i386__)
    asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#else
    __builtin_prefetch(p);
#endif
}

}  // namespace gdr::detail
