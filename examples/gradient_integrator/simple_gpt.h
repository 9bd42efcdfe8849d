// A gradient-domain path tracer written outside gdr on its public film
// (gdr/integrators/gradient_film.h): one base path per sample, shifted to its
// four neighbours with any registered shift one at a time, each pair weighed
// by gdr's gradient MIS. gdr's own gpt computes the same estimates with
// packets of rays and batches of samples; this one keeps to the plain
// per-sample interface, which is all a new gradient-domain estimator needs to
// start from. Included by the example's main.cpp and by gdr's tests, which
// check that it equals gpt in expectation.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gdr/integrators/gpt.h"
#include "gdr/integrators/gradient_film.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/shift/offset_path.h"
#include "gdr/shift/shift.h"

namespace example {

/// "simple-gpt": G-PT on the public film. Parameters: shift (a registered
/// shift's name, default half-vector), max_depth, rr_depth, and the
/// reconstructions' (reconstruct, alpha, reconstruct.KEY) as gpt's.
class SimpleGradientPathTracer final : public gdr::TiledIntegrator {
public:
    /// Reads the parameters; throws gdr::ParameterError naming a bad one.
    explicit SimpleGradientPathTracer(const gdr::Params& p)
        : shift_name_(p.get_string("shift", "half-vector")),
          shift_(gdr::shift_registry().create(shift_name_, gdr::Params())),
          recon_(gdr::GradientReconstructions::from(p, "simple-gpt")) {
        std::tie(walk_.max_vertices, walk_.rr_depth) = depth_params(p, "simple-gpt");
        // G-PT's MIS reads solid-angle densities only.
        walk_.reverse_densities = false, walk_.forward_densities = false;
    }

    std::string describe() const override {
        return "shift=" + shift_name_ + "\nmax_depth=" + std::to_string(walk_.max_vertices) +
               "\nrr_depth=" + std::to_string(walk_.rr_depth) + "\n" + recon_.describe();
    }

    /// The reconstructions, run after the render and after a merge.
    void update_merged(gdr::FrameBuffer& merged) const override { recon_.add(merged, 0, "simple-gpt"); }

protected:
    std::vector<gdr::SlotSpec> slots() const override { return layout_.slots(); }

    // render() hands over one sample at a time (batch_size() is 1).
    void sample_batch(const gdr::Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        for (int i = 0; i < n; ++i) sample(scene, jobs[i].x, jobs[i].y, jobs[i].sampler, out + size_t(i) * stride, rays);
    }

    void sample(const gdr::Scene& scene, int x, int y, gdr::Sampler& sampler, float* out,
                uint64_t& rays) const {
        using namespace gdr;
        GradientRecord rec(out, layout_);
        sampler.set_dimension(dims::kFilm);
        const Vec2 film = Vec2(float(x), float(y)) + sampler.next2d();
        CameraPath path;
        trace_camera_path(scene, film, sampler, walk_, path);
        rays += path.rays;
        if (path.size() <= 1) return;  // the camera ray left the scene without an emitter behind it
        BaseTerms terms;
        compute_base_terms(scene, path, mis_.heuristic, terms);
        const int W = scene.camera().width(), H = scene.camera().height();
        for (int d = 0; d < kNeighbours; ++d) {
            const int nx = x + kNeighbourDx[d], ny = y + kNeighbourDy[d];
            if (nx < 0 || ny < 0 || nx >= W || ny >= H) {
                // No neighbour at the border: the base alone estimates its quarter.
                rec.add_alone(evaluate_pair(scene, path, terms, nullptr, mis_).base);
                continue;
            }
            OffsetPath offset;
            shift_camera_path(scene, *shift_, config_, path, Vec2(float(kNeighbourDx[d]), float(kNeighbourDy[d])),
                              offset);
            rays += offset.rays;
            const PairEstimate e = evaluate_pair(scene, path, terms, &offset, mis_);
            rec.add_pair(d, e.base, e.offset, e.gradient);
        }
        rec.add_direct(terms.v[1].emitted);  // directly visible emitters stay out of the gradients
        if (!path.v[1].infinite) {
            const Vertex& v = path.v[1];
            rec.set_surface(v.si.material->bsdf->albedo(v.si.uv), v.si.frame.n);
            rec.set_depth(v.si.t);
        }
    }

    void finalize(const gdr::Accumulated& acc, gdr::FrameBuffer& out) const override {
        gdr::set_gradient_layers(out, gdr::gather_gradients(acc, layout_), acc, layout_);
    }

private:
    std::string shift_name_;
    std::unique_ptr<gdr::Shift> shift_;
    gdr::GradientReconstructions recon_;
    gdr::ShiftConfig config_;
    gdr::GradientMis mis_;
    gdr::WalkOptions walk_;
    gdr::GradientLayout layout_ = gdr::GradientLayout::make();
};

/// Registers "simple-gpt" in gdr's integrator registry.
inline void register_simple_gpt() {
    gdr::integrator_registry().add(
        "simple-gpt", "G-PT written outside gdr on the public gradient film (params: shift, max_depth, rr_depth, "
                      "reconstruct)",
        [](const gdr::Params& p) { return std::make_unique<SimpleGradientPathTracer>(p); });
}

}  // namespace example
