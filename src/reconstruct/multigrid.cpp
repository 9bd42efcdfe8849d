// Aggregation multigrid V-cycle for the weighted screened Poisson operator
// (see multigrid.h for why it exists and why coarse operators stay 5-point).
//
// Loops are written so the compiler vectorises them: a red-black half sweep
// touches every other pixel of a row and reads only the other colour, so the
// stride-2 loop has no dependences.

#include "multigrid.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace gdr::detail {
namespace {

constexpr int kRows = 8;          // rows per parallel task
constexpr size_t kCoarsest = 64;  // pixels at which coarsening stops

template <class F>
void for_blocks(int h, F&& f) {
    const int blocks = (h + kRows - 1) / kRows;
    if (blocks == 1) return f(0, h);
    tbb::parallel_for(0, blocks, [&](int b) { f(b * kRows, std::min(h, (b + 1) * kRows)); });
}


/// Sum over neighbours j of w_ij x_j at pixel i of one row (Up / Down: the
/// row above / below exists; eyu / eyd: the vertical edge weights).
template <bool Up, bool Down>
inline float neighbours(int i, int w, const float* x, const float* ex, const float* xu, const float* eyu,
                        const float* xd, const float* eyd) {
    float s = 0.f;
    if (i > 0) s += ex[i - 1] * x[i - 1];
    if (i < w - 1) s += ex[i] * x[i + 1];
    if constexpr (Up) s += eyu[i] * xu[i];
    if constexpr (Down) s += eyd[i] * xd[i];
    return s;
}

/// One Gauss-Seidel half sweep over the pixels i = start, start + 2, ... of
/// a row: x_i = (b_i + sum_j w_ij x_j) / diag_i. Only the other colour is
/// read, so the stride-2 interior loop has no dependences and vectorises.
template <bool Up, bool Down>
void gs_row(int w, int start, const float* __restrict b, float* __restrict x, const float* __restrict ex,
            const float* __restrict xu, const float* __restrict eyu, const float* __restrict xd,
            const float* __restrict eyd, const float* __restrict inv) {
    int i = start;
    if (i == 0) x[0] = (b[0] + neighbours<Up, Down>(0, w, x, ex, xu, eyu, xd, eyd)) * inv[0], i = 2;
    for (; i < w - 1; i += 2) {
        float v = b[i] + ex[i - 1] * x[i - 1] + ex[i] * x[i + 1];
        if constexpr (Up) v += eyu[i] * xu[i];
        if constexpr (Down) v += eyd[i] * xd[i];
        x[i] = v * inv[i];
    }
    if (i == w - 1) x[i] = (b[i] + neighbours<Up, Down>(i, w, x, ex, xu, eyu, xd, eyd)) * inv[i];
}

/// Residual b - A x at the pixels i = start, start + 2, ... of a row, added to
/// out[i / 2] (the coarse aggregate of pixel i).
template <bool Up, bool Down>
void residual_row(int w, int start, const float* __restrict b, const float* __restrict x, const float* __restrict ex,
                  const float* __restrict xu, const float* __restrict eyu, const float* __restrict xd,
                  const float* __restrict eyd, const float* __restrict diag, float* __restrict out) {
    int i = start;
    if (i == 0) out[0] += b[0] + neighbours<Up, Down>(0, w, x, ex, xu, eyu, xd, eyd) - diag[0] * x[0], i = 2;
    for (; i < w - 1; i += 2) {
        float v = b[i] + ex[i - 1] * x[i - 1] + ex[i] * x[i + 1] - diag[i] * x[i];
        if constexpr (Up) v += eyu[i] * xu[i];
        if constexpr (Down) v += eyd[i] * xd[i];
        out[i / 2] += v;
    }
    if (i == w - 1) out[i / 2] += b[i] + neighbours<Up, Down>(i, w, x, ex, xu, eyu, xd, eyd) - diag[i] * x[i];
}

/// The first (pre-smoothing) sweep from x = 0, both colours in one pass: red
/// pixels get x = b / diag; black pixels the Gauss-Seidel update from those
/// red values, which are computed on the fly (b * inv of the neighbour), so
/// the pass reads only b and the operator and any row can go in any order.
template <bool Up, bool Down>
void pre_smooth_row(int w, int red, const float* __restrict b, const float* __restrict bu,
                    const float* __restrict bd, const float* __restrict inv, const float* __restrict invu,
                    const float* __restrict invd, const float* __restrict ex, const float* __restrict eyu,
                    const float* __restrict eyd, float* __restrict x) {
    for (int i = red; i < w; i += 2) x[i] = b[i] * inv[i];
    auto edge = [&](int i) {
        float v = b[i];
        if (i > 0) v += ex[i - 1] * b[i - 1] * inv[i - 1];
        if (i < w - 1) v += ex[i] * b[i + 1] * inv[i + 1];
        if constexpr (Up) v += eyu[i] * bu[i] * invu[i];
        if constexpr (Down) v += eyd[i] * bd[i] * invd[i];
        x[i] = v * inv[i];
    };
    int i = 1 - red;
    if (i == 0) edge(0), i = 2;
    for (; i < w - 1; i += 2) {
        float v = b[i] + ex[i - 1] * b[i - 1] * inv[i - 1] + ex[i] * b[i + 1] * inv[i + 1];
        if constexpr (Up) v += eyu[i] * bu[i] * invu[i];
        if constexpr (Down) v += eyd[i] * bd[i] * invd[i];
        x[i] = v * inv[i];
    }
    if (i == w - 1) edge(i);
}

/// The black half sweep after the coarse correction, with the piecewise-
/// constant prolongation folded in: neighbour values are src + cx(aggregate),
/// src being the pre-smoothing values. Only black pixels of dst are written
/// (a Gauss-Seidel update ignores the old value), so the corrected red values
/// are never stored: the following red half sweep replaces them anyway.
/// cx / cxu / cxd: coarse rows of this row and of the rows above / below.
template <bool Up, bool Down>
void post_black_row(int w, int black, const float* __restrict b, const float* __restrict src,
                    const float* __restrict srcu, const float* __restrict srcd, const float* __restrict cx,
                    const float* __restrict cxu, const float* __restrict cxd, const float* __restrict ex,
                    const float* __restrict eyu, const float* __restrict eyd, const float* __restrict inv,
                    float* __restrict dst) {
    auto edge = [&](int i) {
        float v = b[i];
        if (i > 0) v += ex[i - 1] * (src[i - 1] + cx[(i - 1) / 2]);
        if (i < w - 1) v += ex[i] * (src[i + 1] + cx[(i + 1) / 2]);
        if constexpr (Up) v += eyu[i] * (srcu[i] + cxu[i / 2]);
        if constexpr (Down) v += eyd[i] * (srcd[i] + cxd[i / 2]);
        dst[i] = v * inv[i];
    };
    int i = black;
    if (i == 0) edge(0), i = 2;
    for (; i < w - 1; i += 2) {
        float v = b[i] + ex[i - 1] * (src[i - 1] + cx[(i - 1) / 2]) + ex[i] * (src[i + 1] + cx[(i + 1) / 2]);
        if constexpr (Up) v += eyu[i] * (srcu[i] + cxu[i / 2]);
        if constexpr (Down) v += eyd[i] * (srcd[i] + cxd[i / 2]);
        dst[i] = v * inv[i];
    }
    if (i == w - 1) edge(i);
}

/// Calls f.template operator()<Up, Down>() for the row's neighbour situation.
template <class F>
void dispatch_rows(bool up, bool down, F&& f) {
    if (up && down) f.template operator()<true, true>();
    else if (up) f.template operator()<true, false>();
    else if (down) f.template operator()<false, true>();
    else f.template operator()<false, false>();
}

}  // namespace

