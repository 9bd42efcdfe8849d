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
#include "../shift/offset_packets.h"
#include "gdr/integrators/gradient_film.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/shift/shift.h"

namespace gdr::detail {

constexpr int kDirs = kNeighbours;
constexpr const int* kDx = kNeighbourDx;
constexpr const int* kDy = kNeighbourDy;

/// One G-PT render's primal and gradient estimates and their per-sample
/// variances (radiance, radiance^2), from the slots of one set of G-PT samples.
struct GradientHalf : GradientEstimates {
    /// With combined shifts: each shift's own gradients and their variances
    /// (index 0: the first shift), of which dx, dy are the combination.
    Image shift_dx[2], shift_dy[2], shift_dx_var[2], shift_dy_var[2];
};

/// Gradient-domain path tracing (Kettunen, Manzi, Aittala, Lehtinen, Durand
/// and Zwicker, "Gradient-Domain Path Tracing", 2015). `who` names the
/// integrator in errors and in its reconstructions' parameters.
class GradientPathTracer : public TiledIntegrator {
public:
    explicit GradientPathTracer(const Params& p, std::string who = "gpt") : who_(std::move(who)) {
        const std::string shift_name = p.get_string("shift", "half-vector");
        shift_name_ = shift_name;
        if (shift_name == "combined") {
            // Thesis section 4.3.6: several shifts of one base path, their
            // gradients combined by inverse variance in finalize.
            const std::string list = p.get_string("shifts", "half-vector,replay-reconnect");
            const size_t comma = list.find(',');
            if (comma == std::string::npos || list.find(',', comma + 1) != std::string::npos)
                throw ParameterError(who_ + ": shifts must name two shifts, 'first,second', got '" + list + "'");
            combined_names_[0] = list.substr(0, comma), combined_names_[1] = list.substr(comma + 1);
            if (combined_names_[0] == combined_names_[1] || combined_names_[0] == "combined" ||
                combined_names_[1] == "combined")
                throw ParameterError(who_ + ": shifts must name two different registered shifts, got '" + list + "'");
            auto made = make_shifts(p, {combined_names_[0], combined_names_[1]}, shift_params_);
            shift_ = std::move(made[0]), shift2_ = std::move(made[1]);
        } else {
            shift_ = std::move(make_shifts(p, {shift_name}, shift_params_)[0]);
        }
        config_.threshold = float(p.get_real("threshold", 0.001));
        config_.probabilistic = p.get_choice("classification", "hard", {"hard", "probabilistic"}) == "probabilistic";
        mis_.heuristic = p.get_choice("mis", "power", {"power", "balance"}) == "power" ? MisHeuristic::Power
                                                                                        : MisHeuristic::Balance;
        std::tie(trace_.max_vertices, trace_.rr_depth) = depth_params(p, who_);
        // G-PT's MIS reads solid-angle densities only.
        trace_.reverse_densities = false, trace_.forward_densities = false;
        primal_both_ = p.get_choice("primal", "both", {"both", "base"}) == "both";
        batch_ = batch_param(p, who_, kMaxBatch);
        recon_ = GradientReconstructions::from(p, who_);
        if (!(config_.threshold >= 0.f)) throw ParameterError(who_ + ": threshold must be >= 0");
        // Where each slot beyond the standard ones starts in a sample's record.
        const std::vector<SlotSpec> record = half_slots("");
        for (const SlotSpec& spec : record) half_floats_ += spec.channels;
        if (!primal_both_) base_float_ = slot_offset(record, "base");
        if (shift2_)
            for (int d = 0; d < kDirs; ++d) {
                second_float_[d] = slot_offset(record, std::string("2") + GradientLayout::gradient_name(d));
                cross_float_[d] = slot_offset(record, std::string("x") + GradientLayout::gradient_name(d));
            }
    }

    std::string describe() const override {
        return "shift=" + shift_name_ + (shift2_ ? "\nshifts=" + combined_names_[0] + "," + combined_names_[1] : "") +
               "\nthreshold=" + fmt::format("{}", config_.threshold) +
               "\nclassification=" + (config_.probabilistic ? "probabilistic" : "hard") +
               "\nmis=" + (mis_.heuristic == MisHeuristic::Power ? "power" : "balance") +
               "\nmax_depth=" + std::to_string(trace_.max_vertices) + "\nrr_depth=" + std::to_string(trace_.rr_depth) +
               "\nprimal=" + (primal_both_ ? "both" : "base") + "\n" + shift_params_ + recon_.describe();
    }

protected:
    std::vector<SlotSpec> slots() const override { return half_slots(""); }
    bool takes_gradient_mask() const override { return true; }

