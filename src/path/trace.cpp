// gdr's own Scene's instances of the camera-path templates (gdr/path/trace.h).
#include "gdr/path/trace.h"

namespace gdr {

template SurfaceInteraction* begin_camera_path(const Scene&, const Vec2&, CameraPath&, Ray&);
template void continue_camera_path(const Scene&, const Sampler&, const WalkOptions&, CameraPath&, const Ray&, bool);
template void trace_camera_path(const Scene&, const Vec2&, const Sampler&, const WalkOptions&, CameraPath&);

}  // namespace gdr
