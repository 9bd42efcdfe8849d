// Overwriting an existing record with a function's result without a copy: a
// performance device of the path walks, internal to the library (its
// headers' templates use it, so it is installed, in gdr::detail).
#pragma once

#include <new>
#include <type_traits>
#include <utility>

namespace gdr::detail {

/// Replaces `dst` with the value `make()` returns, built directly in `dst`.
/// Why: `dst = f()` builds f's result in a temporary and copies it 16 bytes
/// at a time right after f wrote it field by field; those loads cannot take
/// their data from the pending narrower stores (a store-forwarding stall of
/// over ten cycles), which showed in the hot loops of path tracing and
/// shifting. A prvalue initialising `dst` leaves no temporary to copy.
template <typename T, typename Make>
void assign_in_place(T& dst, Make&& make) {
    static_assert(std::is_trivially_destructible_v<T>, "the old value is overwritten without its destructor");
    ::new (static_cast<void*>(&dst)) T(std::forward<Make>(make)());
}

}  // namespace gdr::detail
