// The G-PT integrator's class, shared by gpt and tgpt (which renders two
// seed-shared G-PT halves per frame). Internal to the library.
#pragma once

#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include "gdr/integrators/gpt.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/shift/shift.h"
#include "gradient_slots.h"

namespace gdr::detail {

// The optional base-only primal follows the slots of gradient_slots.h at this float.
constexpr int kBaseFloat = 3 * kAux + 7;


/// One G-PT render's primal and gradient estimates and their per-sample
/// variances (radiance, radiance^2), from the slots of one set of G-PT samples.
struct GradientHalf {
    Image primal, primal_var, dx, dy, dx_var, dy_var;
};

/// Gradient-domain path tracing (Kettunen, Manzi, Aittala, Lehtinen, Durand
/// and Zwicker, "Gradient-Domain Path Tracing", 2015). `who` names the
/// integrator in errors and in its reconstructions' parameters.
class GradientPathTracer : public TiledIntegrator {
public:
    explicit GradientPathTracer(const Params& p, std::string who = "gpt") : who_(std::move(who)) {
        const std::string shift_name = p.get_string("shift", "half-vector");
        shift_ = shift_registry().create(shift_name, Params("shift"));
        shift_name_ = shift_name;
        config_.threshold = float(p.get_real("threshold", 0.001));
        config_.probabilistic = p.get_choice("classification", "hard", {"hard", "probabilistic"}) == "probabilistic";
        mis_.heuristic = p.get_choice("mis", "power", {"power", "balance"}) == "power" ? MisHeuristic::Power
                                                                                        : MisHeuristic::Balance;
        std::tie(trace_.max_vertices, trace_.rr_depth) = depth_params(p, who_);
        // G-PT's MIS reads solid-angle densities only.
        trace_.reverse_densities = false, trace_.forward_densities = false;
        trace_.classify_numbers = config_.probabilistic;
        primal_both_ = p.get_choice("primal", "both", {"both", "base"}) == "both";
        batch_ = batch_param(p, who_, kMaxBatch);
        recon_ = GradientReconstructions::from(p, who_);
        if (!(config_.threshold >= 0.f)) throw ParameterError(who_ + ": threshold must be >= 0");
    }

    std::string describe() const override {
        return "shift=" + shift_name_ + "\nthreshold=" + fmt::format("{}", config_.threshold) +
               "\nclassification=" + (config_.probabilistic ? "probabilistic" : "hard") +
               "\nmis=" + (mis_.heuristic == MisHeuristic::Power ? "power" : "balance") +
               "\nmax_depth=" + std::to_string(trace_.max_vertices) + "\nrr_depth=" + std::to_string(trace_.rr_depth) +
               "\nprimal=" + (primal_both_ ? "both" : "base") + "\nreconstruct=" + recon_.choice +
               "\nalpha=" + fmt::format("{}", recon_.alpha) + "\n";
    }

protected:
    std::vector<SlotSpec> slots() const override { return half_slots(""); }

    /// The slots of one set of G-PT samples, each name prefixed with
    /// `prefix`: half_floats() floats of a sample, in the order
    /// sample_batch() writes them.
    std::vector<SlotSpec> half_slots(const std::string& prefix) const {
        // Order fixes the offsets sample() writes to (kSelf, kGrad, ...).
        std::vector<SlotSpec> s{{prefix + "self", 3, true}};
        for (int d = 0; d < kDirs; ++d) s.push_back({prefix + kGradSlot[d], 3, true});
        for (int d = 0; d < kDirs; ++d) s.push_back({prefix + kSplatSlot[d], 3, true});
        s.push_back({prefix + "direct", 3, false});
        s.push_back({prefix + "albedo", 3, false});
        s.push_back({prefix + "normal", 3, false});
        s.push_back({prefix + "depth", 1, false});
        // The base-only primal is accumulated only where it is the output: a
        // slot costs 48 bytes a pixel of accumulators, zeroed every render.
        if (!primal_both_) s.push_back({prefix + "base", 3, true});
        return s;
    }
    /// Floats one sample writes for half_slots().
    int half_floats() const { return kBaseFloat + (primal_both_ ? 0 : 3); }

    void sample(const Scene& scene, int px, int py, Sampler& sampler, float* out, uint64_t& rays) const override {
        SampleJob job{px, py, sampler};
        sample_batch(scene, &job, 1, out, 0, rays);
    }

    int batch_size() const override { return batch_; }

