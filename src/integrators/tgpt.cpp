// Temporal gradient-domain path tracing: every sample of a frame is a pair of
// G-PT samples, one per half. Half A uses the frame's own seed at the
// previous frame's corresponding pixel, so it repeats the random numbers of
// the previous frame's half B there; half B uses the next frame's seed at the
// pixel itself. Frames stay independent jobs: the temporal difference is
// formed from two frames' files when they are reconstructed together.
#include "gdr/integrators/tgpt.h"

#include <cmath>
#include <vector>

#include "gdr/core/error.h"
#include "gdr/core/sampler.h"
#include "gdr/reconstruct/temporal.h"
#include "gpt_tracer.h"

namespace gdr {

namespace {

constexpr const char* kHalfA = "a:";
constexpr const char* kHalfB = "b:";

class TemporalGradientPathTracer final : public detail::GradientPathTracer {
public:
    explicit TemporalGradientPathTracer(const Params& p) : GradientPathTracer(p, "tgpt") {}

    bool shares_frame_samples() const override { return true; }

protected:
    // Its temporal gradients pair every pixel with the previous frame's: a
    // mask of spatial gradients alone is not defined for it.
    bool takes_gradient_mask() const override { return false; }

    std::vector<SlotSpec> slots() const override {
        std::vector<SlotSpec> s = half_slots(kHalfA);
        for (SlotSpec& b : half_slots(kHalfB)) s.push_back(std::move(b));
        return s;
    }

    // The half samplers are keyed by the job's sample number.
    bool jobs_only() const override { return true; }

    void begin_render(const Scene& scene, const RenderSettings& st) override {
        const int W = scene.camera().width(), H = scene.camera().height();
        seed_a_ = st.seed;
        // A still has no next frame: any seed other than the first half's will do.
        seed_b_ = st.frame_sampling ? st.frame_sampling->next_seed : mix64(st.seed ^ 0x74677074ull);
        if (seed_b_ == seed_a_)
            throw ParameterError("tgpt: the next frame's seed equals this frame's (" + std::to_string(seed_a_) +
                                 "), so both halves would be the same samples");
        replay_.assign(size_t(W) * size_t(H), kOwn);
        replay_image_ = Image(W, H, 2);
        std::fill(replay_image_.values().begin(), replay_image_.values().end(), -1.f);
        if (!st.frame_sampling || st.frame_sampling->replay.empty()) return;
        const Image& r = st.frame_sampling->replay;
        if (r.width() != W || r.height() != H || r.channels() != 2)
            throw ParameterError("tgpt: the replay map is " + std::to_string(r.width()) + "x" +
                                 std::to_string(r.height()) + " with " + std::to_string(r.channels()) +
                                 " channels, not " + std::to_string(W) + "x" + std::to_string(H) + " with 2");
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const float qx = r.at(x, y, 0), qy = r.at(x, y, 1);
                if (qx == -1.f && qy == -1.f) continue;
                if (!(qx >= 0.f && qy >= 0.f && qx < float(W) && qy < float(H)) || qx != std::floor(qx) ||
                    qy != std::floor(qy))
                    throw ParameterError("tgpt: the replay map holds (" + std::to_string(qx) + ", " +
                                         std::to_string(qy) + ") at pixel (" + std::to_string(x) + ", " +
                                         std::to_string(y) + "): neither a pixel nor (-1, -1)");
                replay_[size_t(y) * W + x] = uint32_t(qy) * uint32_t(W) + uint32_t(qx);
                replay_image_.at(x, y, 0) = qx, replay_image_.at(x, y, 1) = qy;
            }
    }

