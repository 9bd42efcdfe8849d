// Screened Poisson solvers: exact L2 through the DCT, weighted (P)CG, and
// IRLS for L1 (see gdr/reconstruct/poisson.h and ALGORITHMS.md section 4).
//
// Internally images are planar (one plane per channel) so that the FFTs and
// the stencil loops run over contiguous rows. Storage is float; every sum
// over the image (dot products, energies) is accumulated in double over
// fixed row blocks and combined in block order, so results do not depend on
// thread scheduling. The normal-equation right-hand side is never formed:
// the CG residual b - A x is computed directly as P^T W (b - P x) from the
// row residuals, which is one pass instead of three.

#include "gdr/reconstruct/poisson.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <cmath>
#include <string>

#include "gdr/core/error.h"
#include "multigrid.h"

namespace gdr {
namespace {

constexpr int kBlockRows = 8;  // rows per parallel task; fixed so reductions are deterministic

using Sums = std::array<double, 4>;  // one accumulator per channel

/// Runs f(y0, y1) over fixed blocks of rows in parallel.
template <class F>
void for_rows(int h, F&& f) {
    const int blocks = (h + kBlockRows - 1) / kBlockRows;
    if (blocks == 1) return f(0, h);
    tbb::parallel_for(0, blocks, [&](int b) { f(b * kBlockRows, std::min(h, (b + 1) * kBlockRows)); });
}

/// Runs f(y0, y1, Sums&) over fixed row blocks and adds the block sums in block order.
template <class F>
Sums sum_rows(int h, F&& f) {
    const int blocks = (h + kBlockRows - 1) / kBlockRows;
    std::vector<Sums> part(blocks, Sums{0, 0, 0, 0});
    tbb::parallel_for(0, blocks, [&](int b) { f(b * kBlockRows, std::min(h, (b + 1) * kBlockRows), part[b]); });
    Sums total{0, 0, 0, 0};
    for (const auto& s : part)
        for (int c = 0; c < 4; ++c) total[c] += s[c];
    return total;
}

double total(const Sums& s) { return s[0] + s[1] + s[2] + s[3]; }

/// sqrt(s) for s >= 0 that the compiler can vectorise (std::sqrt cannot be,
/// because it may set errno): the classic bit-level estimate of 1/sqrt(s)
/// refined by two Newton steps (relative error 5e-10 before rounding), times
/// s. Used only for IRLS weights, where a few ulp do not matter.
inline float sqrt_nonneg(float s) {
    float r = std::bit_cast<float>(0x5f375a86u - (std::bit_cast<std::uint32_t>(s) >> 1));
    r = r * (1.5f - 0.5f * s * r * r);
    r = r * (1.5f - 0.5f * s * r * r);
    return s * r;
}

/// IRLS weights of one row from the squared row-residual norms: colour
/// a0 / (a |e| + eps), gradients eps / (|e| + eps). Restrict-qualified so the
/// loop vectorises.
void weight_row(int w, float a, float a0, float eps, const float* __restrict s0, const float* __restrict sx,
                const float* __restrict sy, float* __restrict w0, float* __restrict wx, float* __restrict wy) {
    for (int i = 0; i < w; ++i) {
        w0[i] = a0 / (a * sqrt_nonneg(s0[i]) + eps);
        wx[i] = eps / (sqrt_nonneg(sx[i]) + eps);
        wy[i] = eps / (sqrt_nonneg(sy[i]) + eps);
    }
}

/// sum a[i] in double (four accumulators, see dot).
inline double sum(const float* a, size_t n) {
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    size_t i = 0;
    for (; i + 4 <= n; i += 4) s0 += a[i], s1 += a[i + 1], s2 += a[i + 2], s3 += a[i + 3];
    for (; i < n; ++i) s0 += a[i];
    return (s0 + s1) + (s2 + s3);
}


/// Per-thread scratch rows (3 of them).
float* scratch(size_t n) {
    thread_local std::vector<float> buf;
    if (buf.size() < 3 * n) buf.resize(3 * n);
    return buf.data();
}

struct Shape {
    int w, h, c;
    size_t n;  // pixels per plane
};

Shape shape_of(const PoissonProblem& p) {
    return {p.primal.width, p.primal.height, p.primal.channels, size_t(p.primal.width) * p.primal.height};
}

void to_planar(const Shape& s, const float* in, float* out) {
    for_rows(s.h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int c = 0; c < s.c; ++c) {
                float* o = out + c * s.n + size_t(y) * s.w;
                const float* i = in + size_t(y) * s.w * s.c + c;
                for (int x = 0; x < s.w; ++x) o[x] = i[size_t(x) * s.c];
            }
    });
}