    /// The slots of one set of G-PT samples, each name prefixed with
    /// `prefix`: half_floats() floats of a sample, in the order
    /// sample_batch() writes them: the film's standard slots, then this
    /// integrator's own.
    std::vector<SlotSpec> half_slots(const std::string& prefix) const {
        std::vector<SlotSpec> s = GradientLayout::make(prefix).slots();
        // The base-only primal is accumulated only where it is the output: a
        // slot costs 48 bytes a pixel of accumulators, zeroed every render.
        if (!primal_both_) s.push_back({prefix + "base", 3, true});
        if (shift2_) {
            // The second shift's one-sided gradients, and the products of the
            // two shifts' (their covariance, which the combination needs:
            // both share the base path's f(x)).
            for (int d = 0; d < kDirs; ++d) s.push_back({prefix + "2" + GradientLayout::gradient_name(d), 3, true});
            for (int d = 0; d < kDirs; ++d) s.push_back({prefix + "x" + GradientLayout::gradient_name(d), 3, false});
        }
        return s;
    }
    /// Floats one sample writes for half_slots().
    int half_floats() const { return half_floats_; }

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
            OffsetPath offsets2[kMaxBatch][kDirs];  // the second shift's (combined shifts)
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
            // A pair is formed only where both pixels take gradients
            // (RenderSettings::gradient_mask): elsewhere, as at the border, the
            // base estimates its pixel alone, and no offset ray is traced.
            const bool own = gradients_at(px, py);
            for (int d = 0; d < kDirs; ++d) {
                const int nx = px + kDx[d], ny = py + kDy[d];
                inside[d] = own && nx >= 0 && ny >= 0 && nx < W && ny < H && gradients_at(nx, ny);
            }
        }
        // The jobs' camera rays and their offsets' as full packets.
        const bool* inside[kMaxBatch];
        OffsetPath* offsets[kMaxBatch];
        for (int j = 0; j < n; ++j) inside[j] = scratch.inside[j], offsets[j] = scratch.offsets[j];
        trace_camera_packets(scene, n, film, scratch.path, step, inside, offsets, scratch.packet);
        for (int j = 0; j < n; ++j) {
            continue_camera_path(scene, jobs[j].sampler, trace_, scratch.path[j], scratch.packet[j].rays[0],
                                 scratch.packet[j].hit[0]);
            if (config_.probabilistic)
                draw_classification_numbers(scene, jobs[j].sampler, trace_.max_vertices, scratch.path[j]);
        }
        if (shift2_)
            // Both shifts start from the same offset camera hits.
            for (int j = 0; j < n; ++j)
                for (int d = 0; d < kDirs; ++d) {
                    scratch.offsets2[j][d] = scratch.offsets[j][d];
                    scratch.offsets2[j][d].rays = 0;  // the camera ray is counted once
                }
        for (int j = 0; j < n; ++j) {
            shift_from_camera_packet(scene, *shift_, config_, scratch.path[j], scratch.packet[j], scratch.offsets[j]);
            if (shift2_)
                shift_from_camera_packet(scene, *shift2_, config_, scratch.path[j], scratch.packet[j],
                                         scratch.offsets2[j]);
        }
        for (int j = 0; j < n; ++j) {
            rays += scratch.path[j].rays;
            for (int d = 0; d < kDirs; ++d)
                rays += scratch.inside[j][d]
                            ? scratch.offsets[j][d].rays + (shift2_ ? scratch.offsets2[j][d].rays : 0)
                            : 0;
            estimate(scene, jobs[j].x, jobs[j].y, scratch.path[j], scratch.offsets[j],
                     shift2_ ? scratch.offsets2[j] : nullptr, scratch.inside[j],
                     scratch.terms, out + size_t(j) * stride);
        }
    }
    /// The primal and gradients of the samples in the slots named with
    /// `prefix` (see half_slots()): the primal gathers each pixel's own share
    /// and its neighbours' offsets, and dx(x) = I(x+1) - I(x) combines the
    /// pair shifted each way across the edge.
    GradientHalf finalize_half(const Accumulated& acc, const std::string& prefix) const {
        GradientHalf h;
        static_cast<GradientEstimates&>(h) = gather_gradients(acc, GradientLayout::make(prefix));
        if (shift2_) combine_shifts(acc, prefix, h);
        if (!primal_both_) {
            std::vector<Image> base = acc.images({{prefix + "base"}, {prefix + "base", true}});
            h.primal = std::move(base[0]);
            h.primal_var = std::move(base[1]);
        }
        return h;
    }

    /// Combined shifts: replaces h's gradients (the first shift's) by the
    /// minimum-variance combination w g1 + (1 - w) g2 of both shifts' per
    /// edge, w = (v2 - c) / (v1 + v2 - 2c) from their variances v1, v2 and
    /// covariance c (both use the base path's f(x), so c is far from 0),
    /// keeping each shift's own gradients in h.shift_*. The moments are
    /// averaged over the 3x3 edges around each one before they weigh it, so
    /// that a weight hardly depends on the values it weighs (a weight that
    /// did would bias the combination).
    void combine_shifts(const Accumulated& acc, const std::string& prefix, GradientHalf& h) const {
        const int W = acc.width, H = acc.height;
        int g2[kDirs], gx[kDirs];
        for (int d = 0; d < kDirs; ++d)
            g2[d] = acc.slot(prefix + "2" + GradientLayout::gradient_name(d)),
            gx[d] = acc.slot(prefix + "x" + GradientLayout::gradient_name(d));
        h.shift_dx[0] = h.dx, h.shift_dy[0] = h.dy, h.shift_dx_var[0] = h.dx_var, h.shift_dy_var[0] = h.dy_var;
        for (Image* im : {&h.shift_dx[1], &h.shift_dy[1], &h.shift_dx_var[1], &h.shift_dy_var[1]}) *im = Image(W, H, 3);
        Image cov_x(W, H, 3), cov_y(W, H, 3);  // per-sample covariances of the two shifts' gradients
        int g1[kDirs];
        for (int d = 0; d < kDirs; ++d) g1[d] = acc.slot(prefix + GradientLayout::gradient_name(d));
        // Per-sample covariance of the two shifts' one-sided gradients at (x, y) in direction d.
        const auto cov = [&](int d, int x, int y) {
            const double n = double(acc.count(x, y));
            Color c;
            for (int k = 0; k < 3; ++k) {
                const double m = double(acc.mean(gx[d], x, y, k)) -
                                 double(acc.mean(g1[d], x, y, k)) * double(acc.mean(g2[d], x, y, k));
                (&c.r)[k] = n > 1.0 ? float(m * n / (n - 1.0)) : 0.f;
            }
            return c;
        };
        tbb::parallel_for(0, H, [&](int y) {
            for (int x = 0; x < W; ++x) {
                // Neighbours' per-sample moments scaled by the count ratio, as in finalize_half().
                if (x + 1 < W) {
                    const float q = float(double(acc.count(x, y)) / double(acc.count(x + 1, y)));
                    h.shift_dx[1].set_rgb(x, y, acc.mean_rgb(g2[0], x, y) - acc.mean_rgb(g2[1], x + 1, y));
                    h.shift_dx_var[1].set_rgb(x, y, acc.variance_rgb(g2[0], x, y) + q * acc.variance_rgb(g2[1], x + 1, y));
                    cov_x.set_rgb(x, y, cov(0, x, y) + q * cov(1, x + 1, y));
                }
                if (y + 1 < H) {
                    const float q = float(double(acc.count(x, y)) / double(acc.count(x, y + 1)));
                    h.shift_dy[1].set_rgb(x, y, acc.mean_rgb(g2[2], x, y) - acc.mean_rgb(g2[3], x, y + 1));
                    h.shift_dy_var[1].set_rgb(x, y, acc.variance_rgb(g2[2], x, y) + q * acc.variance_rgb(g2[3], x, y + 1));
                    cov_y.set_rgb(x, y, cov(2, x, y) + q * cov(3, x, y + 1));
                }
            }
        });
        const auto blend = [&](const Image& a, const Image& b, const Image& va, const Image& vb, const Image& c,
                               Image& out, Image& out_var) {
            tbb::parallel_for(0, H, [&](int y) {
                for (int x = 0; x < W; ++x)
                    for (int k = 0; k < 3; ++k) {
                        double s1 = 0, s2 = 0, s12 = 0;
                        for (int j = std::max(0, y - 1); j <= std::min(H - 1, y + 1); ++j)
                            for (int i = std::max(0, x - 1); i <= std::min(W - 1, x + 1); ++i)
                                s1 += va.at(i, j, k), s2 += vb.at(i, j, k), s12 += c.at(i, j, k);
                        const double den = s1 + s2 - 2.0 * s12;
                        const double w = den > 0.0 ? std::clamp((s2 - s12) / den, 0.0, 1.0) : 0.5;
                        const double v1 = va.at(x, y, k), v2 = vb.at(x, y, k), v12 = c.at(x, y, k);
                        out.at(x, y, k) = float(w * a.at(x, y, k) + (1.0 - w) * b.at(x, y, k));
                        out_var.at(x, y, k) =
                            float(std::max(0.0, w * w * v1 + (1.0 - w) * (1.0 - w) * v2 + 2.0 * w * (1.0 - w) * v12));
                    }
            });
        };
        blend(h.shift_dx[0], h.shift_dx[1], h.shift_dx_var[0], h.shift_dx_var[1], cov_x, h.dx, h.dx_var);
        blend(h.shift_dy[0], h.shift_dy[1], h.shift_dy_var[0], h.shift_dy_var[1], cov_y, h.dy, h.dy_var);
    }

    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        GradientHalf h = finalize_half(acc, "");
        set_gradient_layers(out, std::move(static_cast<GradientEstimates&>(h)), acc, layout_);
        for (int i = 0; i < 2 && shift2_; ++i) {
            // Each shift's own gradients, as a render with that shift alone would write them.
            const std::string& n = combined_names_[i];
            out.set("dx_" + n, std::move(h.shift_dx[i]));
            out.set("dy_" + n, std::move(h.shift_dy[i]));
            out.set("dx_" + n + "_variance", std::move(h.shift_dx_var[i]));
            out.set("dy_" + n + "_variance", std::move(h.shift_dy_var[i]));
        }
        // Edges with a primal-only pixel have no gradient estimate.
        if (masked()) fill_masked_gradients(out);
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

    // The sample's slots from its traced base path (of pixel (px, py)) and offsets.
    void estimate(const Scene& scene, int px, int py, const CameraPath& path, const OffsetPath* offsets,
                  const OffsetPath* offsets2, const bool* inside, BaseTerms& terms, float* out) const {
        if (path.size() <= 1) return;
        GradientRecord rec(out, layout_);
        compute_base_terms(scene, path, mis_.heuristic, terms);
        // The base alone (plain path-tracing MIS) is needed for the base-only primal and at the border.
        PairEstimate alone;
        bool have_alone = false;
        const auto base_alone = [&]() -> const PairEstimate& {
            if (!have_alone) alone = evaluate_pair(scene, path, terms, nullptr, mis_), have_alone = true;
            return alone;
        };
        if (!primal_both_) rec.set(base_float_, base_alone().base);
        for (int d = 0; d < kDirs; ++d) {
            if (!inside[d]) {
                // No neighbour to share with: the base alone estimates its pixel.
                rec.add_alone(base_alone().base);
                continue;
            }
            GradientMis mis = mis_;
            if (adaptive()) {
                // Unequal sample counts: the multi-sample heuristic weighs each
                // pixel's technique by its share a = n_p / (n_p + n_q) of the
                // pair's samples (Manzi, Kettunen,
                // Durand, Zwicker and Lehtinen, "Temporal Gradient-Domain Path
                // Tracing", 2016). Any a keeps the pair's
                // weights summing to one, so a floor on the densities (a
                // pixel always takes a sample) only costs variance, not bias.
                const double dp = std::max(0.01f, sample_density(px, py));
                const double dq = std::max(0.01f, sample_density(px + kDx[d], py + kDy[d]));
                mis.sample_ratio = dp / (dp + dq);
            }
            const PairEstimate e = evaluate_pair(scene, path, terms, &offsets[d], mis);
            rec.add_pair(d, e.base, e.offset, e.gradient);
            if (offsets2) {
                // The second shift's gradient of the same base path (its primal
                // share is not used: the first shift's pairs estimate the primal).
                const Color g2 = evaluate_pair(scene, path, terms, &offsets2[d], mis).gradient;
                rec.set(second_float_[d], g2);
                rec.set(cross_float_[d], Color{e.gradient.r * g2.r, e.gradient.g * g2.g, e.gradient.b * g2.b});
            }
        }
        rec.add_direct(terms.v[1].emitted);
        // Auxiliary features at the first vertex a reconstruction can use (first connectable one).
        for (size_t k = 1; k < path.size(); ++k) {
            const Vertex& v = path.v[k];
            if (v.infinite) break;  // left the scene: no surface
            if (!is_connectable(v.si.material->min_roughness, 0.5f, ShiftConfig{config_.threshold, false}) &&
                &v != &path.v.back())
                continue;
            rec.set_surface(v.si.material->bsdf->albedo(v.si.uv), v.si.frame.n);
            break;
        }
        rec.set_depth(path.v[1].infinite ? 0.f : path.v[1].si.t);  // a camera ray that left the scene: 0, as pt writes
    }

    std::unique_ptr<Shift> shift_;
    std::unique_ptr<Shift> shift2_;  // combined shifts: the second (nullptr otherwise)
    std::string combined_names_[2];
    std::string shift_name_;
    ShiftConfig config_;
    GradientMis mis_;
    WalkOptions trace_;
    bool primal_both_ = true;
    int batch_ = kMaxBatch;
    GradientReconstructions recon_;
    std::string shift_params_;  // the shift.* parameters as "key=value" lines
    std::string who_;
    GradientLayout layout_ = GradientLayout::make();  // the standard slots' offsets in a half's record
    int half_floats_ = 0;                             // floats of a half's record
    int base_float_ = -1;                             // the base-only primal's (primal=base), else -1
    int second_float_[kDirs] = {}, cross_float_[kDirs] = {};  // combined shifts: the second's gradients, the products
};

}  // namespace gdr::detail