void WeightedMultigrid::setup(int w, int h, const float* d, const float* ex, const float* ey) {
    // Level sizes first, so the level storage of an earlier setup is reused
    // (IRLS calls this once per step; reallocating costs page faults).
    size_t count = 1;
    for (int lw = w, lh = h; size_t(lw) * lh > kCoarsest; lw = (lw + 1) / 2, lh = (lh + 1) / 2) ++count;
    if (levels_.size() != count) levels_.resize(count);
    Level& fine = levels_[0];
    fine.w = w, fine.h = h, fine.d = d, fine.ex = ex, fine.ey = ey;
    for (count = 1; count < levels_.size(); ++count) {
        Level& f = levels_[count - 1];
        Level& c = levels_[count];
        c.w = (f.w + 1) / 2, c.h = (f.h + 1) / 2;
        const size_t cn = size_t(c.w) * c.h;
        c.d_own.resize(cn), c.ex_own.resize(cn), c.ey_own.resize(cn);
        const int pairs = f.w / 2;  // aggregates with two fine columns
        for_blocks(c.h, [&](int J0, int J1) {
            for (int J = J0; J < J1; ++J) {
                const int y = 2 * J;
                const bool two = y + 1 < f.h;  // the aggregate has a second fine row
                const float *d0 = f.d + size_t(y) * f.w, *ex0 = f.ex + size_t(y) * f.w;
                const float *d1 = two ? d0 + f.w : d0, *ex1 = two ? ex0 + f.w : ex0;
                const float* ey1 = f.ey + size_t(two ? y + 1 : y) * f.w;  // edges leaving the aggregate downwards
                const float rows = two ? 1.f : 0.f;
                float *cd = c.d_own.data() + size_t(J) * c.w, *cex = c.ex_own.data() + size_t(J) * c.w;
                float* cey = c.ey_own.data() + size_t(J) * c.w;
                for (int I = 0; I < pairs; ++I) {
                    cd[I] = d0[2 * I] + d0[2 * I + 1] + rows * (d1[2 * I] + d1[2 * I + 1]);
                    cex[I] = ex0[2 * I + 1] + rows * ex1[2 * I + 1];  // edges leaving it to the right
                    cey[I] = two ? ey1[2 * I] + ey1[2 * I + 1] : 0.f;
                }
                if (f.w % 2) {  // last aggregate: one fine column, no edge to the right
                    const int x = f.w - 1;
                    cd[pairs] = d0[x] + rows * d1[x];
                    cex[pairs] = 0.f;
                    cey[pairs] = two ? ey1[x] : 0.f;
                }
            }
        });
        c.d = c.d_own.data(), c.ex = c.ex_own.data(), c.ey = c.ey_own.data();
    }
    for (auto& L : levels_) {
        const size_t ln = size_t(L.w) * L.h;
        L.diag.resize(ln), L.inv_diag.resize(ln);
        const int lw = L.w;
        for_blocks(L.h, [&](int y0, int y1) {
            for (int y = y0; y < y1; ++y) {
                const size_t row = size_t(y) * lw;
                const float *d = L.d + row, *ex = L.ex + row, *ey = L.ey + row;
                float *dg = L.diag.data() + row, *inv = L.inv_diag.data() + row;
                for (int i = 0; i < lw; ++i) dg[i] = d[i] + ex[i] + ey[i];
                for (int i = 1; i < lw; ++i) dg[i] += ex[i - 1];
                if (y > 0)
                    for (int i = 0; i < lw; ++i) dg[i] += ey[i - lw];
                for (int i = 0; i < lw; ++i) inv[i] = dg[i] > 0.f ? 1.f / dg[i] : 0.f;
            }
        });
    }
    // Dense Cholesky factor of the coarsest operator.
    const Level& C = levels_.back();
    const int cn = C.w * C.h;
    chol_.assign(size_t(cn) * cn, 0.0);
    for (int i = 0; i < cn; ++i) {
        chol_[size_t(i) * cn + i] = C.diag[i];
        if ((i % C.w) + 1 < C.w) chol_[size_t(i + 1) * cn + i] = chol_[size_t(i) * cn + i + 1] = -double(C.ex[i]);
        if (i + C.w < cn) chol_[size_t(i + C.w) * cn + i] = chol_[size_t(i) * cn + i + C.w] = -double(C.ey[i]);
    }
    for (int j = 0; j < cn; ++j) {
        const double ajj = chol_[size_t(j) * cn + j];
        double s = ajj;
        for (int k = 0; k < j; ++k) s -= chol_[size_t(j) * cn + k] * chol_[size_t(j) * cn + k];
        // Late IRLS steps make some edges 1/eps ~ 1e12 times stronger than the
        // rest; the pivot then cancels to rounding noise (or below zero). A
        // relative floor keeps the factor finite and positive: it is the exact
        // factor of a slightly perturbed SPD matrix, which a preconditioner may be.
        chol_[size_t(j) * cn + j] = std::sqrt(std::max(s, 1e-10 * ajj + 1e-300));
        for (int i = j + 1; i < cn; ++i) {
            double t = chol_[size_t(i) * cn + j];
            for (int k = 0; k < j; ++k) t -= chol_[size_t(i) * cn + k] * chol_[size_t(j) * cn + k];
            chol_[size_t(i) * cn + j] = t / chol_[size_t(j) * cn + j];
        }
    }
}

