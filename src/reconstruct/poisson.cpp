// Screened Poisson solvers: exact L2 through the DCT, weighted (P)CG, and
// IRLS for L1 (see gdr/reconstruct/poisson.h and docs/algorithms.md, "Screened Poisson reconstruction").
//
// Internally images are planar (one plane per channel) so that the FFTs and
// the stencil loops run over contiguous rows. Storage is float; every sum
// over the image (dot products, energies) is accumulated in double over
// fixed row blocks and combined in block order, so results do not depend on
// thread scheduling. The normal-equation right-hand side is never formed:
// the CG residual b - A x is computed directly as P^T W (b - P x) from the
// row residuals, which is one pass instead of three.
//
// Float range. The solvers work on copies divided by a power of two, which
// is exact in IEEE arithmetic (the scaling commutes with every rounding, also
// in sqrt_nonneg below), so results on ordinary inputs are bit for bit those
// of unscaled solves. L1 divides by a robust scale of the data, so that its
// squared residuals neither overflow nor underflow whatever the radiance
// unit; L2 and weighted CG, being linear, are rescaled only when their input
// is large enough to overflow. Every result is checked for NaN / Inf before
// it is returned (check_finite_result).

#include "gdr/reconstruct/poisson.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cfloat>
#include <cstdint>
#include <cmath>
#include <string>

#include "gdr/core/cancel.h"
#include "gdr/core/error.h"
#include "gdr/detail/large_alloc.h"
#include "multigrid.h"

namespace gdr {
namespace {

using detail::Plane;

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

/// Powers of two bounding the magnitudes of a problem's values (radiance).
struct Magnitudes {
    double robust = 1.0;  // >= the 99th percentile of the nonzero |values| (colour and used gradients); 1 if none
    double max = 0.0;     // >= every |value|; +inf if one is NaN or Inf
};

/// One pass over primal, dx and dy (the used entries) building a histogram of
/// float exponents. A percentile rather than the maximum, so that a few
/// outliers (up to 1% of the values) cannot set the scale; exponent bins
/// rather than a sort, so the pass costs about one read of the data.
Magnitudes magnitudes(const PoissonProblem& p) {
    const Shape s = shape_of(p);
    const int blocks = (s.h + kBlockRows - 1) / kBlockRows;
    using Histogram = std::array<std::uint64_t, 256>;
    std::vector<Histogram> part(blocks);
    tbb::parallel_for(0, blocks, [&](int b) {
        // Four sub-histograms, so that consecutive values rarely wait for
        // each other's increment of the same bin.
        std::array<std::array<std::uint32_t, 256>, 4> sub{};
        auto add = [&](const float* v, size_t count) {
            size_t i = 0;
            for (; i + 4 <= count; i += 4)
                for (int k = 0; k < 4; ++k) ++sub[k][(std::bit_cast<std::uint32_t>(v[i + k]) >> 23) & 0xffu];
            for (; i < count; ++i) ++sub[0][(std::bit_cast<std::uint32_t>(v[i]) >> 23) & 0xffu];
        };
        for (int y = b * kBlockRows; y < std::min(s.h, (b + 1) * kBlockRows); ++y) {
            const size_t o = size_t(y) * s.w * s.c;
            add(p.primal.data + o, size_t(s.w) * s.c);
            add(p.dx.data + o, size_t(s.w - 1) * s.c);  // the unused last column is the row's tail
            if (y + 1 < s.h) add(p.dy.data + o, size_t(s.w) * s.c);
        }
        for (int i = 0; i < 256; ++i) part[b][i] = std::uint64_t(sub[0][i]) + sub[1][i] + sub[2][i] + sub[3][i];
    });
    Histogram hist{};
    for (const Histogram& h : part)
        for (int i = 0; i < 256; ++i) hist[i] += h[i];
    // Bin b (1..254) holds |v| in [2^(b-127), 2^(b-126)); bin 0 zeros and
    // subnormals (no scale information), bin 255 NaN and Inf.
    Magnitudes m;
    std::uint64_t nonzero = 0;
    for (int b = 1; b < 255; ++b) nonzero += hist[b];
    if (hist[255] > 0) m.max = INFINITY;
    else
        for (int b = 254; b >= 1; --b)
            if (hist[b] > 0) {
                m.max = std::ldexp(1.0, b - 126);
                break;
            }
    const std::uint64_t allowed = nonzero / 100;  // values allowed above the robust scale
    std::uint64_t above = 0;
    for (int b = 254; b >= 1; --b) {
        if (above + hist[b] > allowed) {
            m.robust = std::ldexp(1.0, b - 126);
            break;
        }
        above += hist[b];
    }
    return m;
}

/// Planar copy of an interleaved image times inv_scale (a power of two). If
/// `limit` is finite, pixels whose largest scaled channel exceeds it are
/// shortened to it, all channels by one factor so the vector keeps its
/// direction; the arithmetic is in double, so no input can overflow here.
void to_planar(const Shape& s, const float* in, float* out, double inv_scale = 1.0, double limit = INFINITY) {
    const bool bounded = std::isfinite(limit);
    for_rows(s.h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            if (bounded) {
                const float* row = in + size_t(y) * s.w * s.c;
                for (int x = 0; x < s.w; ++x) {
                    double m = 0;
                    for (int c = 0; c < s.c; ++c) m = std::max(m, std::abs(double(row[size_t(x) * s.c + c]) * inv_scale));
                    const double f = m > limit ? limit / m * inv_scale : inv_scale;
                    for (int c = 0; c < s.c; ++c) out[c * s.n + size_t(y) * s.w + x] = float(double(row[size_t(x) * s.c + c]) * f);
                }
                continue;
            }
            const float k = float(inv_scale);
            for (int c = 0; c < s.c; ++c) {
                float* o = out + c * s.n + size_t(y) * s.w;
                const float* i = in + size_t(y) * s.w * s.c + c;
                if (k == 1.f) for (int x = 0; x < s.w; ++x) o[x] = i[size_t(x) * s.c];
                else for (int x = 0; x < s.w; ++x) o[x] = i[size_t(x) * s.c] * k;
            }
        }
    });
}

