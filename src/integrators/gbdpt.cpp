// Gradient-domain bidirectional path tracing (Manzi et al., "Gradient-Domain
// Bidirectional Path Tracing", 2015).
//
// A sample is a bidirectional one: a camera subpath x through the pixel and a
// light subpath, joined by every (s, t) strategy of the path-space core
// (gdr/path/connection.h). For each of the four neighbouring pixels, the
// camera subpath is shifted by the registered shift mapping (the walk of
// gpt's offsets, offset_path.h, without its light samples); the light
// subpath is shared. Each base path x of strategy (s, t) then has an offset
// y = T(x) that follows the offset camera subpath up to its reconnection
// y_b -> x_{b+1} and shares every vertex after it, light subpath included.
//
// For T to be one map on full paths, whichever strategy sampled them, it must
// not depend on which of a path's vertices came from which subpath. The
// camera-side shift reads the vertices up to x_{b+1}; so T(x) is taken to be
// defined only where the shift reconnects no later than the first pair of
// consecutive connectable vertices of x and of y (every kept strategy connects
// at such a pair, so that b <= t - 1 and the shift never needs light-subpath
// vertices it has not reached). A reconnection at b = t - 1 is the connection
// itself; the shift decides it with the light vertex as x_{b+1}. Light
// tracing (t = 1) shifts the film point of the light vertex seen by the
// camera and reconnects its first hit to the next light vertex.
//
// Strategies: a connection needs both of its vertices connectable (roughness
// above `drop`, at least the shift's own threshold), which drops connections
// at very glossy vertices, the publication's key insight; s = 0 (the camera
// walk hits the light) is always kept, so every path keeps a strategy and the
// estimator stays unbiased. A pair (x, y) keeps the strategies both paths
// allow. Its balance-heuristic weight is
//     w_st = p_st(x) / sum_{s',t' kept} ( p_s't'(x) + |J| p_s't'(y) ),
// where a strategy counts for a path only if it can produce it: a path with a
// blocked segment is produced only by the strategy that connects across that
// segment (every other one would trace it), which is what makes the weights of
// a pair sum to one when one of its two paths is blocked.
//
// Layers follow gpt: primal (base and offsets both contribute, as in
// G-PT's default), dx, dy, direct, their variances, auxiliary features and
// the reconstructions. Scenes with an environment light are refused: a
// vertex at infinity is not connectable and the shift's treatment of it is
// not a map on full paths.
#include "gdr/integrators/gbdpt.h"

#include <charconv>
#include <limits>
#include <tuple>

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include "gdr/integrators/gpt.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/connection.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/integrators/gradient_film.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/shift/bidir.h"
#include "gdr/shift/offset_path.h"