void to_interleaved(const Shape& s, const float* in, float* out) {
    for_rows(s.h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
            for (int c = 0; c < s.c; ++c) {
                const float* i = in + c * s.n + size_t(y) * s.w;
                float* o = out + size_t(y) * s.w * s.c + c;
                for (int x = 0; x < s.w; ++x) o[size_t(x) * s.c] = i[x];
            }
    });
}

/// Operator weights, per pixel and shared by the channels: a0w0 = alpha^2 *
/// colour weight; wx / wy are zero on the dropped rows, so stencils need no
/// special case for them. Their overall scale is arbitrary (it cancels).
struct OpWeights {
    std::vector<float> a0w0, wx, wy;
    double mean_a0w0 = 0, mean_gradient = 0;  // for the DCT preconditioner (set_weight_means)
};

void set_unit_weights(const Shape& s, double alpha, OpWeights& W) {
    W.a0w0.assign(s.n, float(alpha * alpha));
    W.wx.assign(s.n, 1.f), W.wy.assign(s.n, 1.f);
    for (int y = 0; y < s.h; ++y) W.wx[size_t(y) * s.w + s.w - 1] = 0.f;
    for (int x = 0; x < s.w; ++x) W.wy[size_t(s.h - 1) * s.w + x] = 0.f;
    W.mean_a0w0 = alpha * alpha, W.mean_gradient = 1.0;
}

/// The planar copy of a problem and the vectors of its solves.
struct Workspace {
    Shape s;
    double alpha;
    std::vector<float> c, gx, gy, x, r, z, p, p2, q;
    OpWeights W;
    std::unique_ptr<DctSolver> dct;
    detail::WeightedMultigrid mg;

    explicit Workspace(const PoissonProblem& prob) : s(shape_of(prob)), alpha(prob.alpha) {
        const size_t len = s.n * s.c;
        c.resize(len), gx.resize(len), gy.resize(len), x.resize(len);
        r.resize(len), z.resize(len), p.resize(len), p2.resize(len), q.resize(len);
        to_planar(s, prob.primal.data, c.data());
        to_planar(s, prob.dx.data, gx.data());
        to_planar(s, prob.dy.data, gy.data());
    }
    DctSolver& dct_solver() {
        if (!dct) dct = std::make_unique<DctSolver>(s.w, s.h);
        return *dct;
    }
};

/// r = P^T W (b - P x) = b - A x (the CG residual) from the row residuals;
/// returns |r|^2 per channel.
Sums normal_residual(Workspace& ws, const OpWeights& W) {
    const Shape& s = ws.s;
    const int w = s.w, h = s.h;
    return sum_rows(h, [&](int y0, int y1, Sums& acc) {
        float* fx = scratch(size_t(w));
        for (int y = y0; y < y1; ++y) {
            const size_t row = size_t(y) * w;
            const float *a0 = W.a0w0.data() + row, *wx = W.wx.data() + row, *wy = W.wy.data() + row;
            for (int ch = 0; ch < s.c; ++ch) {
                const size_t o = ch * s.n + row;
                const float *x = ws.x.data() + o, *c = ws.c.data() + o, *gx = ws.gx.data() + o, *gy = ws.gy.data() + o;
                float* r = ws.r.data() + o;
                // Weighted horizontal row residuals f = wx (gx - Dx x); zero in the last column.
                for (int i = 0; i + 1 < w; ++i) fx[i] = wx[i] * (gx[i] - (x[i + 1] - x[i]));
                fx[w - 1] = 0.f;
                r[0] = a0[0] * (c[0] - x[0]) - fx[0];
                for (int i = 1; i < w; ++i) r[i] = a0[i] * (c[i] - x[i]) + fx[i - 1] - fx[i];
                if (y + 1 < h) {
                    const float* xd = x + w;
                    for (int i = 0; i < w; ++i) r[i] -= wy[i] * (gy[i] - (xd[i] - x[i]));
                }
                if (y > 0) {
                    const float *xu = x - w, *gyu = gy - w, *wyu = wy - w;
                    for (int i = 0; i < w; ++i) r[i] += wyu[i] * (gyu[i] - (x[i] - xu[i]));
                }
                acc[ch] += detail::dot(r, r, size_t(w));
            }
        }
    });
}

