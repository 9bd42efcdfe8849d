// Gradient-domain path tracing: every base path is shifted to its four
// neighbours; the MIS-weighted differences give the gradients dx, dy and the
// weighted base and offset contributions give the primal image.
#include <tuple>

#include "gdr/integrators/gpt.h"

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include "gdr/path/dims.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/trace.h"
#include "gdr/reconstruct/reconstructor.h"

namespace gdr {

namespace {

// Solid-angle density (1/sr) with which light sampling at `from` picks the
// emitter point of `at`, or, if `infinite`, the environment's direction -at.ng.
double light_pdf_w(const Scene& scene, const Vec3& from, const SurfaceInteraction& at, bool infinite) {
    if (infinite) return scene.environment_pdf(-at.ng);
    const float pa = scene.light_pdf_a(at.prim);
    if (!(pa > 0.f)) return 0.0;
    const Vec3d d = Vec3d(at.p) - Vec3d(from);
    const double dist = glm::length(d);
    return pdf_a_to_w(double(pa), dist, glm::dot(Vec3d(at.ng), d / dist));
}

// Inlined: it sits in evaluate_pair's inner loop, and as a call it kept its
// operands in memory.
[[gnu::always_inline]] inline void add(PairEstimate& e, double w, const Color& cx, const Color& cy) {
    const float wf = float(w);
    e.base += wf * cx;
    e.offset += wf * cy;
    e.gradient += wf * (cy - cx);
}

}  // namespace

// Plain path-tracing MIS weight of technique density a_t against a_other:
// the gradient weight without offset densities (the sample ratio cancels).
inline double pt_mis_weight(MisHeuristic h, double a_t, double a_other) {
    return gradient_mis_weight(GradientMis{h, 0.5}, a_t, a_other, 0.0, 0.0, 1.0);
}

void compute_base_terms(const Scene& scene, const CameraPath& x, MisHeuristic heuristic, BaseTerms& t) {
    t.v.assign(x.size(), BaseTerms::Vertex{});
    Color beta(1.f);
    for (size_t k = 1; k < x.size(); ++k) {
        const Vertex& X = x.v[k];
        const LightConnection& nee = x.nee[k];
        BaseTerms::Vertex& T = t.v[k];
        T.beta = beta;
        T.emitted = emitted(X);
        if (k >= 2) {
            const Vertex& P = x.v[k - 1];
            T.emit = beta * T.emitted;
            T.emit_pdf_bsdf = P.bs.pdf;
            if (!P.bs.is_delta() && x.nee[k - 1].valid && !is_black(T.emitted))
                T.emit_pdf_light = light_pdf_w(scene, P.si.p, X.si, X.infinite);
        }
        if (nee.valid) {
            const LightSample& ls = nee.light;
            T.nee_pdf_light = nee.pdf_w;
            if (T.nee_pdf_light > 0.0) {
                const Vec3& wi = nee.wi;
                T.nee_pdf_bsdf = nee.pdf_bsdf;
                T.inv_nee_pdf_light = 1.0 / T.nee_pdf_light;
                if (nee.visible) {
                    T.nee_unit = nee.f * abs_cos_theta(wi) * ls.radiance * float(T.inv_nee_pdf_light);
                    T.nee = beta * T.nee_unit;
                }
            }
        }
        if (!X.scattered()) break;
        T.inv_bs_pdf = 1.0 / double(X.bs.pdf);
        T.inv_scatter_pdf = T.inv_bs_pdf / double(X.rr_survival);
        T.scatter = scatter_weight(X);
        beta *= T.scatter;
    }
    // Suffix sums, back to front. Where y equals x (same vertices, same
    // densities), gradient_mis_weight(a_t, a_o, a_t, a_o, r) factors into the
    // path-tracing weight of (a_t, a_o) times a function of r alone, and r and
    // beta_y / beta_x stay constant: the whole shared suffix is one product.
    Color next(0.f);  // suffix of vertex k+1 plus its emitter hit, per unit throughput at k+1
    for (size_t k = x.size(); k-- > 1;) {
        const Vertex& X = x.v[k];
        BaseTerms::Vertex& T = t.v[k];
        // Weights only where they multiply something (each costs a division).
        T.suffix = is_black(T.nee_unit) ? Color(0.f)
                                        : float(pt_mis_weight(heuristic, T.nee_pdf_light, T.nee_pdf_bsdf)) * T.nee_unit;
        if (X.scattered() && k + 1 < x.size()) T.suffix += T.scatter * next;
        next = T.suffix;
        if (k >= 2 && !is_black(T.emitted))
            next += float(pt_mis_weight(heuristic, T.emit_pdf_bsdf, T.emit_pdf_light)) * T.emitted;
    }
}

namespace {

// evaluate_pair() with `closed_form` fixed at compile time: the rendering
// loop's form carries none of the vertex-by-vertex walk's tests.
template <bool closed_form>
PairEstimate evaluate_pair_as(const Scene& scene, const CameraPath& x, const BaseTerms& t, const OffsetPath* y,
                              const GradientMis& mis) {
    PairEstimate e;
    Color beta_y(1.f);
    double r = 1.0, r_prev = 1.0;  // offset prefix density / base prefix density (through k-1, k-2)
    const size_t m = y ? y->size() : 0;
    bool y_alive = m > 0;
    for (size_t k = 1; k < x.size(); ++k) {
        const Vertex& X = x.v[k];
        const BaseTerms::Vertex& T = t.v[k];
        const bool has_y = y_alive && k < m;
        // In the shared suffix the offset is the base with its own throughput and prefix density.
        const bool merged = has_y && y->merged(k);
        // In closed form the walk stops at the first merged vertex, so there
        // every merged vertex is the first one; it stops one vertex sooner
        // where the offset reconnected onto x_k with x_k's BSDF values, past
        // x_k's emitter term (that one sees the offset's own previous vertex).
        const bool closed_from_here = closed_form && (merged || (has_y && k == y->base_values_from));
        if (closed_form && !has_y) {
            // No offset from here on (none, failed or ended): every later term has
            // the plain path-tracing weight and no offset share, so the base's
            // suffix sums give the rest at once.
            Color c = T.suffix;
            if (k >= 2 && !is_black(T.emitted))
                c += float(pt_mis_weight(mis.heuristic, T.emit_pdf_bsdf, T.emit_pdf_light)) * T.emitted;
            const Color cx = T.beta * c;
            if (!is_black(cx)) add(e, 1.0, cx, Color(0.f));
            break;
        }

        // Emitter reached by BSDF sampling at x_{k-1}.
        if (k >= 2) {
            Color cy(0.f);
            double b_b = 0.0, b_l = 0.0;
            if (merged) {
                cy = beta_y * T.emitted;
                if (closed_form || k == y->merged_from) {
                    const ShiftStep& S = y->v[k - 1].step;  // left the shared vertex with its own incoming direction
                    b_b = double(S.pdf) * S.jacobian;
                    b_l = T.emit_pdf_light * S.jacobian;
                } else {
                    b_b = T.emit_pdf_bsdf, b_l = T.emit_pdf_light;
                }
            } else if (has_y) {
                const OffsetRecord& Y = y->v[k];
                const ShiftStep& S = y->v[k - 1].step;
                cy = beta_y * Y.y.emitted;
                // The offset's densities weigh the base even where the offset itself contributes nothing.
                b_b = double(S.pdf) * S.jacobian;
                const OffsetVertex& Yp = y->v[k - 1].y;
                if (!S.delta && (Y.y.infinite || Y.y.si.is_emitter()) && scene.has_lights() && !Yp.si.material->pure_delta)
                    b_l = light_pdf_w(scene, Yp.si.p, Y.y.si, Y.y.infinite) * S.jacobian;
            }
            if (!is_black(T.emit) || !is_black(cy))
                add(e, gradient_mis_weight(mis, T.emit_pdf_bsdf, T.emit_pdf_light, b_b, b_l, r_prev), T.emit, cy);
        }

        if (closed_from_here) {
            // Everything from here on (this light sample, later vertices) in closed
            // form: w = w_pt * g(r), g(r) = (a q)^b / ((a q)^b + ((1-a) r q)^b),
            // which is the gradient weight of one technique of density 1 against
            // an offset of density 1 (and no other technique).
            const double g = gradient_mis_weight(mis, 1.0, 0.0, 1.0, 0.0, r);
            if (g > 0.0) {
                const Color cx = T.beta * T.suffix, cy = beta_y * T.suffix;
                add(e, g, cx, cy);
            }
            break;
        }

        // Light sample at x_k, shared with the offset.
        if (T.nee_pdf_light > 0.0) {
            Color cy(0.f);
            double b_l = 0.0, b_b = 0.0;
            if (!closed_form && merged) {
                cy = beta_y * T.nee_unit;
                b_l = T.nee_pdf_light, b_b = T.nee_pdf_bsdf;
            } else if (has_y && y->v[k].nee) {
                const OffsetRecord& R = y->v[k];
                b_l = R.nee_pdf_light_w * R.nee_jacobian;
                b_b = double(R.nee_pdf_bsdf) * R.nee_jacobian;
                cy = beta_y * R.nee_f * R.nee_cos * R.nee_radiance * float(R.nee_jacobian * T.inv_nee_pdf_light);
            }
            if (!is_black(T.nee) || !is_black(cy))
                add(e, gradient_mis_weight(mis, T.nee_pdf_light, T.nee_pdf_bsdf, b_l, b_b, r), T.nee, cy);
        }

        if (!X.scattered()) break;
        r_prev = r;
        if (!closed_form && merged) {
            beta_y *= scatter_weight(X);
        } else if (has_y) {
            const ShiftStep& S = y->v[k].step;
            if (S.kind == ShiftStep::Kind::Fail || k + 1 >= m) {
                y_alive = false;
            } else {
                // Products with the base's reciprocals: four offsets share them.
                beta_y *= S.f * float(abs_cos_theta(S.wi) * S.jacobian * T.inv_scatter_pdf);
                r *= double(S.pdf) * S.jacobian * T.inv_bs_pdf;
            }
        }
    }
    return e;
}

}  // namespace

PairEstimate evaluate_pair(const Scene& scene, const CameraPath& x, const BaseTerms& t, const OffsetPath* y,
                           const GradientMis& mis, bool closed_form) {
    return closed_form ? evaluate_pair_as<true>(scene, x, t, y, mis) : evaluate_pair_as<false>(scene, x, t, y, mis);
}

namespace {

constexpr int kDirs = 4;
const int kDx[kDirs] = {1, -1, 0, 0};
const int kDy[kDirs] = {0, 0, 1, -1};
const char* const kGradSlot[kDirs] = {"g+x", "g-x", "g+y", "g-y"};
const char* const kSplatSlot[kDirs] = {"s+x", "s-x", "s+y", "s-y"};
// First RGB triple of each slot in a sample's output (slots() order); albedo,
// normal and depth (7 floats) follow from triple kAux, then the optional
// base-only primal at float kBaseFloat.
constexpr int kSelf = 0, kGrad = 1, kSplat = kGrad + kDirs, kDirect = kSplat + kDirs, kAux = kDirect + 1;
constexpr int kBaseFloat = 3 * kAux + 7;


class GradientPathTracer final : public TiledIntegrator {
public:
    explicit GradientPathTracer(const Params& p) {
        const std::string shift_name = p.get_string("shift", "half-vector");
        shift_ = shift_registry().create(shift_name, Params("shift"));
        shift_name_ = shift_name;
        config_.threshold = float(p.get_real("threshold", 0.001));
        config_.probabilistic = p.get_choice("classification", "hard", {"hard", "probabilistic"}) == "probabilistic";
        mis_.heuristic = p.get_choice("mis", "power", {"power", "balance"}) == "power" ? MisHeuristic::Power
                                                                                        : MisHeuristic::Balance;
        std::tie(trace_.max_vertices, trace_.rr_depth) = depth_params(p, "gpt");
        // G-PT's MIS reads solid-angle densities only.
        trace_.reverse_densities = false, trace_.forward_densities = false;
        trace_.classify_numbers = config_.probabilistic;
        primal_both_ = p.get_choice("primal", "both", {"both", "base"}) == "both";
        batch_ = batch_param(p, "gpt", kMaxBatch);
        recon_ = GradientReconstructions::from(p, "gpt");
        if (!(config_.threshold >= 0.f)) throw ParameterError("gpt: threshold must be >= 0");
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
    std::vector<SlotSpec> slots() const override {
        // Order fixes the offsets sample() writes to (kSelf, kGrad, ...).
        std::vector<SlotSpec> s{{"self", 3, true}};
        for (int d = 0; d < kDirs; ++d) s.push_back({kGradSlot[d], 3, true});
        for (int d = 0; d < kDirs; ++d) s.push_back({kSplatSlot[d], 3, true});
        s.push_back({"direct", 3, false});
        s.push_back({"albedo", 3, false});
        s.push_back({"normal", 3, false});
        s.push_back({"depth", 1, false});
        // The base-only primal is accumulated only where it is the output: a
        // slot costs 48 bytes a pixel of accumulators, zeroed every render.
        if (!primal_both_) s.push_back({"base", 3, true});
        return s;
    }

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
    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        const int W = out.width(), H = out.height();
        Image primal(W, H, 3), primal_var(W, H, 3), dx(W, H, 3), dy(W, H, 3), dx_var(W, H, 3), dy_var(W, H, 3);
        const int self = acc.slot("self");
        int splat[kDirs], grad[kDirs];
        for (int d = 0; d < kDirs; ++d) splat[d] = acc.slot(kSplatSlot[d]), grad[d] = acc.slot(kGradSlot[d]);
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
                primal.set_rgb(x, y, p);
                primal_var.set_rgb(x, y, pv);
                // dx(x) = I(x+1) - I(x): from x shifted right, minus from x+1 shifted left.
                if (x + 1 < W) {
                    dx.set_rgb(x, y, acc.mean_rgb(gpx, x, y) - acc.mean_rgb(gmx, x + 1, y));
                    dx_var.set_rgb(x, y, acc.variance_rgb(gpx, x, y) + acc.variance_rgb(gmx, x + 1, y));
                }
                if (y + 1 < H) {
                    dy.set_rgb(x, y, acc.mean_rgb(gpy, x, y) - acc.mean_rgb(gmy, x, y + 1));
                    dy_var.set_rgb(x, y, acc.variance_rgb(gpy, x, y) + acc.variance_rgb(gmy, x, y + 1));
                }
            }
        });
        std::vector<Accumulated::Want> wanted{{"direct"}, {"albedo"}, {"normal"}, {"depth"}};
        if (!primal_both_) wanted.push_back({"base"}), wanted.push_back({"base", true});
        std::vector<Image> im = acc.images(wanted);
        const Image& direct = im[0];
        Image color(W, H, 3);
        const Image& chosen = primal_both_ ? primal : im[4];
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) color.set_rgb(x, y, chosen.rgb(x, y) + direct.rgb(x, y));
        out.set("color", std::move(color));
        out.set("primal", primal_both_ ? std::move(primal) : std::move(im[4]));
        out.set("dx", std::move(dx));
        out.set("dy", std::move(dy));
        out.set("direct", std::move(im[0]));
        out.set("primal_variance", primal_both_ ? std::move(primal_var) : std::move(im[5]));
        out.set("dx_variance", std::move(dx_var));
        out.set("dy_variance", std::move(dy_var));
        if (acc.derived) recon_.add(out, acc.spp, "gpt");
        out.set("albedo", std::move(im[1]));
        out.set("normal", std::move(im[2]));
        out.set("depth", std::move(im[3]));
    }

