#include "gdr/shift/offset_path.h"
#include "offset_packets.h"

#include "gdr/core/error.h"
#include "gdr/detail/in_place.h"
#include "gdr/path/trace.h"
#include "gdr/shift/builtin.h"
#include "gdr/shift/half_vector.h"
#include "gdr/shift/reconnection.h"
#include "gdr/shift/replay.h"
#include "gdr/shift/steps.h"

namespace gdr {

namespace {

using DeferredVisibility = detail::DeferredVisibility<Scene>;
using detail::complete_offset;
using detail::finish_offset;
using detail::reset;
using detail::start_offset;

// complete_offset() of the traced ones of four offsets, their shadow
// segments traced as packets: they start at neighbouring points and mostly
// end at the base's light points and next vertices, so they share traversal.
void complete_offsets4(const Scene& scene, const Shift& shift, const ShiftConfig& config, const CameraPath& base,
                       const Ray rays[4], const bool traced[4], const bool hit[4], OffsetPath out[4]) {
    DeferredVisibility defer;
    for (int i = 0; i < 4; ++i)
        if (traced[i]) complete_offset(scene, shift, config, base, rays[i], hit[i], out[i], &defer);
    defer.resolve(scene);
    for (int i = 0; i < 4; ++i)
        if (traced[i]) finish_offset(base, out[i]);
}

}  // namespace

template void shift_camera_path(const Scene&, const Shift&, const ShiftConfig&, const CameraPath&, const Vec2&,
                                OffsetPath&);

void shift_camera_paths4(const Scene& scene, const Shift& shift, const ShiftConfig& config, const CameraPath& base,
                         const Vec2 pixel_offsets[4], const bool active[4], OffsetPath out[4]) {
    Ray rays[4];
    SurfaceInteraction* si[4];
    bool traced[4], hit[4];
    for (int i = 0; i < 4; ++i) {
        reset(out[i]);
        traced[i] = active[i] && base.size() > 1;
        si[i] = traced[i] ? start_offset(scene, base.film, pixel_offsets[i], out[i], rays[i]) : nullptr;
    }
    scene.intersect4(rays, traced, si, hit);  // the hits are written into the first records
    complete_offsets4(scene, shift, config, base, rays, traced, hit, out);
}

void trace_camera_packet(const Scene& scene, const Vec2& film, CameraPath& base, const Vec2 pixel_offsets[4],
                         const bool active[4], OffsetPath out[4], CameraPacket& packet) {
    // A batch of one: its five rays share one packet.
    trace_camera_packets(scene, 1, &film, &base, pixel_offsets, &active, &out, &packet);
}

void trace_camera_packets(const Scene& scene, int n, const Vec2* film, CameraPath* base, const Vec2 pixel_offsets[4],
                          const bool* const* active, OffsetPath* const* out, CameraPacket* packet) {
    // Lane l of every sample's packet, then lane l + 1: the samples of a batch
    // are mostly of one pixel, so each group (all bases, all +x offsets, ...)
    // is as coherent as camera rays get.
    struct Lane {
        CameraPacket* packet;
        int lane;
        SurfaceInteraction* si;
    };
    if (n < 0 || n > kMaxCameraBatch)
        throw ParameterError("trace_camera_packets: n must be between 0 and " + std::to_string(kMaxCameraBatch) +
                             ", got " + std::to_string(n));
    Lane lanes[5 * kMaxCameraBatch];
    int m = 0;
    SurfaceInteraction* first[kMaxCameraBatch][5];
    for (int j = 0; j < n; ++j) {
        CameraPacket& p = packet[j];
        for (int i = 0; i < 8; ++i) p.traced[i] = false, p.hit[i] = false;
        first[j][0] = begin_camera_path(scene, film[j], base[j], p.rays[0]);
        p.traced[0] = true;
        for (int i = 0; i < 4; ++i) {
            reset(out[j][i]);
            p.traced[1 + i] = active[j][i];
            first[j][1 + i] = active[j][i] ? start_offset(scene, film[j], pixel_offsets[i], out[j][i], p.rays[1 + i]) : nullptr;
        }
    }
    for (int l = 0; l < 5; ++l)
        for (int j = 0; j < n; ++j)
            if (packet[j].traced[l]) lanes[m++] = {&packet[j], l, first[j][l]};
    for (int b = 0; b < m; b += 8) {
        Ray rays[8];
        bool act[8], hit[8];
        SurfaceInteraction* si[8];
        for (int i = 0; i < 8; ++i) {
            act[i] = b + i < m;
            const Lane& L = lanes[act[i] ? b + i : b];  // idle lanes repeat a ray; they are not traced
            rays[i] = L.packet->rays[L.lane];
            si[i] = act[i] ? L.si : nullptr;
        }
        scene.intersect8(rays, act, si, hit);
        for (int i = 0; i < 8 && b + i < m; ++i) lanes[b + i].packet->hit[lanes[b + i].lane] = hit[i];
    }
}

void shift_from_camera_packet(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                              const CameraPath& base, const CameraPacket& packet, OffsetPath out[4]) {
    complete_offsets4(scene, shift, config, base, packet.rays + 1, packet.traced + 1, packet.hit + 1, out);
}

void trace_and_shift_camera_paths4(const Scene& scene, const Shift& shift, const ShiftConfig& config,
                                   const Vec2& film, const Sampler& sampler, const WalkOptions& opt, CameraPath& base,
                                   const Vec2 pixel_offsets[4], const bool active[4], OffsetPath out[4]) {
    CameraPacket packet;
    trace_camera_packet(scene, film, base, pixel_offsets, active, out, packet);
    continue_camera_path(scene, sampler, opt, base, packet.rays[0], packet.hit[0]);
    if (config.probabilistic) draw_classification_numbers(scene, sampler, opt.max_vertices, base);
    shift_from_camera_packet(scene, shift, config, base, packet, out);
}

void register_builtin_shifts(Registry<Shift>& r) { register_builtin_shifts_on(r); }

std::vector<std::unique_ptr<Shift>> make_shifts(const Params& p, const std::vector<std::string>& names,
                                                std::string& stored) {
    const std::vector<Params> parts = p.parts("shift", names);
    std::vector<std::unique_ptr<Shift>> out;
    for (size_t i = 0; i < names.size(); ++i) {
        out.push_back(shift_registry().create(names[i], parts[i]));
        for (const auto& [key, value] : parts[i].values()) stored += parts[i].key_prefix() + key + "=" + to_string(value) + "\n";
    }
    return out;
}

Registry<Shift>& shift_registry() {
    return process_registry<Shift>("shift mapping", register_builtin_shifts);
}

}  // namespace gdr
