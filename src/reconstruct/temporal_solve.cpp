// The window solver of the spatio-temporal screened Poisson reconstruction
// (see gdr/reconstruct/temporal.h): the 3-D DCT direct solve, PCG with the
// 3-D DCT or per-frame multigrid preconditioner, and IRLS for L1.
//
// Internally a window is planar: value (frame f, channel ch, pixel i) at
// (f * C + ch) * n + i, so that every frame's channel is one plane for the
// 2-D DCT solver and the multigrid V-cycle. Storage is float; every sum
// over the window is accumulated in double per fixed task and the task sums
// are added in task order, so results do not depend on thread scheduling.
// Temporal rows may map several pixels of frame f onto one pixel of frame
// f + 1; the transpose gathers through an inverse map (sources of each
// target pixel, in pixel order) instead of scattering, for the same reason.

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>

#include "gdr/core/error.h"
#include "gdr/reconstruct/temporal.h"
#include "multigrid.h"

namespace gdr {
namespace {

constexpr int kBlockRows = 8;  // rows per parallel task; fixed so reductions are deterministic
constexpr double kPi = 3.14159265358979323846;

using Sums = std::array<double, 4>;  // one accumulator per channel

double total(const Sums& s) { return s[0] + s[1] + s[2] + s[3]; }

/// The planar copy of a window and the weights of its rows.
struct Window {
    int w = 0, h = 0, C = 0, F = 0;
    size_t n = 0;  // pixels per plane
    double alpha = 0.2, ws = 1, wt = 1;
    std::vector<float> c, gx, gy, gt;  // targets of the rows (planar)
    // Temporal row of (f, i): the pixel of frame f + 1 it ends at, -1 if dropped.
    std::vector<std::int32_t> target;
    // Inverse map of frame f's rows: sources of pixel j of frame f + 1 are
    // inv_src[inv_off[f * (n + 1) + j] .. inv_off[f * (n + 1) + j + 1]).
    std::vector<std::uint32_t> inv_off;
    std::vector<std::int32_t> inv_src;
    bool motion_free = true;  // every row kept and every target is its own pixel
    long long temporal_rows = 0;
    // Operator weights per pixel (squared row weights folded in; zero on dropped rows).
    std::vector<float> a0, ex, ey, et;