    void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        // A G-PT sample runs through more code (four Embree kernels, the
        // base's tracing, the offsets' walks, the estimates) than the
        // instruction cache holds, so each stage runs for all jobs in turn.
        // Per-thread scratch is kept between calls (no allocation per sample).
        struct Scratch {
            CameraPath path[kMaxBatch];
            OffsetPath offsets[kMaxBatch][kDirs];
            CameraPacket packet[kMaxBatch];
            bool inside[kMaxBatch][kDirs];
            BaseTerms terms;
        };
        thread_local Scratch scratch;
        const int W = scene.camera().width(), H = scene.camera().height();
        Vec2 step[kDirs];
        for (int d = 0; d < kDirs; ++d) step[d] = Vec2(float(kDx[d]), float(kDy[d]));
        Vec2 film[kMaxBatch];
        for (int j = 0; j < n; ++j) {
            Sampler& sampler = jobs[j].sampler;
            const int px = jobs[j].x, py = jobs[j].y;
            sampler.set_dimension(dims::kFilm);
            film[j] = Vec2(float(px), float(py)) + sampler.next2d();
            bool* inside = scratch.inside[j];
            for (int d = 0; d < kDirs; ++d) {
                const int nx = px + kDx[d], ny = py + kDy[d];
                inside[d] = nx >= 0 && ny >= 0 && nx < W && ny < H;
            }
        }
        // The jobs' camera rays and their offsets' as full packets.
        const bool* inside[kMaxBatch];
        OffsetPath* offsets[kMaxBatch];
        for (int j = 0; j < n; ++j) inside[j] = scratch.inside[j], offsets[j] = scratch.offsets[j];
        trace_camera_packets(scene, n, film, scratch.path, step, inside, offsets, scratch.packet);
        for (int j = 0; j < n; ++j)
            continue_camera_path(scene, jobs[j].sampler, trace_, scratch.path[j], scratch.packet[j].rays[0],
                                 scratch.packet[j].hit[0]);
        for (int j = 0; j < n; ++j)
            shift_from_camera_packet(scene, *shift_, config_, scratch.path[j], scratch.packet[j], scratch.offsets[j]);
        for (int j = 0; j < n; ++j) {
            rays += scratch.path[j].rays;
            for (int d = 0; d < kDirs; ++d) rays += scratch.inside[j][d] ? scratch.offsets[j][d].rays : 0;
            estimate(scene, scratch.path[j], scratch.offsets[j], scratch.inside[j], scratch.terms,
                     out + size_t(j) * stride);
        }
    }
    /// The primal and gradients of the samples in the slots named with
    /// `prefix` (see half_slots()): the primal gathers each pixel's own share
    /// and its neighbours' offsets, and dx(x) = I(x+1) - I(x) combines the
    /// pair shifted each way across the edge.
    GradientHalf finalize_half(const Accumulated& acc, const std::string& prefix) const {
        const int W = acc.width, H = acc.height;
        GradientHalf h;
        for (Image* im : {&h.primal, &h.primal_var, &h.dx, &h.dy, &h.dx_var, &h.dy_var}) *im = Image(W, H, 3);
        const int self = acc.slot(prefix + "self");
        int splat[kDirs], grad[kDirs];
        for (int d = 0; d < kDirs; ++d)
            splat[d] = acc.slot(prefix + kSplatSlot[d]), grad[d] = acc.slot(prefix + kGradSlot[d]);
        const int gpx = grad[0], gmx = grad[1], gpy = grad[2], gmy = grad[3];
        // Straight from the sums: the splat and one-sided gradient slots feed
        // only these layers, so they never become images of their own.
        tbb::parallel_for(0, H, [&](int y) {
            for (int x = 0; x < W; ++x) {
                Color p = acc.mean_rgb(self, x, y), pv = acc.variance_rgb(self, x, y);
                // Each neighbour q = (x,y) - step splatted its offset towards (x,y).
                for (int d = 0; d < kDirs; ++d) {
                    const int qx = x - kDx[d], qy = y - kDy[d];
                    if (qx < 0 || qy < 0 || qx >= W || qy >= H) continue;
                    p += acc.mean_rgb(splat[d], qx, qy);
                    pv += acc.variance_rgb(splat[d], qx, qy);
                }
                h.primal.set_rgb(x, y, p);
                h.primal_var.set_rgb(x, y, pv);
                if (x + 1 < W) {
                    h.dx.set_rgb(x, y, acc.mean_rgb(gpx, x, y) - acc.mean_rgb(gmx, x + 1, y));
                    h.dx_var.set_rgb(x, y, acc.variance_rgb(gpx, x, y) + acc.variance_rgb(gmx, x + 1, y));
                }
                if (y + 1 < H) {
                    h.dy.set_rgb(x, y, acc.mean_rgb(gpy, x, y) - acc.mean_rgb(gmy, x, y + 1));
                    h.dy_var.set_rgb(x, y, acc.variance_rgb(gpy, x, y) + acc.variance_rgb(gmy, x, y + 1));
                }
            }
        });
        if (!primal_both_) {
            std::vector<Image> base = acc.images({{prefix + "base"}, {prefix + "base", true}});
            h.primal = std::move(base[0]);
            h.primal_var = std::move(base[1]);
        }
        return h;
    }

    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        const int W = out.width(), H = out.height();
        GradientHalf h = finalize_half(acc, "");
        std::vector<Image> im = acc.images({{"direct"}, {"albedo"}, {"normal"}, {"depth"}});
        Image color(W, H, 3);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) color.set_rgb(x, y, h.primal.rgb(x, y) + im[0].rgb(x, y));
        out.set("color", std::move(color));
        out.set("primal", std::move(h.primal));
        out.set("dx", std::move(h.dx));
        out.set("dy", std::move(h.dy));
        out.set("direct", std::move(im[0]));
        out.set("primal_variance", std::move(h.primal_var));
        out.set("dx_variance", std::move(h.dx_var));
        out.set("dy_variance", std::move(h.dy_var));
        out.set("albedo", std::move(im[1]));
        out.set("normal", std::move(im[2]));
        out.set("depth", std::move(im[3]));
        // Last: a reconstruction may read any layer (neural: albedo, normal, depth).
        if (acc.derived) recon_.add(out, acc.spp, who_);
    }

    /// The reconstructions stored beside the primal and gradients.
    const GradientReconstructions& reconstructions() const { return recon_; }
    /// The integrator's name in errors and reconstruction parameters.
    const std::string& who() const { return who_; }