void WeightedMultigrid::coarsest_solve(Level& L, int channels) {
    const int cn = L.w * L.h;
    std::vector<double> z(cn);
    for (int ch = 0; ch < channels; ++ch) {
        const float* b = L.b + size_t(ch) * cn;
        for (int i = 0; i < cn; ++i) {
            double s = b[i];
            for (int k = 0; k < i; ++k) s -= chol_[size_t(i) * cn + k] * z[k];
            z[i] = s / chol_[size_t(i) * cn + i];
        }
        for (int i = cn - 1; i >= 0; --i) {
            double s = z[i];
            for (int k = i + 1; k < cn; ++k) s -= chol_[size_t(k) * cn + i] * z[k];
            z[i] = s / chol_[size_t(i) * cn + i];
        }
        for (int i = 0; i < cn; ++i) L.x[size_t(ch) * cn + i] = float(z[i]);
    }
}

void WeightedMultigrid::cycle(size_t l, int channels) {
    Level& L = levels_[l];
    if (l + 1 == levels_.size()) return coarsest_solve(L, channels);
    const int w = L.w, h = L.h;
    const size_t n = size_t(w) * h;

    // Colour 0 = red = pixels with x + y even. Rows that do not exist are
    // passed as the row itself (never read).
    const float* ex = L.ex;
    const float* ey = L.ey;
    const float* inv = L.inv_diag.data();

    // Pre-smoothing from x = 0 (red, then black) and the residual summed
    // straight into the coarse right-hand side, in one pass over row blocks.
    // After the black half sweep the black pixels satisfy their equations
    // exactly, so only red pixels carry residual; a red pixel's vertical
    // neighbours are black pixels of the rows above and below, which for the
    // block's first and last row belong to other blocks: they are recomputed
    // here (they depend on b only), never read from memory another task writes.
    // Blocks start at even rows (kRows is even), so each coarse row has one owner.
    Level& C = levels_[l + 1];
    const size_t cn = size_t(C.w) * C.h;
    float* cb = C.b_own.data();
    for_blocks(h, [&](int y0, int y1) {
        thread_local std::vector<float> halo;
        if (halo.size() < 2 * size_t(w)) halo.resize(2 * size_t(w));
        float* above = halo.data();  // row y0 - 1 as the pre-smoothing leaves it
        float* below = above + w;    // row y1
        auto smooth_row = [&](int y, const float* b, float* out) {
            const size_t row = size_t(y) * w, up = y > 0 ? row - w : row, down = y < h - 1 ? row + w : row;
            dispatch_rows(y > 0, y < h - 1, [&]<bool Up, bool Down>() {
                pre_smooth_row<Up, Down>(w, y & 1, b + row, b + up, b + down, inv + row, inv + up, inv + down,
                                         ex + row, ey + up, ey + row, out);
            });
        };
        for (int ch = 0; ch < channels; ++ch) {
            const float* b = L.b + ch * n;
            float* x = L.xs.data() + ch * n;
            for (int y = y0; y < y1; ++y) smooth_row(y, b, x + size_t(y) * w);
            if (y0 > 0) smooth_row(y0 - 1, b, above);
            if (y1 < h) smooth_row(y1, b, below);
            float* out0 = cb + ch * cn + size_t(y0 / 2) * C.w;
            std::fill(out0, out0 + size_t((y1 - y0 + 1) / 2) * C.w, 0.f);
            for (int y = y0; y < y1; ++y) {
                const size_t row = size_t(y) * w;
                const float* xu = y == y0 ? above : x + row - w;  // (not read when y == 0)
                const float* xd = y + 1 == y1 ? below : x + row + w;  // (not read when y == h - 1)
                const float* eyu = y > 0 ? ey + row - w : ey + row;
                float* out = cb + ch * cn + size_t(y / 2) * C.w;
                dispatch_rows(y > 0, y < h - 1, [&]<bool Up, bool Down>() {
                    residual_row<Up, Down>(w, y & 1, b + row, x + row, ex + row, xu, eyu, xd, ey + row,
                                           L.diag.data() + row, out);
                });
            }
        }
    });
    cycle(l + 1, channels);

    // Post-smoothing in reverse colour order (black, then red) keeps the
    // cycle symmetric; the prolongation is folded into the black sweep, and
    // both half sweeps are one pass: the black values read from the
    // pre-smoothing buffer (xs, not written here) and go to x, then the red
    // values read those. The black values of the rows just outside a block
    // are recomputed into a halo, never read from another task's output.
    // On the finest level the caller may want <b, x> (CG's r.z): each row is
    // final in this pass, so it is summed while in cache.
    const bool dots = l == 0 && dots_;
    if (dots) dot_parts_.assign(size_t((h + kRows - 1) / kRows) * channels, 0.0);
    for_blocks(h, [&](int y0, int y1) {
        thread_local std::vector<float> halo;
        if (halo.size() < 2 * size_t(w)) halo.resize(2 * size_t(w));
        float *above = halo.data(), *below = above + w;  // black values of rows y0 - 1 and y1
        for (int ch = 0; ch < channels; ++ch) {
            const float* b = L.b + ch * n;
            const float* xs = L.xs.data() + ch * n;
            float* x = L.x + ch * n;
            const float* cx = C.x + ch * cn;
            auto black_row = [&](int y, float* dst) {
                const size_t row = size_t(y) * w, up = y > 0 ? row - w : row, down = y < h - 1 ? row + w : row;
                const int yu = y > 0 ? y - 1 : y, yd = y < h - 1 ? y + 1 : y;
                dispatch_rows(y > 0, y < h - 1, [&]<bool Up, bool Down>() {
                    post_black_row<Up, Down>(w, 1 - (y & 1), b + row, xs + row, xs + up, xs + down,
                                             cx + size_t(y / 2) * C.w, cx + size_t(yu / 2) * C.w,
                                             cx + size_t(yd / 2) * C.w, ex + row, ey + up, ey + row, inv + row, dst);
                });
            };
            for (int y = y0; y < y1; ++y) black_row(y, x + size_t(y) * w);
            if (y0 > 0) black_row(y0 - 1, above);
            if (y1 < h) black_row(y1, below);
            for (int y = y0; y < y1; ++y) {
                const size_t row = size_t(y) * w;
                const float* xu = y == y0 ? above : x + row - w;  // (not read when y == 0)
                const float* xd = y + 1 == y1 ? below : x + row + w;  // (not read when y == h - 1)
                const float* eyu = y > 0 ? ey + row - w : ey + row;
                dispatch_rows(y > 0, y < h - 1, [&]<bool Up, bool Down>() {
                    gs_row<Up, Down>(w, y & 1, b + row, x + row, ex + row, xu, eyu, xd, ey + row, inv + row);
                });
                if (dots) dot_parts_[size_t(y0 / kRows) * channels + ch] += dot(b + row, x + row, size_t(w));
            }
        }
    });
}