/// 1 if v is NaN or Inf (exponent bits all ones), as an integer so that
/// loops OR-ing it vectorise.
inline std::uint32_t not_finite(float v) { return (std::bit_cast<std::uint32_t>(v) & 0x7f800000u) == 0x7f800000u; }

/// Interleaved copy of a planar image times `scale` (a power of two; in
/// double, since the scale itself may lie outside the float range). Returns
/// whether every value written is finite (tested while writing).
bool to_interleaved(const Shape& s, const float* in, float* out, double scale = 1.0) {
    const int blocks = (s.h + kBlockRows - 1) / kBlockRows;
    std::vector<char> bad(blocks, 0);
    for_rows(s.h, [&](int y0, int y1) {
        std::uint32_t any = 0;
        for (int y = y0; y < y1; ++y)
            for (int c = 0; c < s.c; ++c) {
                const float* i = in + c * s.n + size_t(y) * s.w;
                float* o = out + size_t(y) * s.w * s.c + c;
                if (scale == 1.0)
                    for (int x = 0; x < s.w; ++x) o[size_t(x) * s.c] = i[x], any |= not_finite(i[x]);
                else
                    for (int x = 0; x < s.w; ++x) {
                        const float v = float(double(i[x]) * scale);
                        o[size_t(x) * s.c] = v, any |= not_finite(v);
                    }
            }
        bad[y0 / kBlockRows] = any != 0;
    });
    return std::find(bad.begin(), bad.end(), 1) == bad.end();
}