template <bool Up, bool Down>
inline void operator_row(int w, const float* a0, const float* wx, const float* wyu, const float* wyd,
                         const float* pu, const float* pr, const float* pd, float* qr) {
    auto vertical = [&](int i) {
        float v = 0.f;
        if constexpr (Up) v += wyu[i] * (pr[i] - pu[i]);
        if constexpr (Down) v += wyd[i] * (pr[i] - pd[i]);
        return v;
    };
    if (w == 1) {
        qr[0] = a0[0] * pr[0] + vertical(0);
        return;
    }
    qr[0] = a0[0] * pr[0] + wx[0] * (pr[0] - pr[1]) + vertical(0);
    for (int i = 1; i < w - 1; ++i)
        qr[i] = a0[i] * pr[i] + wx[i] * (pr[i] - pr[i + 1]) + wx[i - 1] * (pr[i] - pr[i - 1]) + vertical(i);
    qr[w - 1] = a0[w - 1] * pr[w - 1] + wx[w - 2] * (pr[w - 1] - pr[w - 2]) + vertical(w - 1);
}

/// q = A p for all channels, A = alpha^2 W0 + Dx^T Wx Dx + Dy^T Wy Dy; returns <p, q> per channel.
Sums apply_operator(const Shape& s, const OpWeights& W, const float* p, float* q) {
    const int w = s.w, h = s.h;
    return sum_rows(h, [&](int y0, int y1, Sums& acc) {
        for (int y = y0; y < y1; ++y) {
            const size_t row = size_t(y) * w;
            const float *a0 = W.a0w0.data() + row, *wx = W.wx.data() + row, *wy = W.wy.data() + row;
            const float* wyu = y > 0 ? wy - w : wy;  // (not read in the first row)
            for (int ch = 0; ch < s.c; ++ch) {
                const float* pr = p + ch * s.n + row;
                float* qr = q + ch * s.n + row;
                const bool up = y > 0, down = y + 1 < h;
                if (up && down) operator_row<true, true>(w, a0, wx, wyu, wy, pr - w, pr, pr + w, qr);
                else if (up) operator_row<true, false>(w, a0, wx, wyu, wy, pr - w, pr, nullptr, qr);
                else if (down) operator_row<false, true>(w, a0, wx, wyu, wy, nullptr, pr, pr + w, qr);
                else operator_row<false, false>(w, a0, wx, wyu, wy, nullptr, pr, nullptr, qr);
                acc[ch] += detail::dot(pr, qr, size_t(w));
            }
        }
    });
}

/// p = z + beta p_old and q = A p in one pass (returns <p, q> per channel):
/// A p at a row needs p of the rows above and below, which for a block's
/// first and last row belong to other blocks; they are recomputed from z and
/// p_old (read-only here) rather than read back. p must not alias z or p_old.
Sums update_and_apply(const Shape& s, const OpWeights& W, const float* z, const float* p_old, const float beta[4],
                      float* p, float* q) {
    const int w = s.w, h = s.h;
    return sum_rows(h, [&](int y0, int y1, Sums& acc) {
        float* halo = scratch(size_t(w));  // rows y0 - 1 and y1 of p
        float *above = halo, *below = halo + w;
        for (int ch = 0; ch < s.c; ++ch) {
            const size_t plane = ch * s.n;
            const float b = beta[ch];
            auto form = [&](int y, float* out) {
                const float *zr = z + plane + size_t(y) * w, *pr = p_old + plane + size_t(y) * w;
                for (int i = 0; i < w; ++i) out[i] = zr[i] + b * pr[i];
            };
            for (int y = y0; y < y1; ++y) form(y, p + plane + size_t(y) * w);
            if (y0 > 0) form(y0 - 1, above);
            if (y1 < h) form(y1, below);
            for (int y = y0; y < y1; ++y) {
                const size_t row = size_t(y) * w;
                const float *a0 = W.a0w0.data() + row, *wx = W.wx.data() + row, *wy = W.wy.data() + row;
                const float* wyu = y > 0 ? wy - w : wy;
                const float* pr = p + plane + row;
                const float* pu = y == y0 ? above : pr - w;
                const float* pd = y + 1 == y1 ? below : pr + w;
                float* qr = q + plane + row;
                const bool up = y > 0, down = y + 1 < h;
                if (up && down) operator_row<true, true>(w, a0, wx, wyu, wy, pu, pr, pd, qr);
                else if (up) operator_row<true, false>(w, a0, wx, wyu, wy, pu, pr, nullptr, qr);
                else if (down) operator_row<false, true>(w, a0, wx, wyu, wy, nullptr, pr, pd, qr);
                else operator_row<false, false>(w, a0, wx, wyu, wy, nullptr, pr, nullptr, qr);
                acc[ch] += detail::dot(pr, qr, size_t(w));
            }
        }
    });
}

