// Unidirectional path tracing with next-event estimation and multiple
// importance sampling (power heuristic) between light and BSDF sampling, on
// the path-space core: the camera subpath's walk (path/walk.h) and, at each
// of its vertices, the two connections of a path tracer (connection.h): the
// emitter the walk hit (s = 0) and the vertex's light sample (s = 1).
#include <tuple>

#include "gdr/detail/in_place.h"
#include "gdr/path/connection.h"
#include "gdr/path/dims.h"
#include "gdr/path/walk.h"
#include "gdr/integrators/pt.h"
#include "gdr/integrators/tiled.h"

namespace gdr {

namespace {


// Most camera rays traced as one Embree packet.
constexpr int kPacket = 8;

class PathTracer final : public TiledIntegrator {
public:
    explicit PathTracer(const Params& p) {
        std::tie(max_depth_, rr_depth_) = depth_params(p, "pt");
        nee_ = p.get_bool("nee", true);
        batch_ = batch_param(p, "pt", kPacket);
    }

    std::string describe() const override {
        return "max_depth=" + std::to_string(max_depth_) + "\nrr_depth=" + std::to_string(rr_depth_) +
               "\nnee=" + (nee_ ? "true" : "false") + "\n";
    }

protected:
    std::vector<SlotSpec> slots() const override {
        return {{"color", 3, true}, {"albedo", 3, false}, {"normal", 3, false}, {"depth", 1, false}};
    }

    int batch_size() const override { return batch_; }

    void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        // Camera rays go as one packet: consecutive jobs are samples of one
        // pixel, or of neighbouring pixels in a row, so they share traversal
        // (and often the hit triangle, whose frame is then computed once).
        // A lone ray goes as a packet too: the packet kernel's last-bit
        // rounding differs from the single-ray kernel's, so every camera ray
        // takes the same kernel and images do not depend on the batch size.
        // Each job's camera ray is traced straight into the first hit record
        // of its subpath.
        thread_local Subpath paths[kPacket];
        Ray ray[kPacket];
        SurfaceInteraction* sip[kPacket];
        bool active[kPacket], hit[kPacket];
        const PathOptions opt{max_depth_, rr_depth_, nee_};
        for (int base = 0; base < n; base += kPacket) {
            const int m = std::min(kPacket, n - base);
            for (int j = 0; j < kPacket; ++j) {
                active[j] = j < m;
                if (!active[j]) {
                    ray[j] = ray[0];  // a packet's idle lanes are still read
                    sip[j] = sip[0];
                    continue;
                }
                Sampler& sampler = jobs[base + j].sampler;
                sampler.set_dimension(dims::kFilm);
                const Vec2 film = Vec2(float(jobs[base + j].x), float(jobs[base + j].y)) + sampler.next2d();
                detail::assign_in_place(ray[j], [&] { return scene.camera().generate_ray(film); });
                sip[j] = begin_camera_subpath(scene, ray[j], paths[j]);
                // The first vertex's light prefetch, which the walk otherwise
                // does a vertex ahead: the packet's traversal hides the load.
                if (nee_ && scene.light_prefetch_pays())
                    scene.prefetch_light(sampler.at(dims::vertex(1) + dims::kLightSelect));
            }
            scene.intersect8(ray, active, sip, hit);
            PathResult results[kPacket];
            for (int j = 0; j < m; ++j)
                results[j] = trace_path_from(scene, ray[j], jobs[base + j].sampler, opt, paths[j], hit[j]);
            for (int j = 0; j < m; ++j) {
                const PathResult& r = results[j];
                rays += r.rays;
                float* o = out + size_t(base + j) * stride;
                o[0] = r.radiance.r, o[1] = r.radiance.g, o[2] = r.radiance.b;
                o[3] = r.albedo.r, o[4] = r.albedo.g, o[5] = r.albedo.b;
                o[6] = r.normal.x, o[7] = r.normal.y, o[8] = r.normal.z;
                o[9] = r.depth;
            }
        }
    }

    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        std::vector<Image> im = acc.images({{"color"}, {"albedo"}, {"normal"}, {"depth"}, {"color", true}});
        out.set("color", std::move(im[0]));
        out.set("albedo", std::move(im[1]));
        out.set("normal", std::move(im[2]));
        out.set("depth", std::move(im[3]));
        out.set("variance", std::move(im[4]));
    }

private:
    int max_depth_ = -1, rr_depth_ = 5;
    bool nee_ = true;
    int batch_ = kPacket;  // jobs per sample_batch(); does not change images
};

}  // namespace

template PathResult trace_path_from(const Scene&, const Ray&, const Sampler&, const PathOptions&, Subpath&, bool);
template PathResult trace_path(const Scene&, Ray, Sampler&, const PathOptions&);

void register_pt(Registry<Integrator>& r) {
    r.add("pt", "path tracing with next-event estimation and MIS (params: max_depth, rr_depth, nee, batch)",
          [](const Params& p) { return std::make_unique<PathTracer>(p); });
}

}  // namespace gdr
