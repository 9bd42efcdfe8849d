// The four neighbour directions of gradient-domain integrators and the
// order of their per-sample slots, shared by gpt, tgpt and gbdpt. Internal
// to the library.
#pragma once

namespace gdr::detail {

constexpr int kDirs = 4;  ///< Neighbours a base path is shifted to: +x, -x, +y, -y.
const int kDx[kDirs] = {1, -1, 0, 0};  ///< Column step of each direction (pixels).
const int kDy[kDirs] = {0, 0, 1, -1};  ///< Row step of each direction (pixels, y down).
const char* const kGradSlot[kDirs] = {"g+x", "g-x", "g+y", "g-y"};   ///< One-sided gradient slot names.
const char* const kSplatSlot[kDirs] = {"s+x", "s-x", "s+y", "s-y"};  ///< Offset-share slot names.
// First RGB triple of each slot in a sample's output (slots() order), then
// albedo, normal and depth (7 floats) from triple kAux.
constexpr int kSelf = 0, kGrad = 1, kSplat = kGrad + kDirs, kDirect = kSplat + kDirs, kAux = kDirect + 1;

}  // namespace gdr::detail
