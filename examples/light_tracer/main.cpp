// A light tracer written outside gdr on its public path-space core: light
// subpaths start on the emitters (trace_light_subpath), every vertex is
// joined to the camera by the core's t = 1 connection, and the film takes
// the result wherever it lands (splat_layers, SplatList). Emitters the camera
// sees directly come from the pixel's own ray, the (0, 2) connection. The
// program renders a scene with it and with the built-in path tracer and
// checks that the two images agree.
//
//   light_tracer SCENE.json OUT.exr [--spp N]
#include <cmath>
#include <cstdio>
#include <string>

#include "gdr/path/dims.h"
#include "gdr/integrators/tiled.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/path/connection.h"

namespace {

/// Light tracing (radiance, W/(m^2 sr)); parameter max_depth (segments, -1 unlimited).
class LightTracer final : public gdr::TiledIntegrator {
public:
    explicit LightTracer(const gdr::Params& p) : max_depth_(depth_params(p, "lighttracer").first) {}
    std::string describe() const override { return "max_depth=" + std::to_string(max_depth_) + "\n"; }

protected:
    std::vector<gdr::SlotSpec> slots() const override { return {{"color", 3, false}}; }
    int splat_layers() const override { return 1; }

    void sample_batch(const gdr::Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        using namespace gdr;
        thread_local Subpath camera, light;
        for (int j = 0; j < n; ++j) {
            const Sampler& sampler = jobs[j].sampler;
            const Vec2 film = Vec2(float(jobs[j].x), float(jobs[j].y)) + sampler.at2(dims::kFilm);
            trace_camera_subpath(scene, film, sampler, {1, 5}, camera);  // the camera and its first hit
            trace_light_subpath(scene, sampler, {max_depth_ > 0 ? max_depth_ - 1 : -1, 5}, light);
            rays += camera.rays + light.rays;
            if (camera.size() == 2) {
                const Color le = connect(scene, light, camera, {0, 2}, sampler, {}, false, rays).value;
                out[size_t(j) * stride + 0] = le.r, out[size_t(j) * stride + 1] = le.g, out[size_t(j) * stride + 2] = le.b;
            }
            for (int s = 2; s <= light.size(); ++s) {
                const ConnectionResult c = connect(scene, light, camera, {s, 1}, sampler, {}, false, rays);
                if (!is_black(c.value)) jobs[j].splats->add(c.film, c.value);
            }
        }
    }

    void finalize(const gdr::Accumulated& acc, gdr::FrameBuffer& out) const override {
        gdr::Image color = acc.images({{"color"}})[0];
        for (int y = 0; y < acc.height; ++y)
            for (int x = 0; x < acc.width; ++x)
                for (int c = 0; c < 3; ++c) color.at(x, y, c) += acc.splat_mean(0, x, y)[c];
        out.set("color", std::move(color));
    }

private:
    int max_depth_;
};

double mean_of(const gdr::Image& img) {
    double sum = 0;
    for (float v : img.values()) sum += v;
    return sum / double(img.values().size());
}

}  // namespace

int main(int argc, char** argv) {
    if (!(argc == 3 || (argc == 5 && std::string(argv[3]) == "--spp"))) {
        std::fprintf(stderr, "usage: light_tracer SCENE.json OUT.exr [--spp N]\n");
        return 2;
    }
    try {
        gdr::integrator_registry().add("lighttracer", "light tracing (params: max_depth)",
                                       [](const gdr::Params& p) { return std::make_unique<LightTracer>(p); });
        gdr::SceneFile sf = gdr::load_scene_file(argv[1]);
        gdr::set_resolution(sf, 64, 64);
        gdr::RenderSettings st;
        st.spp = argc == 5 ? std::stoll(argv[4]) : 64;
        gdr::FrameBuffer lt, pt;
        gdr::integrator_registry().create("lighttracer", gdr::Params())->render(*sf.scene, st, lt);
        gdr::write_exr(argv[2], lt);
        st.seed = 1;
        gdr::integrator_registry().create("pt", gdr::Params())->render(*sf.scene, st, pt);
        // The image means agree to within their noise (about 1% at 64 spp on the Cornell box).
        const double a = mean_of(lt.get("color")), b = mean_of(pt.get("color"));
        std::printf("light tracer mean %.5f, path tracer mean %.5f, ratio %.4f\n", a, b, a / b);
        if (!(std::abs(a / b - 1.0) < 0.03)) {
            std::fprintf(stderr, "light_tracer: the light-traced image does not match the path tracer's\n");
            return 1;
        }
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "light_tracer: error: %s\n", e.what());
        return 1;
    }
}