/// True if no value of v[0..n) is NaN or Inf. Tests the exponent bits with an
/// integer OR, which vectorises (an early-exit loop would not).
bool all_finite(const float* v, size_t n) {
    const size_t chunk = size_t(1) << 16;
    const size_t chunks = (n + chunk - 1) / chunk;
    std::vector<char> bad(chunks, 0);
    tbb::parallel_for(size_t(0), chunks, [&](size_t k) {
        std::uint32_t any = 0;
        for (size_t i = k * chunk; i < std::min(n, (k + 1) * chunk); ++i) any |= not_finite(v[i]);
        bad[k] = any != 0;
    });
    return std::find(bad.begin(), bad.end(), 1) == bad.end();
}

/// Operator weights, per pixel and shared by the channels: a0w0 = alpha^2 *
/// colour weight; wx / wy are zero on the dropped rows, so stencils need no
/// special case for them. Their overall scale is arbitrary (it cancels).
struct OpWeights {
    Plane a0w0, wx, wy;
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
    double scale;  // the problem's values are `scale` times those of the copies c, gx, gy (and x)
    Plane c, gx, gy, x, r, z, p, p2, q;
    OpWeights W;
    std::unique_ptr<DctSolver> dct;
    detail::WeightedMultigrid mg;

    /// Copies divided by `scale` (a power of two); pixels whose largest
    /// channel then exceeds `limit` shortened to it (see to_planar).
    explicit Workspace(const PoissonProblem& prob, double scale = 1.0, double limit = INFINITY)
        : s(shape_of(prob)), alpha(prob.alpha), scale(scale) {
        const size_t len = s.n * s.c;
        c.resize(len), gx.resize(len), gy.resize(len), x.resize(len);
        r.resize(len), z.resize(len), p.resize(len), p2.resize(len), q.resize(len);
        to_planar(s, prob.primal.data, c.data(), 1.0 / scale, limit);
        to_planar(s, prob.dx.data, gx.data(), 1.0 / scale, limit);
        to_planar(s, prob.dy.data, gy.data(), 1.0 / scale, limit);
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

// The L1 solve works in units of the robust scale (Magnitudes::robust), in
// which the following bounds keep every IRLS quantity a normal float. Data
// are at most kDataLimit; an iterate follows data along paths through the
// image, so a value differs from the colours by at most kDataLimit per pixel
// of path, below 2^56 for images up to 65536 pixels across, and squared row
// norms stay below 2^114. eps is at least kEpsMin, so weights
// eps / (|e| + eps) lie in [2^-96, 1].

/// Largest magnitude (largest channel of a pixel's colour or gradient
/// vector) the L1 solve sees, in robust-scale units (2^40, about 1e12).
/// Longer vectors are shortened to it, keeping their direction. For L1 this
/// leaves the minimiser unchanged as long as the solution's own difference
/// (or value) in that row stays far below the bound: the energy depends on
/// such a row only through the direction of its residual, which shortening
/// does not change, up to a relative 1e-12 for the solution's own
/// difference. (A pixel with fewer constraints than alpha plus one other
/// gradient, as in images one pixel wide, may follow an outlier; then the
/// L1 answer itself is dominated by it.)
constexpr double kDataLimit = 0x1p40;

/// Smallest eps (robust-scale units): the reference schedule reaches it
/// only on images brighter than about 2e5.
constexpr float kEpsMin = 0x1p-40f;

/// Largest row residual (robust-scale units) that the eps floor kEpsFloor
/// follows. Beyond it a residual is an outlier, whose weight is meant to
/// vanish (losing it in float sums is harmless, its pull w e ~ eps is
/// computed separately); following it would raise eps for every row, and
/// each IRLS step lets an outlier move the image by about eps / 2 (measured:
/// a gradient of 1e10 on an image of 0.4 left an error of 6.6 that way).
/// Ordinary inputs (residuals below 1024 times the scale) are unaffected.
constexpr float kResidualCap = 0x1p10f;

/// The starting point of IRLS ignores how far a gradient row exceeds
/// kStartRelative times the sum of its two pixels' colours (largest
/// channel) plus the robust scale. A forward difference of non-negative
/// radiance is at most the sum of the two radiances; on the reference's
/// cbox buffers (16 spp) no row exceeds 4 times that sum, so 16 leaves such
/// noise alone with a margin of 4. The bound matters because IRLS with the
/// reference's eps schedule (absolute, 0.05 halved 19 times) recovers from a
/// start displaced by an outlier only when the displacement is modest:
/// measured on a 16x16 image of 0.4 with one outlier gradient, from the
/// exact L2 start, an outlier of 500 is removed to 1e-6 but one of 2000
/// leaves 0.16 and one of 1e4 leaves 2; from a start shortened to this
/// bound every outlier size is removed to ~1e-7. Only the start uses the
/// shortened rows; the IRLS steps see the data as given.
constexpr float kStartRelative = 16.f;

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

/// Shortens, in place, the gradient rows (channel vectors of gx and gy)
/// whose largest channel exceeds kStartRelative (|c_p| + |c_q|) + 1 (|.|:
/// largest channel; 1 = the robust scale in the workspace's units) to that
/// bound, if `apply`; returns whether any row exceeds it.
bool bound_start_gradients(Workspace& ws, bool apply) {
    const Shape& s = ws.s;
    const int w = s.w, h = s.h, C = s.c;
    const int blocks = (h + kBlockRows - 1) / kBlockRows;
    std::vector<char> found(blocks, 0);
    // Per image row, in scratch rows: the largest colour channel of this row
    // and the next, the largest gradient channel, and the bound. Branch-free
    // loops over contiguous planar rows, so the common case (nothing to
    // shorten) costs about one vectorised read of c, gx and gy.
    for_rows(h, [&](int y0, int y1) {
        thread_local std::vector<float> buf;
        if (buf.size() < 4 * size_t(w)) buf.resize(4 * size_t(w));
        float *cn = buf.data(), *cd = cn + w, *gm = cd + w, *bound = gm + w;
        auto colour = [&](int y, float* out) {
            std::fill(out, out + w, 0.f);
            for (int ch = 0; ch < C; ++ch) {
                const float* c = ws.c.data() + ch * s.n + size_t(y) * w;
                for (int i = 0; i < w; ++i) out[i] = std::max(out[i], std::abs(c[i]));
            }
        };
        // Largest channel of g's row y over pixels [0, count) against `bound`;
        // shortens the rows beyond it if `apply`. Returns whether any is.
        auto check = [&](Plane& g, int y, int count) {
            std::fill(gm, gm + count, 0.f);
            for (int ch = 0; ch < C; ++ch) {
                const float* gr = g.data() + ch * s.n + size_t(y) * w;
                for (int i = 0; i < count; ++i) gm[i] = std::max(gm[i], std::abs(gr[i]));
            }
            std::uint32_t over = 0;
            for (int i = 0; i < count; ++i) over |= gm[i] > bound[i];
            if (over && apply)
                for (int ch = 0; ch < C; ++ch) {
                    float* gr = g.data() + ch * s.n + size_t(y) * w;
                    for (int i = 0; i < count; ++i)
                        if (gm[i] > bound[i]) gr[i] *= bound[i] / gm[i];
                }
            return over != 0;
        };
        bool any = false;
        colour(y0, cn);
        for (int y = y0; y < y1; ++y) {
            for (int i = 0; i + 1 < w; ++i) bound[i] = kStartRelative * (cn[i] + cn[i + 1]) + 1.f;
            any |= check(ws.gx, y, w - 1);
            if (y + 1 < h) {
                colour(y + 1, cd);
                for (int i = 0; i < w; ++i) bound[i] = kStartRelative * (cn[i] + cd[i]) + 1.f;
                any |= check(ws.gy, y, w);
                std::swap(cn, cd);
            }
        }
        found[y0 / kBlockRows] = any;
    });
    return std::find(found.begin(), found.end(), 1) != found.end();
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
    if (!std::isfinite(r0)) {  // overflowed residual: no step can be trusted; leave x as it is
        rep.breakdown = true;
        return rep;
    }

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

    // A channel stops for good once its curvature <p, A p> is not positive
    // or its step is not finite: in exact arithmetic that happens only when
    // p = 0 (the channel is solved); in float it means rounding or overflow,
    // and a step along p would no longer decrease the energy.
    bool active[4] = {true, true, true, true};
    for (int it = 1; it <= opt.max_iterations; ++it) {
        check_cancelled("reconstruction");  // a caller waiting on Ctrl-C (the Python module)
        float step[4] = {0, 0, 0, 0};
        for (int ch = 0; ch < C; ++ch) {
            const float a = float(rz[ch] / pq[ch]);
            if (active[ch] && (!(pq[ch] > 0) || !std::isfinite(a))) {
                active[ch] = false;
                if (!(pq[ch] == 0 && rz[ch] == 0)) rep.breakdown = true;  // p = 0 with r = 0: merely solved
            }
            step[ch] = active[ch] ? a : 0.f;
        }
        if (std::none_of(active, active + C, [](bool b) { return b; })) break;
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
        const double rel = std::sqrt(total(rr) / r0);
        if (!std::isfinite(rel)) {  // A p overflowed: r can no longer guide a step
            rep.breakdown = true;
            break;
        }
        rep.relative_residual = rel;
        if (it == opt.max_iterations || rep.relative_residual <= opt.tolerance) break;
        const float* znew = r;
        Sums rz_new = rr;
        if (!plain) {
            float* target = other(dir, nullptr);
            rz_new = precondition(target);
            znew = target;
        }
        float beta[4] = {0, 0, 0, 0};
        for (int ch = 0; ch < C; ++ch) {
            beta[ch] = rz[ch] > 0 ? float(rz_new[ch] / rz[ch]) : 0.f;
            if (!active[ch] || !std::isfinite(beta[ch])) beta[ch] = 0.f;  // restart along z
        }
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
    W.a0w0.resize(s.n), W.wx.assign(rw.dx.begin(), rw.dx.end()), W.wy.assign(rw.dy.begin(), rw.dy.end());
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

/// Division by which the linear solvers (L2, weighted CG) keep every
/// intermediate sum in float range: 1 unless some value exceeds 2^40.
double linear_scale(const Magnitudes& m) { return m.max > 0x1p40 ? m.max * 0x1p-40 : 1.0; }

ImageView view_of(const PoissonProblem& p, const float* data) {
    return ImageView{data, p.primal.width, p.primal.height, p.primal.channels};
}

}  // namespace

void check_finite_result(const ImageView& image, const std::string& what) {
    const size_t count = size_t(image.width) * image.height * image.channels;
    if (all_finite(image.data, count)) return;
    for (size_t i = 0; i < count; ++i)
        if (!std::isfinite(image.data[i])) {
            const size_t px = i / image.channels;
            throw RuntimeFailure(what + ": the result is not finite (" + std::to_string(image.data[i]) + ") at pixel (" +
                                 std::to_string(px % image.width) + ", " + std::to_string(px / image.width) +
                                 ") channel " + std::to_string(i % image.channels));
        }
}

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
    bool finite = false;
    dct->solve(out, out, C, prob.alpha * prob.alpha, 1.0, /*interleaved=*/true, &finite);
    // Overflow anywhere (right-hand side, FFT sums) turns the whole result
    // non-finite, so checking the output (done while the solver writes it)
    // detects it; only then is the scan of the input and the scaled solve
    // paid for.
    if (finite) return;
    const Magnitudes m = magnitudes(prob);
    const double scale = linear_scale(m);
    if (std::isfinite(m.max) && scale > 1.0) {
        Workspace ws(prob, scale);
        solve_l2_into(ws);
        to_interleaved(s, ws.x.data(), out, scale);  // Inf here: the solution itself exceeds the float range
    }
    check_finite_result(view_of(prob, out), "poisson-l2");
}

CgReport poisson_weighted(const PoissonProblem& prob, const RowWeights* weights, const CgOptions& options, float* x) {
    check_problem(prob);
    if (options.max_iterations < 0) throw ParameterError("poisson_weighted: max_iterations must be >= 0");
    if (!(options.tolerance >= 0)) throw ParameterError("poisson_weighted: tolerance must be >= 0");
    Workspace ws(prob, linear_scale(magnitudes(prob)));
    if (weights) set_row_weights(ws.s, *weights, prob.alpha, ws.W);
    else set_unit_weights(ws.s, prob.alpha, ws.W);
    to_planar(ws.s, x, ws.x.data(), 1.0 / ws.scale);
    const CgReport rep = run_cg(ws, ws.W, options);
    if (!to_interleaved(ws.s, ws.x.data(), x, ws.scale)) check_finite_result(view_of(prob, x), "poisson_weighted");
    return rep;
}

RowWeights irls_weights(const PoissonProblem& prob, const float* x, double eps) {
    check_problem(prob);
    if (!(eps > 0)) throw ParameterError("irls_weights: eps must be > 0");
    // The same units as poisson_l1 (weights are invariant under the common scaling of e and eps).
    const Magnitudes m = magnitudes(prob);
    Workspace ws(prob, m.robust, m.max > kDataLimit * m.robust ? kDataLimit : INFINITY);
    to_planar(ws.s, x, ws.x.data(), 1.0 / ws.scale, kDataLimit);
    float max_norm = 0;
    reweight_and_residual(ws, std::max(float(eps / ws.scale), FLT_MIN), ws.W, max_norm);
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
    // In units of the robust scale (see kDataLimit); eps scales with the data.
    const Magnitudes m = magnitudes(prob);
    Workspace ws(prob, m.robust, m.max > kDataLimit * m.robust ? kDataLimit : INFINITY);
    L1Report rep;
    CgOptions cg;
    cg.max_iterations = opt.cg_iterations;
    cg.tolerance = opt.tolerance;
    cg.preconditioner = opt.preconditioner;
    // The start sees outlier gradients shortened (kStartRelative); ordinary
    // inputs have none, and then nothing is copied.
    Plane full_gx, full_gy;
    const bool bounded = bound_start_gradients(ws, false);
    if (bounded) {
        full_gx = ws.gx, full_gy = ws.gy;
        bound_start_gradients(ws, true);
    }
    if (opt.exact_l2_start) {
        solve_l2_into(ws);
    } else {
        // The reference: start at the primal and spend the CG budget on the unweighted system.
        ws.x = ws.c;
        set_unit_weights(ws.s, prob.alpha, ws.W);
        rep.cg_iterations += run_cg(ws, ws.W, cg).iterations;
    }
    if (bounded) ws.gx.swap(full_gx), ws.gy.swap(full_gy);
    rep.irls_iterations = 1;
    double eps = opt.eps_initial;
    float max_norm = 0;  // largest row residual of the previous iterate (for the eps floor)
    for (int k = 1; k < opt.iterations; ++k, eps *= opt.eps_factor) {
        const float e = std::max({float(eps / ws.scale), kEpsFloor * std::min(max_norm, kResidualCap), kEpsMin});
        float norm = 0;
        const Sums rr = reweight_and_residual(ws, e, ws.W, norm);
        // Cannot happen within the bounds above; if it did, the weights of
        // this step would be NaN, so the last finite iterate is kept.
        if (!std::isfinite(norm) || !std::isfinite(total(rr))) break;
        max_norm = norm;
        rep.cg_iterations += run_cg(ws, ws.W, cg, &rr, false).iterations;
        rep.irls_iterations = k + 1;
    }
    if (!to_interleaved(ws.s, ws.x.data(), out, ws.scale)) check_finite_result(view_of(prob, out), "poisson-l1");
    rep.energy = poisson_energy_l1(prob, out);
    return rep;
}

double poisson_energy_l1(const PoissonProblem& prob, const float* x) { return energy(prob, x, 1); }

double poisson_energy_l2(const PoissonProblem& prob, const float* x) { return energy(prob, x, 2); }

}  // namespace gdr