namespace gdr {

namespace {

constexpr int kDirs = kNeighbours;
constexpr const int* kDx = kNeighbourDx;
constexpr const int* kDy = kNeighbourDy;
constexpr int kNone = kNoDepth;

// First depth k >= 1 of a pair of connectable vertices z_k, z_{k+1} of a
// path of n vertices (kNone if there is none).
int first_pair(const uint8_t* conn, int n) {
    for (int k = 1; k + 1 < n; ++k)
        if (conn[k] && conn[k + 1]) return k;
    return kNone;
}

// Whether strategy t is kept for a path with connectability flags `conn`
// and densities `d`: s = 0 always; a connection only between connectable
// vertices, and light tracing only where its shift reconnects at the first
// hit (z_1 and z_2 connectable).
bool kept(const uint8_t* conn, const PathDensities& d, int t) {
    const int n = d.size();
    if (t == n) return true;
    if (!strategy_possible(d, t) || !conn[t - 1] || !conn[t]) return false;
    return t != 1 || (n >= 3 && conn[2]);
}

// The unweighted contribution of joining camera-side vertex p (radiance
// transport) to light-side vertex q (a surface or an emitter point), visibility
// not tested: beta_q f_q G f_p beta_p (W/(m^2 sr)).
Color join(const Scene& scene, const Vertex& q, const Vertex& p) {
    const Vec3 d = p.si.p - q.si.p;
    const float dist2 = glm::dot(d, d);
    if (!(dist2 > 0.f)) return Color(0.f);
    const Vec3 w = d / std::sqrt(dist2);  // light side -> camera side
    Color fq(1.f);
    float cos_q;
    if (q.delta_light) {
        // A point or spot light: its intensity towards p over its selection
        // probability, no cosine (delta_light.h).
        const Color fp = vertex_f(scene, p, -w, TransportMode::Radiance);
        return q.delta_light->intensity_towards(w) * float(1.0 / q.pdf_fwd) * fp * p.beta *
               (abs_cos_shading(p, w) / dist2);
    }
    if (q.type == VertexType::Light) {
        cos_q = glm::dot(q.si.ng, w);
        if (!(cos_q > 0.f)) return Color(0.f);
    } else {
        fq = vertex_f(scene, q, w, TransportMode::Importance);
        cos_q = abs_cos_shading(q, w);
    }
    const Color fp = vertex_f(scene, p, -w, TransportMode::Radiance);
    return q.beta * fq * fp * p.beta * (cos_q * abs_cos_shading(p, w) / dist2);
}

// Whether the segment between two finite vertices is unblocked.
bool segment_visible(const Scene& scene, const Vertex& a, const Vertex& b) {
    return scene.visible(a.si.p, a.si.ng, b.si.p, b.type == VertexType::Camera ? Vec3(0.f) : b.si.ng);
}

// Sum of the density ratios `rho` of the strategies in `set` (t' = 1..n).
double sum_over(const std::vector<double>& rho, const std::vector<uint8_t>& set) {
    double s = 0.0;
    for (size_t u = 1; u < rho.size(); ++u)
        if (set[u]) s += rho[u];
    return s;
}

class GradientBdpt final : public TiledIntegrator {
public:
    explicit GradientBdpt(const Params& p) {
        shift_name_ = p.get_string("shift", "half-vector");
        shift_ = std::move(make_shifts(p, {shift_name_}, shift_params_)[0]);
        config_.threshold = float(p.get_real("threshold", 0.001));
        if (!(config_.threshold >= 0.f)) throw ParameterError("gbdpt: threshold must be >= 0");
        drop_ = float(p.get_real("drop", config_.threshold));
        if (!(drop_ >= config_.threshold))
            throw ParameterError("gbdpt: drop must be at least the shift's threshold (" +
                                 fmt::format("{}", config_.threshold) + "), got " + fmt::format("{}", drop_));
        std::tie(max_depth_, rr_depth_) = depth_params(p, "gbdpt");
        strategy_ = p.get_string("strategy", "all");
        if (strategy_ != "all") {
            // "s,t": that strategy alone, its base and offset weighed against each other only.
            const auto c = parse_connection(strategy_, 3);
            if (!c)
                throw ParameterError("gbdpt: strategy must be all, or s,t with s >= 0, t >= 1, s + t >= 3 and "
                                     "(s, t) != (1, 1), got '" + strategy_ + "'");
            only_ = *c;
            one_ = true;
        }
        batch_ = batch_param(p, "gbdpt", 16);
        recon_ = GradientReconstructions::from(p, "gbdpt");
    }