void WeightedMultigrid::apply(const float* r, float* z, int channels, double* r_dot_z) {
    for (size_t l = 0; l < levels_.size(); ++l) {
        Level& L = levels_[l];
        const size_t ln = size_t(L.w) * L.h * channels;
        if (L.xs.size() < ln && l + 1 < levels_.size()) L.xs.resize(ln);
        if (l == 0) continue;
        if (L.b_own.size() < ln) L.b_own.resize(ln), L.x_own.resize(ln);
        L.b = L.b_own.data(), L.x = L.x_own.data();
    }
    levels_[0].b = r, levels_[0].x = z;
    dots_ = r_dot_z != nullptr && levels_.size() > 1;
    cycle(0, channels);
    if (!r_dot_z) return;
    const size_t n = size_t(levels_[0].w) * levels_[0].h;
    for (int ch = 0; ch < channels; ++ch) r_dot_z[ch] = 0.0;
    if (!dots_) {  // a single level: solved exactly, no sweep to piggyback on
        for (int ch = 0; ch < channels; ++ch) r_dot_z[ch] = dot(r + ch * n, z + ch * n, size_t(n));
        return;
    }
    // Block partial sums added in block order: the result does not depend on scheduling.
    for (size_t k = 0; k < dot_parts_.size(); ++k) r_dot_z[k % channels] += dot_parts_[k];
}

}  // namespace gdr::detail