    void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        SampleJob half[kMaxBatch];
        const int W = scene.camera().width();
        for (int j = 0; j < n; ++j) {
            const SampleJob& job = jobs[j];
            const uint32_t q = replay_[size_t(job.y) * W + job.x];
            const uint32_t qx = q == kOwn ? uint32_t(job.x) : q % uint32_t(W);
            const uint32_t qy = q == kOwn ? uint32_t(job.y) : q / uint32_t(W);
            // The sample stays in its own pixel: only its random numbers are the previous frame's.
            half[j] = job;
            half[j].sampler = Sampler(SampleKey{seed_a_, qx, qy, job.index});
        }
        GradientPathTracer::sample_batch(scene, half, n, out, stride, rays);
        for (int j = 0; j < n; ++j)
            half[j].sampler = Sampler(SampleKey{seed_b_, uint32_t(jobs[j].x), uint32_t(jobs[j].y), jobs[j].index});
        GradientPathTracer::sample_batch(scene, half, n, out + half_floats(), stride, rays);
    }

    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        const int W = out.width(), H = out.height();
        detail::GradientHalf a = finalize_half(acc, kHalfA), b = finalize_half(acc, kHalfB);
        const std::string A = kHalfA, B = kHalfB;
        std::vector<Image> im = acc.images({{A + "direct"}, {B + "direct"}, {A + "albedo"}, {B + "albedo"},
                                            {A + "normal"}, {B + "normal"}, {A + "depth"}, {B + "depth"}});
        // A sample is one path in each half: its value is the halves' mean, whose
        // per-sample variance is a quarter of the sum of theirs (independent halves).
        const auto mean = [](const Image& u, const Image& v) {
            Image m(u.width(), u.height(), u.channels());
            for (size_t i = 0; i < m.values().size(); ++i) m.values()[i] = 0.5f * (u.values()[i] + v.values()[i]);
            return m;
        };
        const auto mean_var = [](const Image& u, const Image& v) {
            Image m(u.width(), u.height(), u.channels());
            for (size_t i = 0; i < m.values().size(); ++i) m.values()[i] = 0.25f * (u.values()[i] + v.values()[i]);
            return m;
        };
        Image primal = mean(a.primal, b.primal), direct = mean(im[0], im[1]);
        Image color(W, H, 3);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) color.set_rgb(x, y, primal.rgb(x, y) + direct.rgb(x, y));
        out.set("color", std::move(color));
        out.set("primal", std::move(primal));
        out.set("dx", mean(a.dx, b.dx));
        out.set("dy", mean(a.dy, b.dy));
        out.set("direct", std::move(direct));
        out.set("primal_variance", mean_var(a.primal_var, b.primal_var));
        out.set("dx_variance", mean_var(a.dx_var, b.dx_var));
        out.set("dy_variance", mean_var(a.dy_var, b.dy_var));
        if (acc.adaptive()) out.set("spp", acc.count_image());
        out.set(temporal_layers::primal_a, std::move(a.primal));
        out.set(std::string(temporal_layers::primal_a) + "_variance", std::move(a.primal_var));
        out.set(temporal_layers::primal_b, std::move(b.primal));
        out.set(std::string(temporal_layers::primal_b) + "_variance", std::move(b.primal_var));
        out.set(temporal_layers::replay, replay_image_);
        out.set("albedo", mean(im[2], im[3]));
        out.set("normal", mean(im[4], im[5]));
        out.set("depth", mean(im[6], im[7]));
    }

private:
    static constexpr uint32_t kOwn = ~0u;  // replay_ entry of a pixel that uses its own numbers
    uint64_t seed_a_ = 0, seed_b_ = 0;
    std::vector<uint32_t> replay_;  // per pixel: the previous frame's pixel index whose numbers half A uses
    Image replay_image_;            // the same as the layer the frame stores
};

}  // namespace

void register_tgpt(Registry<Integrator>& r) {
    r.add("tgpt",
          "temporal gradient-domain path tracing: two seed-shared G-PT halves per frame; one spp is one G-PT sample "
          "per half (params: as gpt)",
          [](const Params& p) { return std::make_unique<TemporalGradientPathTracer>(p); });
}

}  // namespace gdr