    std::string describe() const override {
        return "shift=" + shift_name_ + "\nthreshold=" + fmt::format("{}", config_.threshold) +
               "\ndrop=" + fmt::format("{}", drop_) + "\nmax_depth=" + std::to_string(max_depth_) +
               "\nrr_depth=" + std::to_string(rr_depth_) + "\nstrategy=" + strategy_ + "\n" + shift_params_ +
               recon_.describe();
    }

protected:
    void prepare(const Scene& scene) override {
        if (scene.environment())
            throw ParameterError("gbdpt: scenes with an environment light are not supported (a vertex at infinity "
                                 "cannot be reconnected to); render them with bdpt or gpt");
        // Point and spot lights: no camera walk hits one, so s = 0 cannot
        // keep a strategy for their paths; where every surface is
        // connectable, s = 1 always can. With a mirror, glass or a surface
        // below `drop`, a path such as light - mirror - wall - camera would
        // keep none (only light tracing samples it, and its shift needs the
        // mirror connectable): refused rather than rendered darker.
        for (const DeltaLight& l : scene.delta_lights())
            if (l.kind == DeltaLight::Kind::Directional)
                throw ParameterError("gbdpt: scenes with a directional light are not supported (a vertex at infinity "
                                     "cannot be reconnected to); render them with bdpt or gpt");
        if (!scene.delta_lights().empty())
            for (const Material& m : scene.materials())
                if (!m.black && (m.pure_delta || !(m.min_roughness > drop_)))
                    throw ParameterError("gbdpt: with point or spot lights every surface must be connectable (rougher "
                                         "than drop = " + fmt::format("{}", drop_) + "), and material '" + m.name +
                                         "' is not: paths through it to the light could be lost; render with bdpt or gpt");
    }

    std::vector<SlotSpec> slots() const override { return layout_.slots(); }
    // Light tracing's share: the primal (0) and the gradient towards each neighbour (1 + d).
    int splat_layers() const override { return 1 + kDirs; }
    int batch_size() const override { return batch_; }

    void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        for (int j = 0; j < n; ++j) estimate(scene, jobs[j], out + size_t(j) * stride, rays);
    }

    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        // Light tracing's shares landed in the splat layers: the primal's in
        // layer 0, each one-sided gradient's in layer 1 + d.
        set_gradient_layers(out, gather_gradients(acc, layout_, true), acc, layout_);
    }

public:
    void update_merged(FrameBuffer& merged) const override { recon_.add(merged, 0, "gbdpt"); }

private:
    // Connectability of a subpath vertex for a connection (endpoints always).
    bool connectable(const Vertex& v) const {
        if (v.type != VertexType::Surface) return !v.infinite;
        if (v.infinite) return false;
        const Material& m = *v.si.material;
        return !m.pure_delta && !m.black && m.min_roughness > drop_;
    }

    // Per-thread scratch: kept between samples, so a sample allocates nothing once warm.
    struct Scratch {
        CameraPath cam;
        Subpath light, first;  // first: an offset camera subpath of light tracing, camera and first hit
        CameraPath synth;      // the base as the shift sees it when the reconnection is the connection
        CameraOffset off[kDirs];
        std::vector<uint8_t> cflag, lflag, oflag[kDirs], fx, fy, ax, ay, px, py;
        PathDensities dx, dy;
        std::vector<double> rx, ry;
    };