public:
    void update_merged(FrameBuffer& merged) const override { recon_.add(merged, 0, "gpt"); }

private:
    // Most samples whose stages run in turn, and the default: 4, 8 and 16
    // ran alike on the Cornell box, about 7% less CPU time per sample than 1.
    static constexpr int kMaxBatch = 8;
    static_assert(kMaxBatch <= kMaxCameraBatch, "a batch's camera rays go through one trace_camera_packets() call");

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
};

}  // namespace

GradientReconstructions GradientReconstructions::from(const Params& p, const std::string& who) {
    GradientReconstructions r;
    // The variance-weighted solve is the final image (the benchmark's
    // best, docs/performance.md); L1 and L2 stay, the anchors' methods.
    r.choice = p.get_choice("reconstruct", "all", {"all", "weighted", "l1+l2", "l1", "l2", "none"});
    r.alpha = p.get_real("alpha", 0.2);
    if (!(r.alpha > 0.0)) throw ParameterError(who + ": alpha must be positive");
    return r;
}

void GradientReconstructions::add(FrameBuffer& fb, int64_t spp, const std::string& who) const {
    const bool weighted = choice == "all" || choice == "weighted";
    const bool l1 = choice == "all" || choice == "l1+l2" || choice == "l1";
    const bool l2 = choice == "all" || choice == "l1+l2" || choice == "l2";
    if (!weighted && !l1 && !l2) return;
    GradientBuffers gb = gradient_buffers(fb);
    Image spp_image;
    if (!gb.spp && spp > 0) {
        spp_image = Image(fb.width(), fb.height(), 1);
        std::fill(spp_image.values().begin(), spp_image.values().end(), float(spp));
        gb.spp = &spp_image;
    }
    if (weighted) fb.set("reconstruction_weighted", reconstruct("poisson-weighted", Params(who), gb));
    Params rp(who);
    rp.set("alpha", alpha);
    if (l1) fb.set("reconstruction_l1", reconstruct("poisson-l1", rp, gb));
    if (l2) fb.set("reconstruction_l2", reconstruct("poisson-l2", rp, gb));
}

void register_gpt(Registry<Integrator>& r) {
    r.add("gpt",
          "gradient-domain path tracing (params: shift, threshold, classification, mis, max_depth, rr_depth, primal, reconstruct, alpha, batch)",
          [](const Params& p) { return std::make_unique<GradientPathTracer>(p); });
}

}  // namespace gdr