    size_t plane(int f, int ch) const { return (size_t(f) * C + ch) * n; }
    size_t size() const { return size_t(F) * C * n; }
};

/// Runs f(frame, channel, y0, y1) over fixed tasks in parallel; returns the
/// per-channel sums the tasks accumulate, added in task order.
template <class Fn>
Sums for_tasks(const Window& W, Fn&& fn) {
    const int blocks = (W.h + kBlockRows - 1) / kBlockRows;
    const int tasks = W.F * W.C * blocks;
    std::vector<double> part(tasks, 0.0);
    tbb::parallel_for(0, tasks, [&](int t) {
        const int b = t % blocks, ch = (t / blocks) % W.C, f = t / (blocks * W.C);
        part[t] = fn(f, ch, b * kBlockRows, std::min(W.h, (b + 1) * kBlockRows));
    });
    Sums s{0, 0, 0, 0};
    for (int t = 0; t < tasks; ++t) s[(t / blocks) % W.C] += part[t];
    return s;
}

/// Per channel <a, b> over the window.
Sums dot(const Window& W, const float* a, const float* b) {
    return for_tasks(W, [&](int f, int ch, int y0, int y1) {
        const size_t o = W.plane(f, ch) + size_t(y0) * W.w;
        return detail::dot(a + o, b + o, size_t(y1 - y0) * W.w);
    });
}

void to_planar(const Window& W, const ImageView& v, int f, std::vector<float>& out) {
    for (int ch = 0; ch < W.C; ++ch) {
        float* o = out.data() + W.plane(f, ch);
        for (size_t i = 0; i < W.n; ++i) o[i] = v.data[i * W.C + ch];
    }
}

/// Builds the window: planar targets, temporal row map and its inverse.
Window make_window(const std::vector<TemporalFrameView>& frames, const TemporalOptions& opt) {
    check_temporal_frames(frames);
    Window W;
    W.w = frames[0].primal.width, W.h = frames[0].primal.height, W.C = frames[0].primal.channels;
    W.F = int(frames.size()), W.n = size_t(W.w) * W.h;
    W.alpha = opt.alpha, W.ws = opt.w_s, W.wt = opt.w_t;
    const size_t len = W.size();
    W.c.resize(len), W.gx.resize(len), W.gy.resize(len), W.gt.assign(len, 0.f);
    W.target.assign(size_t(W.F) * W.n, -1);
    W.inv_off.assign(size_t(W.F) * (W.n + 1), 0);
    tbb::parallel_for(0, W.F, [&](int f) {
        to_planar(W, frames[f].primal, f, W.c);
        to_planar(W, frames[f].dx, f, W.gx);
        to_planar(W, frames[f].dy, f, W.gy);
        if (f + 1 < W.F && frames[f].dt.data) to_planar(W, frames[f].dt, f, W.gt);
    });
    // With w_t = 0 the energy has no temporal rows at all (and is motion-free).
    for (int f = 0; f + 1 < W.F && opt.w_t > 0; ++f) {
        const TemporalFrameView& fr = frames[f];
        if (!fr.dt.data) {
            W.motion_free = false;
            continue;
        }
        std::int32_t* tg = W.target.data() + size_t(f) * W.n;
        for (int y = 0; y < W.h; ++y)
            for (int x = 0; x < W.w; ++x) {
                const size_t i = size_t(y) * W.w + x;
                if (fr.valid && !(fr.valid[i] >= 0.5f)) continue;
                int qx = x, qy = y;
                if (fr.motion) {
                    // Whole pixels, half away from zero, as the authors' motion maps.
                    qx = x + int(std::lround(fr.motion[2 * i]));
                    qy = y + int(std::lround(fr.motion[2 * i + 1]));
                }
                if (qx < 0 || qy < 0 || qx >= W.w || qy >= W.h) continue;
                tg[i] = std::int32_t(size_t(qy) * W.w + qx);
            }
        // Inverse map, sources of each target in pixel order (deterministic gathers).
        std::uint32_t* off = W.inv_off.data() + size_t(f) * (W.n + 1);
        for (size_t i = 0; i < W.n; ++i)
            if (tg[i] >= 0) ++off[tg[i] + 1];
        for (size_t j = 0; j < W.n; ++j) off[j + 1] += off[j];
        const size_t base = W.inv_src.size();
        W.inv_src.resize(base + off[W.n]);
        std::vector<std::uint32_t> fill(off, off + W.n);
        for (size_t i = 0; i < W.n; ++i)
            if (tg[i] >= 0) W.inv_src[base + fill[tg[i]]++] = std::int32_t(i);
        for (size_t j = 0; j <= W.n; ++j) off[j] += std::uint32_t(base);
        for (size_t i = 0; i < W.n; ++i) {
            if (tg[i] != std::int32_t(i)) W.motion_free = false;
            if (tg[i] >= 0) ++W.temporal_rows;
        }
    }
    return W;
}

/// Unit row weights: a0 = alpha^2, ex = ey = w_s^2 (0 on the dropped border rows), et = w_t^2 where a row exists.
void set_unit_weights(Window& W) {
    const size_t m = size_t(W.F) * W.n;
    W.a0.assign(m, float(W.alpha * W.alpha));
    W.ex.assign(m, float(W.ws * W.ws)), W.ey.assign(m, float(W.ws * W.ws)), W.et.assign(m, 0.f);
    for (int f = 0; f < W.F; ++f) {
        float *ex = W.ex.data() + size_t(f) * W.n, *ey = W.ey.data() + size_t(f) * W.n;
        for (int y = 0; y < W.h; ++y) ex[size_t(y) * W.w + W.w - 1] = 0.f;
        for (int x = 0; x < W.w; ++x) ey[size_t(W.h - 1) * W.w + x] = 0.f;
    }
    for (size_t k = 0; k < m; ++k)
        if (W.target[k] >= 0) W.et[k] = float(W.wt * W.wt);
}

/// out = P^T Wt (t - P x) for all channels, Wt the operator weights and t the
/// row targets (c, gx, gy, gt) if `targets`, else zero (then out = -A x).
/// `flux` is scratch of the window's size (temporal row fluxes).
void normal_residual(const Window& W, const float* x, bool targets, std::vector<float>& flux, float* out) {
    // Temporal fluxes et (gt - (x_{f+1}(q) - x_f(p))) at their source pixel.
    if (flux.size() < W.size()) flux.resize(W.size());
    for_tasks(W, [&](int f, int ch, int y0, int y1) {
        float* fl = flux.data() + W.plane(f, ch);
        const size_t i0 = size_t(y0) * W.w, i1 = size_t(y1) * W.w;
        if (f + 1 == W.F) {
            std::fill(fl + i0, fl + i1, 0.f);
            return 0.0;
        }
        const float *xf = x + W.plane(f, ch), *xn = x + W.plane(f + 1, ch), *g = W.gt.data() + W.plane(f, ch);
        const float* et = W.et.data() + size_t(f) * W.n;
        const std::int32_t* tg = W.target.data() + size_t(f) * W.n;
        for (size_t i = i0; i < i1; ++i)
            fl[i] = tg[i] < 0 ? 0.f : et[i] * ((targets ? g[i] : 0.f) - (xn[tg[i]] - xf[i]));
        return 0.0;
    });
    for_tasks(W, [&](int f, int ch, int y0, int y1) {
        const int w = W.w;
        const size_t o = W.plane(f, ch), wo = size_t(f) * W.n;
        const float *xp = x + o, *c = W.c.data() + o, *gx = W.gx.data() + o, *gy = W.gy.data() + o;
        const float *a0 = W.a0.data() + wo, *ex = W.ex.data() + wo, *ey = W.ey.data() + wo;
        const float* fl = flux.data() + o;
        const float* fl_prev = f > 0 ? flux.data() + W.plane(f - 1, ch) : nullptr;
        const std::uint32_t* off = f > 0 ? W.inv_off.data() + size_t(f - 1) * (W.n + 1) : nullptr;
        float* r = out + o;
        const float t = targets ? 1.f : 0.f;
        for (int y = y0; y < y1; ++y) {
            const size_t row = size_t(y) * w;
            for (int xi = 0; xi < w; ++xi) {
                const size_t i = row + xi;
                float v = a0[i] * (t * c[i] - xp[i]);
                if (xi + 1 < w) v -= ex[i] * (t * gx[i] - (xp[i + 1] - xp[i]));
                if (xi > 0) v += ex[i - 1] * (t * gx[i - 1] - (xp[i] - xp[i - 1]));
                if (y + 1 < W.h) v -= ey[i] * (t * gy[i] - (xp[i + w] - xp[i]));
                if (y > 0) v += ey[i - w] * (t * gy[i - w] - (xp[i] - xp[i - w]));
                v -= fl[i];
                if (off)
                    for (std::uint32_t k = off[i]; k < off[i + 1]; ++k) v += fl_prev[W.inv_src[k]];
                r[i] = v;
            }
        }
        return 0.0;
    });
}

/// A preconditioner z = M^-1 r of the current operator weights.
class WindowPreconditioner {
public:
    WindowPreconditioner(Window& W, TemporalPreconditioner kind) : W_(W), kind_(kind) {
        if (kind_ == TemporalPreconditioner::dct) setup_dct();
        if (kind_ == TemporalPreconditioner::frame_multigrid) setup_multigrid();
    }