    void estimate(const Scene& scene, SampleJob& job, float* o, uint64_t& rays) const {
        thread_local Scratch S;
        const int W = scene.camera().width(), H = scene.camera().height();
        const WalkOptions cam_opt{max_depth_, rr_depth_};
        const WalkOptions light_opt{max_depth_ > 0 ? max_depth_ - 1 : -1, rr_depth_};
        const Sampler& sampler = job.sampler;
        const Vec2 film = Vec2(float(job.x), float(job.y)) + sampler.at2(dims::kFilm);
        CameraPath& cam = S.cam;
        trace_camera_subpath(scene, film, sampler, cam_opt, cam);
        cam.film = film;
        cam.nee.assign(cam.v.size(), LightConnection{});
        trace_light_subpath(scene, sampler, light_opt, S.light);
        const Subpath& light = S.light;
        rays += cam.rays + light.rays;
        GradientRecord rec(o, layout_);
        write_aux(cam, rec);
        // A camera ray that misses still leaves light tracing (t = 1) its strategies.

        bool inside[kDirs];
        for (int d = 0; d < kDirs; ++d) {
            const int nx = job.x + kDx[d], ny = job.y + kDy[d];
            inside[d] = nx >= 0 && ny >= 0 && nx < W && ny < H;
            S.off[d].p.v.clear();
            if (inside[d]) shift_camera_subpath(scene, *shift_, config_, cam, Vec2(float(kDx[d]), float(kDy[d])), S.off[d], rays);
            S.oflag[d].resize(size_t(S.off[d].size()));
            for (int k = 0; k < S.off[d].size(); ++k) S.oflag[d][k] = k == 0 || connectable(S.off[d].p.v[k]);
        }
        S.cflag.resize(cam.v.size());
        for (size_t k = 0; k < cam.v.size(); ++k) S.cflag[k] = k == 0 || connectable(cam.v[k]);
        S.lflag.resize(light.v.size());
        for (size_t j = 0; j < light.v.size(); ++j) S.lflag[j] = j == 0 || connectable(light.v[j]);

        const int s_max = std::max(light.size(), scene.has_lights() ? 1 : 0);
        for (int t = 1; t <= int(cam.size()); ++t)
            for (int s = 0; s <= s_max; ++s) {
                const int n = s + t;
                if (n < 2 || (s == 1 && t == 1)) continue;
                if (max_depth_ > 0 && n - 1 > max_depth_) break;
                if (one_ && (s != only_.s || t != only_.t)) continue;
                strategy(scene, S, job, s, t, inside, rec, rays);
            }
    }