/// Smallest eps relative to the largest row residual of the previous
/// iterate. Weights span (|e|max + eps) / eps; beyond ~1e9 float stencils
/// and the coarse factor lose the small weights entirely. The default
/// schedule (20 steps, eps >= 1.9e-7) never reaches the floor for residuals
/// below ~190.
constexpr float kEpsFloor = 1e-9f;

/// One IRLS reweighting fused with the CG residual, in a single pass over
/// x, c, gx, gy: every residual row r (channels jointly) gets the reference
/// weight 1 / (|e_r| + eps), here scaled by eps to eps / (|e_r| + eps) in
/// (0, 1] (a common factor cancels in the solution; this one needs no second
/// pass to normalise and keeps the numbers in float range), then
/// ws.r = P^T W (b - P x). Returns |r|^2 per channel; max_norm receives the
/// largest |e_r|. Each row block recomputes the vertical residual of the row
/// above it instead of waiting for the neighbouring block.
Sums reweight_and_residual(Workspace& ws, float eps, OpWeights& W, float& max_norm) {
    const Shape& s = ws.s;
    const int w = s.w, h = s.h, C = s.c;
    W.a0w0.resize(s.n), W.wx.resize(s.n), W.wy.resize(s.n);
    const float a = float(ws.alpha), a2 = float(ws.alpha * ws.alpha);
    const int blocks = (h + kBlockRows - 1) / kBlockRows;
    std::vector<float> block_max(blocks, 0.f);
    const Sums rr = sum_rows(h, [&](int y0, int y1, Sums& acc) {
        // Scratch: per channel e0 = c - x, ex = gx - Dx x, ey (this row and the one above); 3 norm rows; wy above.
        thread_local std::vector<float> buf;
        const size_t cw = size_t(C) * w;
        if (buf.size() < 4 * cw + 4 * size_t(w)) buf.resize(4 * cw + 4 * size_t(w));
        float *e0 = buf.data(), *ex = e0 + cw, *ey = ex + cw, *ey_up = ey + cw;
        float *s0 = ey_up + cw, *sx = s0 + w, *sy = sx + w, *wy_halo = sy + w;
        const float* wy_up = nullptr;
        // Vertical residual rows of channel ch at row y into out; returns nothing, accumulates squares into sq.
        auto vertical = [&](int y, float* out, float* sq) {
            for (int ch = 0; ch < C; ++ch) {
                const size_t o = ch * s.n + size_t(y) * w;
                const float *x = ws.x.data() + o, *xd = x + w, *gy = ws.gy.data() + o;
                float* e = out + size_t(ch) * w;
                for (int i = 0; i < w; ++i) {
                    e[i] = gy[i] - (xd[i] - x[i]);
                    sq[i] += e[i] * e[i];
                }
            }
        };
        if (y0 > 0) {  // halo: the row above this block
            std::fill(sy, sy + w, 0.f);
            vertical(y0 - 1, ey_up, sy);
            for (int i = 0; i < w; ++i) wy_halo[i] = eps / (sqrt_nonneg(sy[i]) + eps);
            wy_up = wy_halo;
        }
        float m2 = 0.f;  // largest squared row residual
        for (int y = y0; y < y1; ++y) {
            const size_t row = size_t(y) * w;
            const bool down = y + 1 < h;
            std::fill(s0, s0 + 3 * size_t(w), 0.f);
            for (int ch = 0; ch < C; ++ch) {
                const size_t o = ch * s.n + row;
                const float *x = ws.x.data() + o, *c = ws.c.data() + o, *gx = ws.gx.data() + o;
                float *e0c = e0 + size_t(ch) * w, *exc = ex + size_t(ch) * w;
                for (int i = 0; i < w; ++i) {
                    e0c[i] = c[i] - x[i];
                    s0[i] += e0c[i] * e0c[i];
                }
                for (int i = 0; i + 1 < w; ++i) {
                    exc[i] = gx[i] - (x[i + 1] - x[i]);
                    sx[i] += exc[i] * exc[i];
                }
                exc[w - 1] = 0.f;
            }
            if (down) vertical(y, ey, sy);
            float *w0 = W.a0w0.data() + row, *wx = W.wx.data() + row, *wy = W.wy.data() + row;
            weight_row(w, a, a2 * eps, eps, s0, sx, sy, w0, wx, wy);
            for (int i = 0; i < w; ++i) m2 = std::max(m2, std::max(a2 * s0[i], std::max(sx[i], sy[i])));
            wx[w - 1] = 0.f;
            if (!down) std::fill(wy, wy + w, 0.f);
            // r = w0 (c - x) + (fx(i-1) - fx(i)) + (fy(y-1) - fy(y)), f = weight * row residual.
            for (int ch = 0; ch < C; ++ch) {
                float* r = ws.r.data() + ch * s.n + row;
                const float *e0c = e0 + size_t(ch) * w, *exc = ex + size_t(ch) * w;
                r[0] = w0[0] * e0c[0] - wx[0] * exc[0];
                for (int i = 1; i < w; ++i) r[i] = w0[i] * e0c[i] + wx[i - 1] * exc[i - 1] - wx[i] * exc[i];
                if (down) {
                    const float* eyc = ey + size_t(ch) * w;
                    for (int i = 0; i < w; ++i) r[i] -= wy[i] * eyc[i];
                }
                if (wy_up) {
                    const float* eyu = ey_up + size_t(ch) * w;
                    for (int i = 0; i < w; ++i) r[i] += wy_up[i] * eyu[i];
                }
                acc[ch] += detail::dot(r, r, size_t(w));
            }
            std::swap(ey, ey_up);
            wy_up = wy;
        }
        block_max[y0 / kBlockRows] = std::sqrt(m2);
    });
    max_norm = *std::max_element(block_max.begin(), block_max.end());
    return rr;
}

