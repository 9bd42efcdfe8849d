// The packet variants of shift_camera_path(): the camera rays of a base path
// and of its four offsets (and of several samples) traced as Embree packets,
// which share BVH traversal because neighbouring pixels' rays are coherent.
// A performance device of gpt, internal to the library; each gives what the
// plain calls of gdr/shift/offset_path.h give, up to the packets' rounding
// (tests/test_gpt.cpp compares them).
#pragma once

#include "gdr/shift/offset_path.h"

namespace gdr {

/// shift_camera_path() to the pixels displaced by pixel_offsets[i] for each i
/// with active[i] (out[i] is left empty otherwise), tracing the offsets'
/// primary rays as one packet: neighbouring pixels' rays are coherent, so
/// they share BVH traversal. Gives the offset paths of four calls, up to
/// Scene::intersect4's rounding and choice between coincident triangles.
void shift_camera_paths4(const Scene& scene, const Shift& shift, const ShiftConfig& config, const CameraPath& base,
                         const Vec2 pixel_offsets[4], const bool active[4], OffsetPath out[4]);

/// The camera rays of a base path (lane 0) and of its four offsets (lanes
/// 1-4), with which were traced and which hit; lanes 5-7 are unused.
struct CameraPacket {
    Ray rays[8];           ///< Camera rays (world space, scene units).
    bool traced[8] = {};   ///< The lane's ray was cast.
    bool hit[8] = {};      ///< The lane's ray hit; its hit is in the first record of its path.
};

/// The first stage of trace_and_shift_camera_paths4(): resets `base` and
/// `out`, and traces the base's camera ray through `film` and those of its
/// active offsets as one packet into their first records.
void trace_camera_packet(const Scene& scene, const Vec2& film, CameraPath& base, const Vec2 pixel_offsets[4],
                         const bool active[4], OffsetPath out[4], CameraPacket& packet);

/// Most samples trace_camera_packets() takes at once.
constexpr int kMaxCameraBatch = 16;

/// trace_camera_packet() of n <= kMaxCameraBatch samples (sample j: film[j],
/// base[j], the four flags active[j], the four offsets out[j], packet[j]),
/// their camera rays traced as full
/// packets of eight grouped by lane (all bases, then each offset direction):
/// five packets for eight samples instead of eight. Gives what n calls give.
void trace_camera_packets(const Scene& scene, int n, const Vec2* film, CameraPath* base, const Vec2 pixel_offsets[4],
                          const bool* const* active, OffsetPath* const* out, CameraPacket* packet);

/// The last stage of trace_and_shift_camera_paths4(), after
/// continue_camera_path() of the base from packet lane 0: walks the offsets
/// on from their camera hits, their shadow segments traced as packets.
void shift_from_camera_packet(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                              const CameraPath& base, const CameraPacket& packet, OffsetPath out[4]);

/// trace_camera_path() of the base through `film`, then shift_camera_paths4()
/// of it, with the base's camera ray traced in the same packet as its
/// offsets' (Scene::intersect8). Gives what those two calls give, up to that
/// packet's rounding. An offset whose base is empty (its camera ray missed) is
/// left with no vertices, but its camera ray was cast and counted in `rays`.
void trace_and_shift_camera_paths4(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                                   const Vec2& film, const Sampler& sampler, const WalkOptions& opt, CameraPath& base,
                                   const Vec2 pixel_offsets[4], const bool active[4], OffsetPath out[4]);

}  // namespace gdr