    void strategy(const Scene& scene, Scratch& S, SampleJob& job, int s, int t, const bool* inside,
                  GradientRecord& rec, uint64_t& rays) const {
        const CameraPath& cam = S.cam;
        const Subpath& light = S.light;
        const Sampler& sampler = job.sampler;
        const int n = s + t;
        if (cam.v[t - 1].infinite) return;
        // The light end of the connection: s = 1 samples its own point, with the camera vertex's numbers.
        Vertex sampled;
        const Vertex* lend = nullptr;
        if (s == 1) {
            const Vertex& pt = cam.v[t - 1];
            const Vec2 u = sampler.at2(dims::vertex(t - 1) + dims::kLightPoint);
            // A point or spot light faces the vertex it lights (LightSample's convention).
            const LightSample ls = scene.picks_delta(pt.u_light) ? scene.sample_light(pt.si.p, pt.u_light, u)
                                                                 : scene.sample_emitter_point(pt.u_light, u);
            if (!(ls.pdf_a > 0.f) || ls.infinite) return;
            sampled.type = VertexType::Light;
            sampled.delta_light = ls.delta_light;
            sampled.si.p = ls.p, sampled.si.ng = ls.n, sampled.si.frame = Frame(ls.n), sampled.si.prim = ls.prim;
            sampled.le = ls.radiance;
            sampled.pdf_fwd = ls.pdf_a;
            sampled.beta = ls.radiance / ls.pdf_a;
            lend = &sampled;
        } else if (s >= 2) {
            lend = &light.v[s - 1];
        }
        // The full path's connectability flags, camera end first.
        std::vector<uint8_t>& fx = S.fx;
        fx.assign(size_t(n), 0);
        for (int i = 0; i < t; ++i) fx[i] = S.cflag[i];
        for (int j = 0; j < s; ++j) fx[n - 1 - j] = j == 0 ? 1 : S.lflag[j];
        fx[0] = 1, fx[n - 1] = 1;
        // Whether t itself is kept needs no densities: its own connecting
        // vertices are never delta ones (connection_densities).
        if (!one_ && t < n && !(fx[t - 1] && fx[t] && (t != 1 || (n >= 3 && fx[2])))) return;

        // The base's unweighted value.
        const ConnectionResult cx = connect(scene, light, cam, {s, t}, sampler, StrategySet{}, false, rays);
        if (t == 1 && cx.occluded) return;  // the camera does not see x_1: no camera-side shift, and f(x) = 0
        const Color vx = cx.value;
        // f(x) = 0 (visibility aside): nothing to contribute, and never paired.
        if (is_black(vx) && !cx.occluded) return;
        const Vec2 film_x = cx.film;  // light tracing's raster point (its value is not 0 here)
        if (n == 2) {
            rec.add_direct(vx);  // directly visible emitters stay out of the gradients
            return;
        }
        connection_densities(scene, light, cam, {s, t}, lend, S.dx);
        if (!strategy_possible(S.dx, t)) return;
        strategy_density_ratios(S.dx, t, S.rx);
        std::vector<uint8_t>& ax = S.ax;
        ax.assign(size_t(n) + 1, 0);
        for (int u = 1; u <= n; ++u) ax[u] = one_ ? u == t : kept(fx.data(), S.dx, u);
        const int cxp = first_pair(fx.data(), n);
        const int px0 = int(std::floor(film_x.x)), py0 = int(std::floor(film_x.y));

        for (int d = 0; d < kDirs; ++d) {
            const Vec2 delta(float(kDx[d]), float(kDy[d]));
            const bool has_neighbour =
                t >= 2 ? inside[d]
                       : px0 + kDx[d] >= 0 && py0 + kDy[d] >= 0 && px0 + kDx[d] < scene.camera().width() &&
                             py0 + kDy[d] < scene.camera().height();
            // Base alone: only x's strategies (a blocked connection: only its own).
            const auto base_only_weight = [&]() {
                S.px = ax;
                if (cx.occluded) std::fill(S.px.begin(), S.px.end(), 0), S.px[t] = 1;
                return 1.0 / sum_over(S.rx, S.px);
            };
            const auto add_base = [&](double w) {
                if (t >= 2) rec.add_self(float(0.25 * w) * vx);
                else if (job.splats) job.splats->add(film_x, float(0.25 * w) * vx, 0);
            };
            if (!has_neighbour) {
                if (!is_black(vx)) add_base(base_only_weight());
                continue;
            }
            // The offset of this strategy's path.
            bool defined = false, occluded_y = false;
            int blocked_y = -1;  // first vertex of y's blocked traced segment, if any
            Color vy(0.f);
            double R = 0.0;
            std::vector<uint8_t>& fy = S.fy;
            fy.assign(size_t(n), 0);
            for (int j = 0; j < s; ++j) fy[n - 1 - j] = fx[n - 1 - j];
            fy[0] = 1;
            if (t >= 2) {
                const CameraOffset& off = S.off[d];
                if (off.size() >= t) {
                    for (int i = 0; i < t; ++i) fy[i] = S.oflag[d][i];
                    fy[n - 1] = 1;
                    int b = kNone;
                    if (off.b <= t - 2) {
                        b = off.b;
                        if (off.blocked) blocked_y = b;
                    } else if (s >= 1) {
                        const ShiftStep st = shift_onto(scene, *shift_, config_, cam.v.data(), t - 1, *lend, off.y[t - 1], S.synth);
                        if (st.kind == ShiftStep::Kind::Reconnect) b = t - 1;
                    }
                    const int cyp = first_pair(fy.data(), n);
                    defined = b == kNone ? (s == 0 && cxp == kNone && cyp == kNone) : (b <= cxp && b <= cyp);
                    // Connecting at a merged vertex, y's connection is x's (same
                    // points, same directions): its value scales with the throughput.
                    const Color& bx = cam.v[t - 1].beta;
                    const Color& by = off.p.v[t - 1].beta;
                    const bool merged = off.merged <= t - 1 && (bx.r > 0.f || by.r == 0.f) &&
                                        (bx.g > 0.f || by.g == 0.f) && (bx.b > 0.f || by.b == 0.f);
                    if (defined && merged) {
                        const auto ratio = [](float a, float b) { return a > 0.f ? b / a : 0.f; };
                        vy = vx * Color(ratio(bx.r, by.r), ratio(bx.g, by.g), ratio(bx.b, by.b));
                        occluded_y = cx.occluded;
                        if (is_black(vy) && !occluded_y) defined = false;
                        if (blocked_y >= 0) vy = Color(0.f);
                    }
                    if (defined && merged) {
                        // Only the densities of y's own vertices and of the two after them differ.
                        S.dy = S.dx;
                        for (int i = 0; i <= off.merged; ++i) S.dy.fwd[i] = off.p.v[i].pdf_fwd;
                        for (int i = 0; i <= off.merged - 2; ++i)
                            S.dy.rev[i] = off.p.v[i].pdf_rev, S.dy.delta[i] = off.p.v[i].delta;
                        strategy_density_ratios(S.dy, t, S.ry);
                        R = off.r[t - 1];
                    } else if (defined) {
                        if (s >= 1 && off.b == t - 2) {
                            // y_{t-1} is x_{t-1} entered from y_{t-2}: the same segment to
                            // the light side, so x's visibility is y's.
                            const Color v = join(scene, *lend, off.p.v[t - 1]);
                            vy = cx.occluded ? Color(0.f) : v;
                            occluded_y = cx.occluded && !is_black(v);
                        } else {
                            const ConnectionResult cy =
                                connect(scene, light, off.p, {s, t}, sampler, StrategySet{}, false, rays);
                            vy = cy.value;
                            occluded_y = cy.occluded;
                        }
                        // A pair is formed only where both paths carry a non-zero f
                        // (visibility aside): the rule is the same seen from either path.
                        if (is_black(vy) && !occluded_y) defined = false;
                        // connect() tests the connection's segment only: a blocked
                        // reconnection before it zeroes y as well.
                        if (blocked_y >= 0) vy = Color(0.f);
                        if (defined) {
                            connection_densities(scene, light, off.p, {s, t}, lend, S.dy);
                            strategy_density_ratios(S.dy, t, S.ry);
                            R = off.r[t - 1];
                        }
                    }
                }
            } else {
                // Light tracing: the camera ray through the neighbour's film point, reconnected to z_2.
                Subpath& c1 = S.first;
                trace_camera_subpath(scene, scene.camera().generate_ray(film_x + delta), sampler,
                                     WalkOptions{1, rr_depth_}, c1);
                rays += c1.rays;
                if (c1.size() >= 2) {
                    const Vertex& z2 = light.v[s - 2];
                    const Vertex prefix[2] = {cam.v[0], camera_side_vertex(light.v[s - 1], cam.v[0], z2)};
                    OffsetVertex y1;
                    y1.si = c1.v[1].si;
                    y1.wo = y1.si.frame.to_local(c1.v[1].wo);
                    const ShiftStep st = shift_onto(scene, *shift_, config_, prefix, 1, z2, y1, S.synth);
                    // f(y) = 0: no pair (see the t >= 2 case).
                    const Color v = st.kind == ShiftStep::Kind::Reconnect ? join(scene, z2, c1.v[1]) : Color(0.f);
                    if (!is_black(v)) {
                        defined = true;
                        fy[1] = connectable(c1.v[1]);
                        for (int i = 2; i < n; ++i) fy[i] = fx[i];
                        ++rays;
                        if (segment_visible(scene, z2, c1.v[1])) vy = v;
                        else occluded_y = true;
                        // (s - 1, 2) on the offset's camera subpath is the same path y.
                        connection_densities(scene, light, c1, {s - 1, 2}, &light.v[s - 2], S.dy);
                        // f(y)|J|/p(x): p_{s-1,2}(y)|J| / p_{s,1}(x) = fwd_x[1] / rev_x[1].
                        vy *= float(S.dx.fwd[1] / S.dx.rev[1]);
                        R = (S.dx.fwd[1] / S.dy.fwd[1]) * (S.dy.rev[1] / S.dx.rev[1]);
                        strategy_density_ratios(S.dy, 1, S.ry);
                        if (occluded_y) blocked_y = 1, occluded_y = false;  // y's segment (1, 2), not its t = 1 connection
                        if (!std::isfinite(R) || !std::isfinite(vy.r + vy.g + vy.b)) defined = false;
                    }
                }
            }
            if (!defined) {
                if (!is_black(vx)) {
                    const double w = base_only_weight();
                    add_base(w);
                    if (t >= 2) rec.add_gradient(d, float(-w) * vx);
                    else if (job.splats) job.splats->add(film_x, float(-w) * vx, 1 + d);
                }
                continue;
            }
            if (is_black(vx) && is_black(vy)) continue;
            // The strategies kept for the pair, and those that can produce each path.
            std::vector<uint8_t>& ay = S.ay;
            ay.assign(size_t(n) + 1, 0);
            for (int u = 1; u <= n; ++u) ay[u] = one_ ? u == t : ax[u] && kept(fy.data(), S.dy, u);
            if (!ay[t]) continue;  // this pair does not keep the base's strategy
            S.px = ay, S.py = ay;
            const bool occ_x = cx.occluded;
            if (occ_x) std::fill(S.px.begin(), S.px.end(), 0), S.px[t] = 1;
            if (blocked_y >= 0 && occluded_y) {
                std::fill(S.py.begin(), S.py.end(), 0);  // two blocked segments: no strategy produces y
            } else if (blocked_y >= 0 || occluded_y) {
                const int u = blocked_y >= 0 ? blocked_y + 1 : t;  // the strategy connecting across the blocked segment
                const bool keep = ay[u];
                std::fill(S.py.begin(), S.py.end(), 0);
                S.py[u] = keep;
            }
            const double w = 1.0 / (sum_over(S.rx, S.px) + R * sum_over(S.ry, S.py));
            if (!std::isfinite(w)) continue;
            if (t >= 2) {
                rec.add_self(float(0.25 * w) * vx);
                rec.add_share(d, float(0.25 * w) * vy);
                rec.add_gradient(d, float(w) * (vy - vx));
            } else if (job.splats) {
                job.splats->add(film_x, float(0.25 * w) * vx, 0);
                job.splats->add(film_x + delta, float(0.25 * w) * vy, 0);
                job.splats->add(film_x, float(w) * (vy - vx), 1 + d);
            }
        }
    }