/// Mean colour and gradient weights (over the rows in use), for the DCT preconditioner.
void set_weight_means(const Shape& s, OpWeights& W) {
    const Sums sums = sum_rows(s.h, [&](int y0, int y1, Sums& acc) {
        for (int y = y0; y < y1; ++y) {
            const size_t row = size_t(y) * s.w;
            for (int i = 0; i < s.w; ++i) acc[0] += W.a0w0[row + i], acc[1] += double(W.wx[row + i]) + W.wy[row + i];
        }
    });
    const double grad_rows = double(s.w - 1) * s.h + double(s.h - 1) * s.w;
    W.mean_a0w0 = sums[0] / double(s.n);
    W.mean_gradient = grad_rows > 0 ? sums[1] / grad_rows : 1.0;
}

/// (P)CG on A x = b (operator weights W), from and into ws.x. If `initial`
/// is given, ws.r already holds b - A x and `initial` its |r|^2 per channel.
/// final_residual = false skips updating r after the last iteration (IRLS
/// recomputes it from scratch anyway); the report then holds the residual
/// before that iteration.
CgReport run_cg(Workspace& ws, OpWeights& W, const CgOptions& opt, const Sums* initial = nullptr,
                bool final_residual = true) {
    const Shape& s = ws.s;
    const int C = s.c;
    const size_t len = s.n * C;
    float *x = ws.x.data(), *r = ws.r.data(), *q = ws.q.data();
    float* bufs[3] = {ws.z.data(), ws.p.data(), ws.p2.data()};  // z and directions rotate through these

    Sums rr = initial ? *initial : normal_residual(ws, W);
    const double r0 = total(rr);
    CgReport rep;
    rep.relative_residual = r0 > 0 ? 1.0 : 0.0;
    if (r0 == 0 || opt.max_iterations == 0) return rep;  // already the solution (or nothing to do)

    if (opt.preconditioner == Preconditioner::multigrid) ws.mg.setup(s.w, s.h, W.a0w0.data(), W.wx.data(), W.wy.data());
    if (opt.preconditioner == Preconditioner::dct) set_weight_means(s, W);
    const bool plain = opt.preconditioner == Preconditioner::none;
    // out = M^-1 r; returns <r, out> per channel.
    auto precondition = [&](float* out) -> Sums {
        Sums d{0, 0, 0, 0};
        if (opt.preconditioner == Preconditioner::multigrid) {
            ws.mg.apply(r, out, C, d.data());
            return d;
        }
        ws.dct_solver().solve(r, out, C, W.mean_a0w0, W.mean_gradient);
        return sum_rows(s.h, [&](int y0, int y1, Sums& acc) {
            for (int ch = 0; ch < C; ++ch) {
                const size_t o0 = ch * s.n + size_t(y0) * s.w, o1 = ch * s.n + size_t(y1) * s.w;
                acc[ch] += detail::dot(r + o0, out + o0, o1 - o0);
            }
        });
    };
    auto other = [&](const float* a, const float* b) {
        for (float* buf : bufs)
            if (buf != a && buf != b) return buf;
        return bufs[0];  // unreachable: three buffers, two excluded
    };
    // The first direction is z itself (preconditioned) or a copy of r (plain
    // CG updates r in place). Later directions p = z + beta p are formed in
    // the same pass as A p (see update_and_apply), which needs z, the old p
    // and the new p in three different buffers.
    Sums rz;
    const float* dir;
    if (plain) {
        rz = rr;
        std::copy(r, r + len, bufs[1]);
        dir = bufs[1];
    } else {
        rz = precondition(bufs[0]);
        dir = bufs[0];
    }
    Sums pq = apply_operator(s, W, dir, q);

    for (int it = 1; it <= opt.max_iterations; ++it) {
        float step[4] = {0, 0, 0, 0};
        for (int ch = 0; ch < C; ++ch) step[ch] = pq[ch] > 0 ? float(rz[ch] / pq[ch]) : 0.f;
        const bool last = it == opt.max_iterations && !final_residual;  // no further use for r or |r|
        rr = sum_rows(s.h, [&](int y0, int y1, Sums& acc) {
            for (int ch = 0; ch < C; ++ch) {
                const size_t o0 = ch * s.n + size_t(y0) * s.w, o1 = ch * s.n + size_t(y1) * s.w;
                const float a = step[ch];
                if (last) {
                    for (size_t i = o0; i < o1; ++i) x[i] += a * dir[i];
                    continue;
                }
                for (size_t i = o0; i < o1; ++i) {
                    x[i] += a * dir[i];
                    r[i] -= a * q[i];
                }
                acc[ch] += detail::dot(r + o0, r + o0, o1 - o0);
            }
        });
        rep.iterations = it;
        if (last) break;
        rep.relative_residual = std::sqrt(total(rr) / r0);
        if (it == opt.max_iterations || rep.relative_residual <= opt.tolerance) break;
        const float* znew = r;
        Sums rz_new = rr;
        if (!plain) {
            float* target = other(dir, nullptr);
            rz_new = precondition(target);
            znew = target;
        }
        float beta[4] = {0, 0, 0, 0};
        for (int ch = 0; ch < C; ++ch) beta[ch] = rz[ch] > 0 ? float(rz_new[ch] / rz[ch]) : 0.f;
        rz = rz_new;
        float* pnew = other(dir, znew);
        pq = update_and_apply(s, W, znew, dir, beta, pnew, q);
        dir = pnew;
    }
    return rep;
}

