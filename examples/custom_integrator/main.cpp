// An integrator written outside gdr: ambient occlusion ("ao"). It derives from
// gdr::TiledIntegrator, so it inherits the parallel tile loop, deterministic
// per-pixel sample streams, time budgets, resume, NaN accounting and variance
// layers; it only says what one sample computes. Registered by name in
// gdr::integrator_registry(), it is then rendered through the same code path
// as `gdr render --integrator ao`, and the image it writes is checked. That
// step calls the tool's own commands, gdr::cli::run, so the example links the
// tool's command library (gdr_cli_lib, in gdr's build tree) besides gdr::gdr.
//
//   custom_integrator SCENE.json OUT.exr [--spp N]
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/integrators/tiled.h"
#include "gdr/io/exr.h"
#include "gdr/scene/warp.h"

namespace {

/// Ambient occlusion: the fraction of cosine-weighted directions above the
/// first hit that reach `radius` (scene units) without hitting anything; 1 for
/// camera rays that miss. Parameters: radius (default a quarter of the scene's
/// bounding radius), rays (occlusion rays per sample, default 1).
class AmbientOcclusion final : public gdr::TiledIntegrator {
public:
    explicit AmbientOcclusion(const gdr::Params& p)
        : radius_param_(p.get_real("radius", -1.0)) {
        // Checked before narrowing to int: 4294967297 rays must not become 1.
        const long long rays = p.get_int("rays", 1);
        if (rays < 1 || rays > 1024) throw gdr::ParameterError("ao: rays must be between 1 and 1024");
        rays_ = int(rays);
        // -1 (the default) asks for a quarter of the scene's radius; NaN or 0 are errors, not that default.
        if (!(radius_param_ > 0.0) && radius_param_ != -1.0)
            throw gdr::ParameterError("ao: radius must be positive (or omitted)");
    }

    std::string describe() const override {
        return "radius=" + std::to_string(radius_param_) + "\nrays=" + std::to_string(rays_) + "\n";
    }

protected:
    std::vector<gdr::SlotSpec> slots() const override { return {{"color", 3, true}}; }

    // The default radius depends on the scene, known only here.
    void prepare(const gdr::Scene& scene) override {
        radius_ = radius_param_ > 0.0 ? float(radius_param_) : 0.25f * scene.bounding_radius();
    }

    // render() hands over one sample at a time (batch_size() is 1).
    void sample_batch(const gdr::Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        for (int i = 0; i < n; ++i) sample(scene, jobs[i].x, jobs[i].y, jobs[i].sampler, out + size_t(i) * stride, rays);
    }

    void sample(const gdr::Scene& scene, int x, int y, gdr::Sampler& sampler, float* out, uint64_t& rays) const {
        using namespace gdr;
        const Ray ray = scene.camera().generate_ray(Vec2(float(x), float(y)) + sampler.next2d());
        SurfaceInteraction si;
        ++rays;
        float visible = 1.f;
        if (scene.intersect(ray, si)) {
            // Occlusion is measured on the side the camera sees.
            const bool front = glm::dot(si.ng, -ray.d) > 0.f;
            const Frame frame(front ? si.frame.n : -si.frame.n);
            const Vec3 ng = front ? si.ng : -si.ng;
            int open = 0;
            for (int k = 0; k < rays_; ++k) {
                const Vec3 w = frame.to_world(warp::square_to_cosine_hemisphere(sampler.next2d()));
                if (glm::dot(w, ng) <= 0.f) continue;  // below the geometric surface: blocked
                ++rays;
                open += !scene.occluded(Ray{offset_ray_origin(si.p, ng, w), w, 0.f, radius_});
            }
            visible = float(open) / float(rays_);
        }
        out[0] = out[1] = out[2] = visible;
    }

private:
    double radius_param_;
    int rays_;
    float radius_ = 1.f;
};

}  // namespace

int main(int argc, char** argv) {
    if (!(argc == 3 || (argc == 5 && std::string(argv[3]) == "--spp"))) {
        std::fprintf(stderr, "usage: custom_integrator SCENE.json OUT.exr [--spp N]\n");
        return 2;
    }
    const std::string scene = argv[1], out = argv[2];
    const std::string spp = argc == 5 ? argv[4] : "4";
    try {
        // 1. Register: from now on "ao" is created by name like any built-in.
        gdr::integrator_registry().add("ao", "ambient occlusion (params: radius, rays)",
                                       [](const gdr::Params& p) { return std::make_unique<AmbientOcclusion>(p); });

        // 2. Render through the CLI's own code path: scene file, parameters,
        //    progress, EXR with settings and PNG preview.
        const int rc = gdr::cli::run({"render", scene, "--integrator", "ao", "--spp", spp, "--set", "rays=2", "-o", out});
        if (rc != 0) return rc;

        // 3. Check what was written: AO is in [0, 1], a closed box is mostly
        //    open but its corners are occluded, and the settings were recorded.
        const gdr::FrameBuffer fb = gdr::read_exr(out);
        const gdr::Image& img = fb.get("color");
        double sum = 0, lo = 1, hi = 0;
        for (float v : img.values()) sum += v, lo = std::min<double>(lo, v), hi = std::max<double>(hi, v);
        const double mean = sum / double(img.values().size());
        std::printf("ao: %dx%d, mean %.3f, min %.3f, max %.3f, integrator '%s'\n", img.width(), img.height(), mean, lo, hi,
                    fb.metadata().at("integrator").c_str());
        const bool ok = lo >= 0.0 && hi <= 1.0 && mean > 0.3 && mean < 0.99 && lo < 0.5 &&
                        fb.metadata().at("integrator") == "ao" && fb.has("color_variance");
        if (!ok) {
            std::fprintf(stderr, "custom_integrator: the AO image is implausible\n");
            return 1;
        }
        return 0;
    } catch (const gdr::Error& e) {
        std::fprintf(stderr, "custom_integrator: error: %s\n", e.what());
        return 1;
    }
}