    // Albedo and normal at the first connectable camera vertex, depth of the first hit.
    void write_aux(const CameraPath& cam, GradientRecord& rec) const {
        if (cam.size() < 2 || cam.v[1].infinite) return;
        rec.set_depth(cam.v[1].si.t);
        for (int k = 1; k < int(cam.size()); ++k) {
            const Vertex& v = cam.v[k];
            if (v.infinite) return;
            if (!is_connectable(v.si.material->min_roughness, 0.5f, ShiftConfig{config_.threshold, false}) &&
                k + 1 < int(cam.size()))
                continue;
            rec.set_surface(v.si.material->bsdf->albedo(v.si.uv), v.si.frame.n);
            return;
        }
    }

    std::unique_ptr<Shift> shift_;
    std::string shift_name_;
    ShiftConfig config_;
    float drop_ = 0.001f;
    int max_depth_ = -1, rr_depth_ = 5;
    std::string strategy_ = "all";
    bool one_ = false;
    Connection only_;
    int batch_ = 16;
    GradientReconstructions recon_;
    GradientLayout layout_ = GradientLayout::make();
    std::string shift_params_;  // the shift.* parameters as "key=value" lines
};

}  // namespace

void register_gbdpt(Registry<Integrator>& r) {
    r.add("gbdpt",
          "gradient-domain bidirectional path tracing (params: shift, threshold, drop, max_depth, rr_depth, "
          "strategy=all|s,t, reconstruct, alpha, batch)",
          [](const Params& p) { return std::make_unique<GradientBdpt>(p); });
}

}  // namespace gdr