    void apply(const float* r, float* z) {
        if (kind_ == TemporalPreconditioner::none) std::copy(r, r + W_.size(), z);
        else if (kind_ == TemporalPreconditioner::dct) apply_dct(r, z);
        else apply_multigrid(r, z);
    }

    /// The exact inverse of the motion-free operator with weights a I + b L_xy + c L_t.
    void solve_dct(const float* r, float* z, double a, double b, double c) {
        a_ = a, b_ = b, c_ = c;
        apply_dct(r, z);
    }

private:
    void setup_dct() {
        // Mean weights over the rows in use: exact for unit weights without motion.
        double s0 = 0, sg = 0, ng = 0, st = 0, nt = 0;
        const size_t m = size_t(W_.F) * W_.n;
        for (size_t k = 0; k < m; ++k) {
            s0 += W_.a0[k];
            const int x = int(k % W_.n % W_.w), y = int(k % W_.n / W_.w);
            if (x + 1 < W_.w) sg += W_.ex[k], ng += 1;
            if (y + 1 < W_.h) sg += W_.ey[k], ng += 1;
            if (W_.target[k] >= 0) st += W_.et[k], nt += 1;
        }
        a_ = s0 / double(m);
        b_ = ng > 0 ? sg / ng : 0.0;
        c_ = nt > 0 ? st / nt : 0.0;
    }