/// Converts user weights to operator weights (alpha^2 folded in, dropped rows zeroed).
void set_row_weights(const Shape& s, const RowWeights& rw, double alpha, OpWeights& W) {
    if (rw.primal.size() != s.n || rw.dx.size() != s.n || rw.dy.size() != s.n)
        throw ParameterError("poisson_weighted: every weight array must hold width * height values");
    W.a0w0.resize(s.n), W.wx = rw.dx, W.wy = rw.dy;
    double s0 = 0, sg = 0, ng = 0;
    for (size_t k = 0; k < s.n; ++k) {
        const int x = int(k % s.w), y = int(k / s.w);
        for (float v : {rw.primal[k], rw.dx[k], rw.dy[k]})
            if (!(v >= 0) || !std::isfinite(v))
                throw ParameterError("poisson_weighted: weights must be finite and non-negative (pixel (" +
                                     std::to_string(x) + ", " + std::to_string(y) + "))");
        W.a0w0[k] = float(alpha * alpha * rw.primal[k]);
        s0 += W.a0w0[k];
        if (x == s.w - 1) W.wx[k] = 0.f;
        else sg += W.wx[k], ng += 1;
        if (y == s.h - 1) W.wy[k] = 0.f;
        else sg += W.wy[k], ng += 1;
    }
    W.mean_a0w0 = s0 / double(s.n);
    W.mean_gradient = ng > 0 ? sg / ng : 1.0;
    if (!(W.mean_a0w0 > 0)) throw ParameterError("poisson_weighted: the colour weights are all zero");
}

/// The exact L2 solution into ws.x: r(x = 0) is the right-hand side.
void solve_l2_into(Workspace& ws) {
    set_unit_weights(ws.s, ws.alpha, ws.W);
    std::fill(ws.x.begin(), ws.x.end(), 0.f);
    normal_residual(ws, ws.W);
    ws.dct_solver().solve(ws.r.data(), ws.x.data(), ws.s.c, ws.alpha * ws.alpha, 1.0);
}