public:
    void update_merged(FrameBuffer& merged) const override { recon_.add(merged, 0, who_); }

protected:
    // Most samples whose stages run in turn, and the default: 4, 8 and 16
    // ran alike on the Cornell box, about 7% less CPU time per sample than 1.
    static constexpr int kMaxBatch = 8;
    static_assert(kMaxBatch <= kMaxCameraBatch, "a batch's camera rays go through one trace_camera_packets() call");

private:

    // The sample's slots from its traced base path and offsets.
    void estimate(const Scene& scene, const CameraPath& path, const OffsetPath* offsets, const bool* inside,
                  BaseTerms& terms, float* out) const {
        if (path.size() <= 1) return;
        auto put = [&](int slot, const Color& c) {
            out[3 * slot] += c.r, out[3 * slot + 1] += c.g, out[3 * slot + 2] += c.b;
        };
        compute_base_terms(scene, path, mis_.heuristic, terms);
        // The base alone (plain path-tracing MIS) is needed for the base-only primal and at the border.
        PairEstimate alone;
        bool have_alone = false;
        const auto base_alone = [&]() -> const PairEstimate& {
            if (!have_alone) alone = evaluate_pair(scene, path, terms, nullptr, mis_), have_alone = true;
            return alone;
        };
        if (!primal_both_) {
            const Color b = base_alone().base;
            out[kBaseFloat] = b.r, out[kBaseFloat + 1] = b.g, out[kBaseFloat + 2] = b.b;
        }
        for (int d = 0; d < kDirs; ++d) {
            if (!inside[d]) {
                // No neighbour to share with: the base alone estimates its pixel.
                put(kSelf, 0.25f * base_alone().base);
                continue;
            }
            const PairEstimate e = evaluate_pair(scene, path, terms, &offsets[d], mis_);
            put(kSelf, 0.25f * e.base);
            put(kGrad + d, e.gradient);
            put(kSplat + d, 0.25f * e.offset);
        }
        put(kDirect, terms.v[1].emitted);
        // Auxiliary features at the first vertex a reconstruction can use (first connectable one).
        float* aux = out + 3 * kAux;
        for (size_t k = 1; k < path.size(); ++k) {
            const Vertex& v = path.v[k];
            if (v.infinite) break;  // left the scene: no surface
            if (!is_connectable(v.si.material->min_roughness, 0.5f, ShiftConfig{config_.threshold, false}) &&
                &v != &path.v.back())
                continue;
            const Color a = v.si.material->bsdf->albedo(v.si.uv);
            aux[0] = a.r, aux[1] = a.g, aux[2] = a.b;
            aux[3] = v.si.frame.n.x, aux[4] = v.si.frame.n.y, aux[5] = v.si.frame.n.z;
            break;
        }
        aux[6] = path.v[1].infinite ? 0.f : path.v[1].si.t;  // a camera ray that left the scene: 0, as pt writes
    }

    std::unique_ptr<Shift> shift_;
    std::string shift_name_;
    ShiftConfig config_;
    GradientMis mis_;
    WalkOptions trace_;
    bool primal_both_ = true;
    int batch_ = kMaxBatch;
    GradientReconstructions recon_;
    std::string who_;
};

}  // namespace gdr::detail