    void apply_dct(const float* r, float* z) {
        const int F = W_.F, C = W_.C;
        const size_t n = W_.n;
        if (!dct_) dct_ = std::make_unique<DctSolver>(W_.w, W_.h);
        // Orthonormal DCT-II along time: T[k][f] = s_k cos(pi k (f + 1/2) / F).
        std::vector<double> T(size_t(F) * F);
        for (int k = 0; k < F; ++k)
            for (int f = 0; f < F; ++f)
                T[size_t(k) * F + f] = std::sqrt((k == 0 ? 1.0 : 2.0) / F) * std::cos(kPi * k * (f + 0.5) / F);
        spectrum_.resize(W_.size());
        auto transform = [&](const float* in, float* out, bool inverse) {
            const size_t chunk = 4096;
            const size_t tasks = (n + chunk - 1) / chunk;
            tbb::parallel_for(size_t(0), tasks * C, [&](size_t t) {
                const int ch = int(t / tasks);
                const size_t i0 = (t % tasks) * chunk, i1 = std::min(n, i0 + chunk);
                for (int k = 0; k < F; ++k) {
                    float* o = out + W_.plane(k, ch);
                    for (size_t i = i0; i < i1; ++i) o[i] = 0.f;
                    for (int f = 0; f < F; ++f) {
                        const float tk = float(inverse ? T[size_t(f) * F + k] : T[size_t(k) * F + f]);
                        const float* s = in + W_.plane(f, ch);
                        for (size_t i = i0; i < i1; ++i) o[i] += tk * s[i];
                    }
                }
            });
        };
        transform(r, spectrum_.data(), false);
        for (int k = 0; k < F; ++k) {
            const double lt = 2.0 - 2.0 * std::cos(kPi * k / F);
            float* plane = spectrum_.data() + W_.plane(k, 0);
            dct_->solve(plane, plane, C, a_ + c_ * lt, b_);
        }
        transform(spectrum_.data(), z, true);
    }

    void setup_multigrid() {
        // Each frame's diagonal block: colour weight plus the temporal rows touching the pixel.
        diag_.resize(size_t(W_.F) * W_.n);
        mg_.resize(W_.F);
        tbb::parallel_for(0, W_.F, [&](int f) {
            float* d = diag_.data() + size_t(f) * W_.n;
            const float *a0 = W_.a0.data() + size_t(f) * W_.n, *et = W_.et.data() + size_t(f) * W_.n;
            for (size_t i = 0; i < W_.n; ++i) d[i] = a0[i] + et[i];
            if (f > 0) {
                const std::uint32_t* off = W_.inv_off.data() + size_t(f - 1) * (W_.n + 1);
                const float* etp = W_.et.data() + size_t(f - 1) * W_.n;
                for (size_t j = 0; j < W_.n; ++j)
                    for (std::uint32_t k = off[j]; k < off[j + 1]; ++k) d[j] += etp[W_.inv_src[k]];
            }
            mg_[f] = std::make_unique<detail::WeightedMultigrid>();
            mg_[f]->setup(W_.w, W_.h, d, W_.ex.data() + size_t(f) * W_.n, W_.ey.data() + size_t(f) * W_.n);
        });
    }

    void apply_multigrid(const float* r, float* z) {
        tbb::parallel_for(0, W_.F, [&](int f) {
            const size_t o = W_.plane(f, 0);
            mg_[f]->apply(r + o, z + o, W_.C);
        });
    }