/// Sum over rows of |residual row| (power 1) or |residual row|^2 (power 2), interleaved x.
double energy(const PoissonProblem& prob, const float* xi, int power) {
    check_problem(prob);
    const Shape s = shape_of(prob);
    const int w = s.w, h = s.h, C = s.c;
    const double a = prob.alpha;
    const Sums e = sum_rows(h, [&](int y0, int y1, Sums& acc) {
        for (int y = y0; y < y1; ++y)
            for (int i = 0; i < w; ++i) {
                const size_t o = (size_t(y) * w + i) * C;
                double s0 = 0, sx = 0, sy = 0;
                for (int ch = 0; ch < C; ++ch) {
                    const double d0 = a * (double(xi[o + ch]) - prob.primal.data[o + ch]);
                    s0 += d0 * d0;
                    if (i < w - 1) {
                        const double dx = double(xi[o + C + ch]) - xi[o + ch] - prob.dx.data[o + ch];
                        sx += dx * dx;
                    }
                    if (y < h - 1) {
                        const double dy = double(xi[o + size_t(w) * C + ch]) - xi[o + ch] - prob.dy.data[o + ch];
                        sy += dy * dy;
                    }
                }
                acc[0] += power == 1 ? std::sqrt(s0) + std::sqrt(sx) + std::sqrt(sy) : s0 + sx + sy;
            }
    });
    return e[0];
}

}  // namespace

void check_problem(const PoissonProblem& p) {
    auto check = [&](const ImageView& v, const char* name) {
        if (!v.data) throw ParameterError(std::string("Poisson problem: no ") + name + " image");
        if (v.width < 1 || v.height < 1 || v.channels < 1 || v.channels > 4)
            throw ParameterError(std::string("Poisson problem: ") + name + " has a bad shape " +
                                 std::to_string(v.width) + "x" + std::to_string(v.height) + "x" +
                                 std::to_string(v.channels));
        if (v.width != p.primal.width || v.height != p.primal.height || v.channels != p.primal.channels)
            throw ParameterError(std::string("Poisson problem: ") + name + " is " + std::to_string(v.width) + "x" +
                                 std::to_string(v.height) + "x" + std::to_string(v.channels) + " but primal is " +
                                 std::to_string(p.primal.width) + "x" + std::to_string(p.primal.height) + "x" +
                                 std::to_string(p.primal.channels));
    };
    check(p.primal, "primal");
    check(p.dx, "dx");
    check(p.dy, "dy");
    if (!(p.alpha > 0) || !std::isfinite(p.alpha))
        throw ParameterError("Poisson problem: alpha must be finite and > 0, got " + std::to_string(p.alpha));
}

void poisson_l2(const PoissonProblem& prob, float* out) {
    check_problem(prob);
    const Shape s = shape_of(prob);
    const float a2 = float(prob.alpha * prob.alpha);
    const int w = s.w, C = s.c;
    // rhs = alpha^2 c + Dx^T gx + Dy^T gy, interleaved, straight into `out`;
    // the DCT solve then reads and writes `out` in place: one pass to build
    // the right-hand side is all this adds to the bare solve.
    const float *c = prob.primal.data, *gx = prob.dx.data, *gy = prob.dy.data;
    const size_t rowlen = size_t(w) * C;
    for_rows(s.h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const size_t o = size_t(y) * rowlen;
            const float *cr = c + o, *gxr = gx + o, *gyr = gy + o;
            float* b = out + o;
            for (size_t k = 0; k < rowlen; ++k) b[k] = a2 * cr[k];
            for (size_t k = 0; k + C < rowlen; ++k) b[k] -= gxr[k];       // -gx(x) for x < w - 1
            for (size_t k = C; k < rowlen; ++k) b[k] += gxr[k - C];       // +gx(x - 1) for x > 0
            if (y + 1 < s.h)
                for (size_t k = 0; k < rowlen; ++k) b[k] -= gyr[k];
            if (y > 0) {
                const float* gyu = gyr - rowlen;
                for (size_t k = 0; k < rowlen; ++k) b[k] += gyu[k];
            }
        }
    });
    // The solver of the last size solved on this thread is kept: a renderer
    // reconstructs frame after frame, and fresh scratch pages cost about a
    // tenth of the solve.
    thread_local std::unique_ptr<DctSolver> dct;
    if (!dct || dct->width() != s.w || dct->height() != s.h) dct = std::make_unique<DctSolver>(s.w, s.h);
    dct->solve(out, out, C, prob.alpha * prob.alpha, 1.0, /*interleaved=*/true);
}

CgReport poisson_weighted(const PoissonProblem& prob, const RowWeights* weights, const CgOptions& options, float* x) {
    check_problem(prob);
    if (options.max_iterations < 0) throw ParameterError("poisson_weighted: max_iterations must be >= 0");
    if (!(options.tolerance >= 0)) throw ParameterError("poisson_weighted: tolerance must be >= 0");
    Workspace ws(prob);
    if (weights) set_row_weights(ws.s, *weights, prob.alpha, ws.W);
    else set_unit_weights(ws.s, prob.alpha, ws.W);
    to_planar(ws.s, x, ws.x.data());
    const CgReport rep = run_cg(ws, ws.W, options);
    to_interleaved(ws.s, ws.x.data(), x);
    return rep;
}

RowWeights irls_weights(const PoissonProblem& prob, const float* x, double eps) {
    check_problem(prob);
    if (!(eps > 0)) throw ParameterError("irls_weights: eps must be > 0");
    Workspace ws(prob);
    to_planar(ws.s, x, ws.x.data());
    float max_norm = 0;
    reweight_and_residual(ws, float(eps), ws.W, max_norm);
    // Normalise to mean 1 over the rows in use, as the reference does.
    const Shape& s = ws.s;
    const double rows = double(s.n) + double(s.w - 1) * s.h + double(s.h - 1) * s.w;
    const double a2 = prob.alpha * prob.alpha;
    double sum = 0;
    for (size_t k = 0; k < s.n; ++k) sum += ws.W.a0w0[k] / a2 + ws.W.wx[k] + ws.W.wy[k];
    const double coef = rows / sum;
    RowWeights rw;
    rw.primal.resize(s.n), rw.dx.resize(s.n), rw.dy.resize(s.n);
    for (size_t k = 0; k < s.n; ++k) {
        rw.primal[k] = float(coef * ws.W.a0w0[k] / a2);
        rw.dx[k] = float(coef * ws.W.wx[k]);
        rw.dy[k] = float(coef * ws.W.wy[k]);
    }
    return rw;
}

L1Report poisson_l1(const PoissonProblem& prob, const L1Options& opt, float* out) {
    check_problem(prob);
    if (opt.iterations < 1) throw ParameterError("poisson-l1: iterations must be >= 1");
    if (opt.cg_iterations < 1) throw ParameterError("poisson-l1: cg_iterations must be >= 1");
    if (!(opt.tolerance >= 0)) throw ParameterError("poisson-l1: tolerance must be >= 0");
    if (!(opt.eps_initial > 0) || !(opt.eps_factor > 0) || opt.eps_factor > 1)
        throw ParameterError("poisson-l1: need eps_initial > 0 and 0 < eps_factor <= 1");
    Workspace ws(prob);
    L1Report rep;
    CgOptions cg;
    cg.max_iterations = opt.cg_iterations;
    cg.tolerance = opt.tolerance;
    cg.preconditioner = opt.preconditioner;
    if (opt.exact_l2_start) {
        solve_l2_into(ws);
    } else {
        // The reference: start at the primal and spend the CG budget on the unweighted system.
        ws.x = ws.c;
        set_unit_weights(ws.s, prob.alpha, ws.W);
        rep.cg_iterations += run_cg(ws, ws.W, cg).iterations;
    }
    rep.irls_iterations = 1;
    double eps = opt.eps_initial;
    float max_norm = 0;  // largest row residual of the previous iterate (for the eps floor)
    for (int k = 1; k < opt.iterations; ++k, eps *= opt.eps_factor) {
        const float e = std::max(float(eps), kEpsFloor * max_norm);
        const Sums rr = reweight_and_residual(ws, e, ws.W, max_norm);
        rep.cg_iterations += run_cg(ws, ws.W, cg, &rr, false).iterations;
        rep.irls_iterations = k + 1;
    }
    to_interleaved(ws.s, ws.x.data(), out);
    rep.energy = poisson_energy_l1(prob, out);
    return rep;
}

double poisson_energy_l1(const PoissonProblem& prob, const float* x) { return energy(prob, x, 1); }

double poisson_energy_l2(const PoissonProblem& prob, const float* x) { return energy(prob, x, 2); }

}  // namespace gdr