    Window& W_;
    TemporalPreconditioner kind_;
    double a_ = 0, b_ = 0, c_ = 0;
    std::unique_ptr<DctSolver> dct_;
    std::vector<float> spectrum_;
    std::vector<float> diag_;
    std::vector<std::unique_ptr<detail::WeightedMultigrid>> mg_;
};

struct CgResult {
    int iterations = 0;
    double relative_residual = 0;
};

/// PCG on A x = b (current operator weights) from and into x, with one set
/// of CG scalars per channel (the channels are independent systems).
CgResult run_pcg(Window& W, TemporalPreconditioner kind, int max_iterations, double tolerance, std::vector<float>& x) {
    const size_t len = W.size();
    const int C = W.C;
    std::vector<float> r(len), z(len), p(len), q(len), flux;
    normal_residual(W, x.data(), true, flux, r.data());
    CgResult res;
    const double r0 = total(dot(W, r.data(), r.data()));
    if (!(r0 > 0) || max_iterations == 0) return res;
    WindowPreconditioner M(W, kind);
    M.apply(r.data(), z.data());
    Sums rz = dot(W, r.data(), z.data());
    p = z;
    bool active[4] = {true, true, true, true};
    for (int it = 1; it <= max_iterations; ++it) {
        normal_residual(W, p.data(), false, flux, q.data());  // q = -A p
        Sums pq = dot(W, p.data(), q.data());
        float step[4] = {0, 0, 0, 0};
        for (int ch = 0; ch < C; ++ch) {
            const double a = rz[ch] / -pq[ch];
            if (!(-pq[ch] > 0) || !std::isfinite(a)) active[ch] = false;  // solved, or lost to rounding
            step[ch] = active[ch] ? float(a) : 0.f;
        }
        if (std::none_of(active, active + C, [](bool b) { return b; })) break;
        const Sums rr = for_tasks(W, [&](int f, int ch, int y0, int y1) {
            const size_t o0 = W.plane(f, ch) + size_t(y0) * W.w, o1 = W.plane(f, ch) + size_t(y1) * W.w;
            const float a = step[ch];
            for (size_t i = o0; i < o1; ++i) x[i] += a * p[i], r[i] += a * q[i];
            return detail::dot(r.data() + o0, r.data() + o0, o1 - o0);
        });
        res.iterations = it;
        res.relative_residual = std::sqrt(total(rr) / r0);
        if (!std::isfinite(res.relative_residual) || res.relative_residual <= tolerance) break;
        M.apply(r.data(), z.data());
        const Sums rz_new = dot(W, r.data(), z.data());
        float beta[4] = {0, 0, 0, 0};
        for (int ch = 0; ch < C; ++ch) beta[ch] = rz[ch] > 0 && active[ch] ? float(rz_new[ch] / rz[ch]) : 0.f;
        rz = rz_new;
        for_tasks(W, [&](int f, int ch, int y0, int y1) {
            const size_t o0 = W.plane(f, ch) + size_t(y0) * W.w, o1 = W.plane(f, ch) + size_t(y1) * W.w;
            for (size_t i = o0; i < o1; ++i) p[i] = z[i] + beta[ch] * p[i];
            return 0.0;
        });
    }
    return res;
}

/// IRLS weights at x: every row r (channels jointly) gets eps / (|e_r| + eps),
/// proportional to the reference's 1 / (|e_r| + eps), then all are scaled to
/// mean 1 over the rows in use; the squared row weights are folded in.
void reweight(Window& W, const std::vector<float>& x, double eps) {
    const size_t m = size_t(W.F) * W.n;
    const int C = W.C, w = W.w, h = W.h;
    std::vector<double> part(W.F, 0.0);
    const float e = float(eps);
    tbb::parallel_for(0, W.F, [&](int f) {
        double s = 0;
        for (int y = 0; y < h; ++y)
            for (int xi = 0; xi < w; ++xi) {
                const size_t i = size_t(y) * w + xi, k = size_t(f) * W.n + i;
                double s0 = 0, sx = 0, sy = 0, st = 0;
                const std::int32_t tg = W.target[k];
                for (int ch = 0; ch < C; ++ch) {
                    const size_t o = W.plane(f, ch) + i;
                    const double d0 = double(x[o]) - W.c[o];
                    s0 += d0 * d0;
                    if (xi + 1 < w) {
                        const double d = double(x[o + 1]) - x[o] - W.gx[o];
                        sx += d * d;
                    }
                    if (y + 1 < h) {
                        const double d = double(x[o + w]) - x[o] - W.gy[o];
                        sy += d * d;
                    }
                    if (tg >= 0) {
                        const double d = double(x[W.plane(f + 1, ch) + tg]) - x[o] - W.gt[o];
                        st += d * d;
                    }
                }
                const float u0 = e / float(W.alpha * std::sqrt(s0) + eps);
                const float ux = xi + 1 < w ? e / float(W.ws * std::sqrt(sx) + eps) : 0.f;
                const float uy = y + 1 < h ? e / float(W.ws * std::sqrt(sy) + eps) : 0.f;
                const float ut = tg >= 0 ? e / float(W.wt * std::sqrt(st) + eps) : 0.f;
                W.a0[k] = u0, W.ex[k] = ux, W.ey[k] = uy, W.et[k] = ut;
                s += double(u0) + ux + uy + ut;
            }
        part[f] = s;
    });
    double sum = 0;
    for (double s : part) sum += s;
    const double rows = double(m) + double(W.F) * (double(w - 1) * h + double(h - 1) * w) + double(W.temporal_rows);
    const double k = rows / sum;  // mean 1 over the rows in use
    const float fa = float(k * W.alpha * W.alpha), fs = float(k * W.ws * W.ws), ft = float(k * W.wt * W.wt);
    tbb::parallel_for(size_t(0), m, [&](size_t i) {
        W.a0[i] *= fa, W.ex[i] *= fs, W.ey[i] *= fs, W.et[i] *= ft;
    });
}

}  // namespace

void check_temporal_frames(const std::vector<TemporalFrameView>& frames) {
    if (frames.empty()) throw ParameterError("temporal reconstruction: the window has no frames");
    const ImageView& p0 = frames[0].primal;
    for (size_t f = 0; f < frames.size(); ++f) {
        const std::string where = "temporal reconstruction: frame " + std::to_string(f) + " of the window: ";
        auto check = [&](const ImageView& v, const char* name, bool optional) {
            if (!v.data) {
                if (optional) return;
                throw ParameterError(where + "no layer '" + name + "'");
            }
            if (v.width < 1 || v.height < 1 || v.channels < 1 || v.channels > 4 || v.width != p0.width ||
                v.height != p0.height || v.channels != p0.channels)
                throw ParameterError(where + "layer '" + name + "' is " + std::to_string(v.width) + "x" +
                                     std::to_string(v.height) + "x" + std::to_string(v.channels) +
                                     " but the first frame's primal is " + std::to_string(p0.width) + "x" +
                                     std::to_string(p0.height) + "x" + std::to_string(p0.channels));
        };
        check(frames[f].primal, "primal", false);
        check(frames[f].dx, "dx", false);
        check(frames[f].dy, "dy", false);
        check(frames[f].dt, "dt", true);
    }
}

TemporalReport solve_temporal_window(const std::vector<TemporalFrameView>& frames, const TemporalOptions& opt,
                                     const std::vector<float*>& out) {
    check_temporal_options(opt);
    if (out.size() != frames.size())
        throw ParameterError("temporal reconstruction: " + std::to_string(out.size()) + " outputs for " +
                             std::to_string(frames.size()) + " frames");
    Window W = make_window(frames, opt);
    TemporalReport rep;
    rep.temporal_rows = W.temporal_rows;
    set_unit_weights(W);
    std::vector<float> x(W.size(), 0.f), flux;
    const bool exact = W.motion_free;
    if (opt.solver == TemporalSolver::dct && !exact)
        throw ParameterError("temporal reconstruction: solver=dct needs a window without motion or dropped rows "
                             "(use solver=cg or auto)");
    if (opt.solver != TemporalSolver::cg && exact) {
        std::vector<float> rhs(W.size());
        normal_residual(W, x.data(), true, flux, rhs.data());  // b
        WindowPreconditioner dct(W, TemporalPreconditioner::none);
        dct.solve_dct(rhs.data(), x.data(), W.alpha * W.alpha, W.ws * W.ws, opt.w_t == 0 ? 0.0 : W.wt * W.wt);
        rep.direct_solve = true;
    } else {
        // From zero: the first preconditioned step is then the motion-free solve of b.
        const CgResult cg = run_pcg(W, opt.l2_preconditioner, opt.cg_iterations, opt.tolerance, x);
        rep.cg_iterations = cg.iterations, rep.relative_residual = cg.relative_residual;
    }
    rep.irls_iterations = 1;
    if (opt.norm == TemporalNorm::l1) {
        double eps = opt.eps_initial;
        for (int k = 1; k < opt.irls_iterations; ++k, eps *= opt.eps_factor) {
            reweight(W, x, eps);
            rep.irls_cg_iterations +=
                run_pcg(W, opt.irls_preconditioner, opt.irls_cg_iterations, opt.irls_tolerance, x).iterations;
            rep.irls_iterations = k + 1;
        }
    }
    std::vector<const float*> results;
    for (int f = 0; f < W.F; ++f) {
        float* o = out[f];
        for (int ch = 0; ch < W.C; ++ch) {
            const float* s = x.data() + W.plane(f, ch);
            for (size_t i = 0; i < W.n; ++i) o[i * W.C + ch] = s[i];
        }
        check_finite_result(ImageView{o, W.w, W.h, W.C}, "temporal reconstruction, frame " + std::to_string(f) +
                                                             " of the window");
        results.push_back(o);
    }
    rep.energy = temporal_energy(frames, opt, results, opt.norm);
    return rep;
}

double temporal_energy(const std::vector<TemporalFrameView>& frames, const TemporalOptions& opt,
                       const std::vector<const float*>& x, TemporalNorm norm) {
    check_temporal_frames(frames);
    if (x.size() != frames.size()) throw ParameterError("temporal_energy: one image per frame needed");
    const int w = frames[0].primal.width, h = frames[0].primal.height, C = frames[0].primal.channels;
    const int F = int(frames.size());
    std::vector<double> part(F, 0.0);
    tbb::parallel_for(0, F, [&](int f) {
        const TemporalFrameView& fr = frames[f];
        const bool temporal = f + 1 < F && fr.dt.data && opt.w_t > 0;
        auto add = [&](double sq, double weight) {
            part[f] += norm == TemporalNorm::l2 ? weight * weight * sq : weight * std::sqrt(sq);
        };
        for (int y = 0; y < h; ++y)
            for (int xi = 0; xi < w; ++xi) {
                const size_t i = size_t(y) * w + xi;
                double s0 = 0, sx = 0, sy = 0, st = 0;
                int q = -1;
                if (temporal && (!fr.valid || fr.valid[i] >= 0.5f)) {
                    const int qx = xi + (fr.motion ? int(std::lround(fr.motion[2 * i])) : 0);
                    const int qy = y + (fr.motion ? int(std::lround(fr.motion[2 * i + 1])) : 0);
                    if (qx >= 0 && qy >= 0 && qx < w && qy < h) q = qy * w + qx;
                }
                for (int ch = 0; ch < C; ++ch) {
                    const size_t o = i * C + ch;
                    const double v = x[f][o];
                    s0 += (v - fr.primal.data[o]) * (v - fr.primal.data[o]);
                    if (xi + 1 < w) sx += std::pow(x[f][o + C] - v - fr.dx.data[o], 2);
                    if (y + 1 < h) sy += std::pow(x[f][o + size_t(w) * C] - v - fr.dy.data[o], 2);
                    if (q >= 0) st += std::pow(x[f + 1][size_t(q) * C + ch] - v - fr.dt.data[o], 2);
                }
                add(s0, opt.alpha);
                if (xi + 1 < w) add(sx, opt.w_s);
                if (y + 1 < h) add(sy, opt.w_s);
                if (q >= 0) add(st, opt.w_t);
            }
    });
    double e = 0;
    for (double p : part) e += p;
    return e;
}

}  // namespace gdr
