// Variance-weighted, outlier-robust screened Poisson reconstruction (see
// gdr/reconstruct/weighted.h for the method and its sources). The solves
// themselves are poisson_l2 (starting point) and poisson_weighted (the
// multigrid-preconditioned CG of gdr/reconstruct/poisson.h); this file
// builds their weights.

#include "gdr/reconstruct/weighted.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "gdr/core/error.h"

namespace gdr {
namespace {

std::string pixel_text(size_t k, int w) {
    return "(" + std::to_string(k % size_t(w)) + ", " + std::to_string(k / size_t(w)) + ")";
}

/// Mean over the (2r+1)^2 box around each pixel of the entries with
/// valid[k] != 0 (all if valid is empty), clipped at the image border; 0
/// where a box holds no valid entry. Separable running sums in double.
std::vector<float> box_mean(const std::vector<float>& v, const std::vector<unsigned char>& valid, int w, int h, int r) {
    const size_t n = size_t(w) * h;
    std::vector<double> sv(n), sc(n);
    tbb::parallel_for(0, h, [&](int y) {
        double acc = 0, cnt = 0;
        const size_t o = size_t(y) * w;
        auto ok = [&](int x) { return valid.empty() || valid[o + x] != 0; };
        for (int x = 0; x < std::min(r, w); ++x)
            if (ok(x)) acc += v[o + x], cnt += 1;
        for (int x = 0; x < w; ++x) {
            if (x + r < w && ok(x + r)) acc += v[o + x + r], cnt += 1;
            if (x - r - 1 >= 0 && ok(x - r - 1)) acc -= v[o + x - r - 1], cnt -= 1;
            sv[o + x] = acc, sc[o + x] = cnt;
        }
    });
    std::vector<float> out(n);
    tbb::parallel_for(0, w, [&](int x) {
        double acc = 0, cnt = 0;
        for (int y = 0; y < std::min(r, h); ++y) acc += sv[size_t(y) * w + x], cnt += sc[size_t(y) * w + x];
        for (int y = 0; y < h; ++y) {
            if (y + r < h) acc += sv[size_t(y + r) * w + x], cnt += sc[size_t(y + r) * w + x];
            if (y - r - 1 >= 0) acc -= sv[size_t(y - r - 1) * w + x], cnt -= sc[size_t(y - r - 1) * w + x];
            out[size_t(y) * w + x] = cnt > 0.5 ? float(std::max(0.0, acc / cnt)) : 0.f;
        }
    });
    return out;
}

/// Median over the (2r+1)^2 box around each pixel of the entries with
/// valid[k] != 0 (all if valid is empty), clipped at the border; 0 where a
/// box holds no valid entry. Unlike the mean, one firefly's variance does
/// not raise its neighbours'.
std::vector<float> box_median(const std::vector<float>& v, const std::vector<unsigned char>& valid, int w, int h, int r) {
    std::vector<float> out(size_t(w) * h);
    tbb::parallel_for(0, h, [&](int y) {
        std::vector<float> win;
        win.reserve(size_t(2 * r + 1) * (2 * r + 1));
        for (int x = 0; x < w; ++x) {
            win.clear();
            for (int yy = std::max(0, y - r); yy <= std::min(h - 1, y + r); ++yy)
                for (int xx = std::max(0, x - r); xx <= std::min(w - 1, x + r); ++xx) {
                    const size_t k = size_t(yy) * w + xx;
                    if (valid.empty() || valid[k]) win.push_back(v[k]);
                }
            if (win.empty()) {
                out[size_t(y) * w + x] = 0.f;
                continue;
            }
            auto mid = win.begin() + win.size() / 2;
            std::nth_element(win.begin(), mid, win.end());
            out[size_t(y) * w + x] = *mid;
        }
    });
    return out;
}

/// Guarded variances of the means of every row and their inverse-variance weights.
struct Rows {
    int w = 0, h = 0, c = 0;
    std::vector<float> vp, vx, vy;           // guarded variances of the means (radiance^2); 0 on unused rows
    std::vector<float> wp, wx, wy;           // weights, 0 on unused and dropped rows (arbitrary common scale)
    std::vector<unsigned char> ux, uy;       // rows in use: not the dropped border
    std::vector<unsigned char> fx, fy;       // rows flagged as outliers (the start point replaces their gradients)
};

/// How far (in units of the local radiance and noise scale) a gradient may lie
/// from the primal's difference before it is dropped whatever its variance
/// says. The z-test needs a variance estimate, which a pixel of one sample
/// lacks and which a gradient of 1e10 with an ordinary variance does not
/// reflect; such a row would otherwise drag the whole solve (float cannot
/// even hold the image to within the noise once a value near 1e10 enters it).
constexpr double kFarFactor = 1000.0;

/// Channel-mean variance of the mean of each pixel of `var` (per-sample / spp).
std::vector<float> mean_variance(const ImageView& var, const float* spp) {
    const size_t n = size_t(var.width) * var.height;
    std::vector<float> out(n);
    tbb::parallel_for(size_t(0), n, [&](size_t k) {
        double s = 0;
        for (int ch = 0; ch < var.channels; ++ch) s += var.data[k * var.channels + ch];
        s /= var.channels;
        if (spp) s /= spp[k];
        out[k] = float(s);
    });
    return out;
}

double mean_of(const std::vector<float>& v, const std::vector<unsigned char>& use) {
    double s = 0, n = 0;
    for (size_t k = 0; k < v.size(); ++k)
        if (use.empty() || use[k]) s += v[k], n += 1;
    return n > 0 ? s / n : 0.0;
}

Rows build_rows(const VarianceProblem& P, const WeightedOptions& o, WeightedReport& rep) {
    Rows R;
    const int w = R.w = P.primal.width, h = R.h = P.primal.height, C = R.c = P.primal.channels;
    const size_t n = size_t(w) * h;
    R.ux.assign(n, 1), R.uy.assign(n, 1);
    for (int y = 0; y < h; ++y) R.ux[size_t(y) * w + w - 1] = 0;
    for (int x = 0; x < w; ++x) R.uy[size_t(h - 1) * w + x] = 0;
    std::vector<float> vp = mean_variance(P.primal_variance, P.spp), vx = mean_variance(P.dx_variance, P.spp),
                       vy = mean_variance(P.dy_variance, P.spp);
    // One sample gives no variance estimate (the layers hold 0 there). Such
    // pixels take the mean variances of the pixels that have one; if none
    // has, the weights are those of poisson-l2 with the reference's alpha
    // (colour variance 1 / 0.2^2 times the gradients'), and no row is tested.
    std::vector<unsigned char> unknown(n, 0);
    size_t n_unknown = 0;
    if (P.spp)
        for (size_t k = 0; k < n; ++k) unknown[k] = P.spp[k] < 2.f, n_unknown += unknown[k];
    if (n_unknown > 0) {
        double sp = 0, sg = 0, cp = 0, cg = 0;
        for (size_t k = 0; k < n; ++k) {
            if (unknown[k]) continue;
            sp += vp[k], cp += 1;
            if (R.ux[k]) sg += vx[k], cg += 1;
            if (R.uy[k]) sg += vy[k], cg += 1;
        }
        const float up = cp > 0 ? float(sp / cp) : 25.f, ug = cg > 0 ? float(sg / cg) : 1.f;
        for (size_t k = 0; k < n; ++k)
            if (unknown[k]) vp[k] = up, vx[k] = ug, vy[k] = ug;
    }
    // Neighbourhood guard: max(own, neighbourhood mean or median).
    if (o.variance_radius > 0) {
        const std::vector<unsigned char> all;
        const bool med = o.guard == VarianceGuard::median;
        auto nb = [&](const std::vector<float>& v, const std::vector<unsigned char>& valid) {
            return med ? box_median(v, valid, w, h, o.variance_radius) : box_mean(v, valid, w, h, o.variance_radius);
        };
        const std::vector<float> bp = nb(vp, all), bx = nb(vx, R.ux), by = nb(vy, R.uy);
        for (size_t k = 0; k < n; ++k)
            vp[k] = std::max(vp[k], bp[k]), vx[k] = std::max(vx[k], bx[k]), vy[k] = std::max(vy[k], by[k]);
    }
    // Floors: a fraction of each kind's mean variance, else of the other
    // kind's, else (a noiseless input) of the squared colour scale, so that
    // weights stay finite and all equal there.
    const double mp = mean_of(vp, {}), mg = 0.5 * (mean_of(vx, R.ux) + mean_of(vy, R.uy));
    double csq = 0;
    for (size_t i = 0; i < n * C; ++i) csq += double(P.primal.data[i]) * P.primal.data[i];
    csq /= double(n * C);
    const double fallback_floor = (mp + mg > 0) ? o.variance_floor * (mp + mg) : 1e-12 * csq + 1e-30;
    const float fp = float(mp > 0 ? o.variance_floor * mp : fallback_floor);
    const float fg = float(mg > 0 ? o.variance_floor * mg : fallback_floor);
    for (size_t k = 0; k < n; ++k) vp[k] = std::max(vp[k], fp), vx[k] = std::max(vx[k], fg), vy[k] = std::max(vy[k], fg);
    R.wp.resize(n), R.wx.assign(n, 0.f), R.wy.assign(n, 0.f);
    for (size_t k = 0; k < n; ++k) {
        R.wp[k] = float(o.primal_scale / vp[k]);
        if (R.ux[k]) R.wx[k] = 1.f / vx[k];
        if (R.uy[k]) R.wy[k] = 1.f / vy[k];
    }
    // Rows far outside what their neighbours and the primal allow are dropped in every mode.
    R.fx.assign(n, 0), R.fy.assign(n, 0);
    {
        std::vector<float> level(n);
        for (size_t k = 0; k < n; ++k) {
            double a = 0;
            for (int ch = 0; ch < C; ++ch) a += std::abs(double(P.primal.data[k * C + ch]));
            level[k] = float(a / C);
        }
        const std::vector<float> local = box_mean(level, {}, w, h, 2);
        auto far = [&](size_t k, size_t q, const float* g, float vg) {
            const double scale = double(local[k]) + local[q] + std::sqrt(double(vg) + vp[k] + vp[q]);
            for (int ch = 0; ch < C; ++ch) {
                const double pk = P.primal.data[k * C + ch], pq = P.primal.data[q * C + ch];
                const double d = std::abs(double(g[k * C + ch]) - (pq - pk));
                if (!(d <= kFarFactor * (std::abs(pk) + std::abs(pq) + scale))) return true;
            }
            return false;
        };
        for (size_t k = 0; k < n; ++k) {
            if (R.ux[k] && far(k, k + 1, P.dx.data, vx[k])) R.wx[k] = 0.f, R.fx[k] = 1, ++rep.outlier_rows;
            if (R.uy[k] && far(k, k + size_t(w), P.dy.data, vy[k])) R.wy[k] = 0.f, R.fy[k] = 1, ++rep.outlier_rows;
        }
    }
    // Outlier test of each gradient row against the primal difference it estimates.
    if (o.outliers != OutlierMode::none) {
        const double tau2 = o.tau * o.tau;
        auto test = [&](size_t k, size_t q, const float* g, float vg, float& weight) {
            double num = 0;
            for (int ch = 0; ch < C; ++ch) {
                const double d = double(g[k * C + ch]) - (double(P.primal.data[q * C + ch]) - P.primal.data[k * C + ch]);
                num += d * d;
            }
            const double z2 = num / C / (double(vg) + vp[k] + vp[q]);
            if (!(z2 > tau2)) return false;
            weight = o.outliers == OutlierMode::drop ? 0.f : float(weight * (tau2 / z2));
            return true;
        };
        for (size_t k = 0; k < n; ++k) {
            const size_t right = k + 1, down = k + size_t(w);
            if (R.ux[k] && !R.fx[k] && !unknown[k] && !unknown[right] && test(k, right, P.dx.data, vx[k], R.wx[k]))
                R.fx[k] = 1, ++rep.outlier_rows;
            if (R.uy[k] && !R.fy[k] && !unknown[k] && !unknown[down] && test(k, down, P.dy.data, vy[k], R.wy[k]))
                R.fy[k] = 1, ++rep.outlier_rows;
        }
    }
    // Tiles where the gradients are noisier than the primal's own differences keep the primal.
    std::vector<unsigned char> off(n, 0);
    if (o.tile_fallback) {
        for (int ty = 0; ty < h; ty += o.tile)
            for (int tx = 0; tx < w; tx += o.tile) {
                double g = 0, ng = 0, p = 0, np = 0;
                for (int y = ty; y < std::min(h, ty + o.tile); ++y)
                    for (int x = tx; x < std::min(w, tx + o.tile); ++x) {
                        const size_t k = size_t(y) * w + x;
                        p += vp[k], np += 1;
                        if (R.ux[k]) g += vx[k], ng += 1;
                        if (R.uy[k]) g += vy[k], ng += 1;
                    }
                if (ng > 0 && g / ng > o.kappa * 2.0 * p / np)
                    for (int y = ty; y < std::min(h, ty + o.tile); ++y)
                        for (int x = tx; x < std::min(w, tx + o.tile); ++x) off[size_t(y) * w + x] = 1;
            }
    }
    if (P.gradient_enabled)
        for (size_t k = 0; k < n; ++k) off[k] |= P.gradient_enabled[k] == 0;
    for (size_t k = 0; k < n; ++k) {
        // A row joins two pixels: it needs gradient samples at both.
        const bool offx = R.ux[k] && (off[k] || off[k + 1]);
        const bool offy = R.uy[k] && (off[k] || off[k + size_t(w)]);
        if (offx && R.wx[k] > 0) R.wx[k] = 0.f, ++rep.fallback_rows;
        if (offy && R.wy[k] > 0) R.wy[k] = 0.f, ++rep.fallback_rows;
    }
    R.vp = std::move(vp), R.vx = std::move(vx), R.vy = std::move(vy);
    return R;
}

/// Weights scaled to mean 1 over the rows in use (the scale cancels in the solve; this keeps floats in range).
RowWeights normalised(const Rows& R, const std::vector<float>& wp, const std::vector<float>& wx,
                      const std::vector<float>& wy) {
    const size_t n = wp.size();
    double s = 0, cnt = 0;
    for (size_t k = 0; k < n; ++k) {
        s += wp[k], cnt += 1;
        if (R.ux[k]) s += wx[k], cnt += 1;
        if (R.uy[k]) s += wy[k], cnt += 1;
    }
    const double f = s > 0 ? cnt / s : 1.0;
    RowWeights rw;
    rw.primal.resize(n), rw.dx.resize(n), rw.dy.resize(n);
    for (size_t k = 0; k < n; ++k)
        rw.primal[k] = float(wp[k] * f), rw.dx[k] = float(wx[k] * f), rw.dy[k] = float(wy[k] * f);
    return rw;
}

void check_view(const ImageView& v, const ImageView& like, const char* name) {
    if (!v.data) throw ParameterError(std::string("poisson-weighted: no ") + name + " layer");
    if (v.width != like.width || v.height != like.height || v.channels != like.channels)
        throw ParameterError(std::string("poisson-weighted: layer '") + name + "' is " + std::to_string(v.width) + "x" +
                             std::to_string(v.height) + "x" + std::to_string(v.channels) + " but primal is " +
                             std::to_string(like.width) + "x" + std::to_string(like.height) + "x" +
                             std::to_string(like.channels));
}

/// x += box_R(c - x) per channel (EnergyMode::lowpass). With clip > 0 each
/// pixel's difference is first bounded by clip times the standard deviation
/// of the primal's mean in its neighbourhood (the box mean of radius
/// `radius_v` of the variances, not the pixel's own: a firefly inflates its
/// own variance estimate but not its neighbours'), so that a firefly's
/// energy is not spread over the box while the systematic shortfall of a
/// robust fit, which is within the noise at every pixel, is restored.
void lowpass_tie(const VarianceProblem& P, int radius, double clip, int radius_v, float* x) {
    const int w = P.primal.width, h = P.primal.height, C = P.primal.channels;
    const size_t n = size_t(w) * h;
    std::vector<float> d(n), bound;
    const std::vector<unsigned char> all;
    if (clip > 0) {
        bound = box_mean(mean_variance(P.primal_variance, P.spp), all, w, h, std::max(1, radius_v));
        for (float& b : bound) b = float(clip * std::sqrt(double(b)));
    }
    for (int ch = 0; ch < C; ++ch) {
        for (size_t k = 0; k < n; ++k) {
            d[k] = P.primal.data[k * C + ch] - x[k * C + ch];
            if (clip > 0) d[k] = std::clamp(d[k], -bound[k], bound[k]);
        }
        // box_mean clips at 0 (it is written for variances): split the signed difference.
        std::vector<float> pos(n), neg(n);
        for (size_t k = 0; k < n; ++k) pos[k] = std::max(d[k], 0.f), neg[k] = std::max(-d[k], 0.f);
        const std::vector<float> bp = box_mean(pos, all, w, h, radius), bn = box_mean(neg, all, w, h, radius);
        for (size_t k = 0; k < n; ++k) x[k * C + ch] += bp[k] - bn[k];
    }
}

/// Each channel's image mean made equal to the primal's (EnergyMode::mean):
/// by a factor where both means are positive, else by a shift.
void mean_tie(const VarianceProblem& P, float* x) {
    const int C = P.primal.channels;
    const size_t n = size_t(P.primal.width) * P.primal.height;
    for (int ch = 0; ch < C; ++ch) {
        double mc = 0, mx = 0;
        for (size_t k = 0; k < n; ++k) mc += P.primal.data[k * C + ch], mx += x[k * C + ch];
        mc /= double(n), mx /= double(n);
        if (mc > 0 && mx > 0) {
            const float f = float(mc / mx);
            for (size_t k = 0; k < n; ++k) x[k * C + ch] *= f;
        } else {
            const float s = float(mc - mx);
            for (size_t k = 0; k < n; ++k) x[k * C + ch] += s;
        }
    }
}

}  // namespace

void check_variance_problem(const VarianceProblem& P, const WeightedOptions& o) {
    check_problem(PoissonProblem{P.primal, P.dx, P.dy, 1.0});
    check_view(P.primal_variance, P.primal, "primal_variance");
    check_view(P.dx_variance, P.primal, "dx_variance");
    check_view(P.dy_variance, P.primal, "dy_variance");
    auto positive = [](double v) { return v > 0 && std::isfinite(v); };
    if (!positive(o.primal_scale)) throw ParameterError("poisson-weighted: primal_scale must be finite and > 0");
    if (!positive(o.variance_floor)) throw ParameterError("poisson-weighted: variance_floor must be finite and > 0");
    if (!positive(o.tau)) throw ParameterError("poisson-weighted: tau must be finite and > 0");
    if (!positive(o.kappa)) throw ParameterError("poisson-weighted: kappa must be finite and > 0");
    if (!(o.energy_clip >= 0) || !std::isfinite(o.energy_clip))
        throw ParameterError("poisson-weighted: energy_clip must be finite and >= 0");
    if (!positive(o.eps)) throw ParameterError("poisson-weighted: eps must be finite and > 0");
    if (!(o.tolerance >= 0) || !std::isfinite(o.tolerance))
        throw ParameterError("poisson-weighted: tolerance must be finite and >= 0");
    if (o.variance_radius < 0 || o.variance_radius > 64)
        throw ParameterError("poisson-weighted: variance_radius must be in 0..64");
    if (o.tile < 1) throw ParameterError("poisson-weighted: tile must be >= 1");
    if (o.energy_radius < 1) throw ParameterError("poisson-weighted: energy_radius must be >= 1");
    if (o.irls_iterations < 0) throw ParameterError("poisson-weighted: irls_iterations must be >= 0");
    if (o.cg_iterations < 2) throw ParameterError("poisson-weighted: cg_iterations must be >= 2");
    const int w = P.primal.width, C = P.primal.channels;
    const size_t n = size_t(w) * P.primal.height;
    const std::pair<const ImageView*, const char*> vars[] = {
        {&P.primal_variance, "primal_variance"}, {&P.dx_variance, "dx_variance"}, {&P.dy_variance, "dy_variance"}};
    for (const auto& [v, name] : vars)
        for (size_t i = 0; i < n * C; ++i)
            if (!(v->data[i] >= 0) || !std::isfinite(v->data[i]))
                throw InputError(std::string("poisson-weighted: layer '") + name + "' holds " +
                                 std::to_string(v->data[i]) + " at pixel " + pixel_text(i / C, w) +
                                 " (a variance must be finite and >= 0)");
    if (P.spp)
        for (size_t k = 0; k < n; ++k)
            if (!(P.spp[k] >= 1) || !std::isfinite(P.spp[k]))
                throw InputError("poisson-weighted: layer 'spp' holds " + std::to_string(P.spp[k]) + " at pixel " +
                                 pixel_text(k, w) + " (a sample count must be >= 1)");
}

RowWeights inverse_variance_weights(const VarianceProblem& P, const WeightedOptions& o, WeightedReport* report) {
    check_variance_problem(P, o);
    WeightedReport rep;
    const Rows R = build_rows(P, o, rep);
    if (report) *report = rep;
    return normalised(R, R.wp, R.wx, R.wy);
}

WeightedReport poisson_variance_weighted(const VarianceProblem& P, const WeightedOptions& o, float* out) {
    check_variance_problem(P, o);
    WeightedReport rep;
    const int w = P.primal.width, h = P.primal.height, C = P.primal.channels;
    const size_t n = size_t(w) * h;
    // Without a single variance estimate (one sample everywhere) there is
    // nothing to weight by: the robust unweighted solve, poisson-l1 with the
    // reference's alpha and schedule, is the best guess for either norm
    // (on the bathroom at 1 spp its relMSE was a third of poisson-l2's).
    if (P.spp && std::all_of(P.spp, P.spp + n, [](float s) { return s < 2.f; }) && !P.gradient_enabled &&
        !o.tile_fallback) {
        poisson_l1(PoissonProblem{P.primal, P.dx, P.dy, 0.2}, L1Options{}, out);
        if (o.energy == EnergyMode::mean) mean_tie(P, out);
        else if (o.energy == EnergyMode::lowpass) lowpass_tie(P, o.energy_radius, o.energy_clip, o.variance_radius, out);
        check_finite_result(ImageView{out, w, h, C}, "poisson-weighted");
        return rep;
    }
    const Rows R = build_rows(P, o, rep);
    const PoissonProblem prob{P.primal, P.dx, P.dy, 1.0};  // alpha 1: the colour weights carry the balance
    // Start: the exact unweighted solution with the reference's alpha, a
    // good approximation wherever the weights are near uniform, of the
    // gradients with the outlier rows' replaced by the primal's difference:
    // a start holding a gradient of 1e10 would end the CG (whose tolerance is
    // relative to the start's residual) far from the solution.
    ImageView dx0 = P.dx, dy0 = P.dy;
    std::vector<float> cleaned_dx, cleaned_dy;
    const auto clean = [&](const ImageView& g, const std::vector<unsigned char>& flag, size_t step,
                           std::vector<float>& store, ImageView& view) {
        if (std::none_of(flag.begin(), flag.end(), [](unsigned char f) { return f != 0; })) return;
        store.assign(g.data, g.data + n * C);
        for (size_t k = 0; k < n; ++k)
            if (flag[k])
                for (int ch = 0; ch < C; ++ch)
                    store[k * C + ch] = P.primal.data[(k + step) * C + ch] - P.primal.data[k * C + ch];
        view.data = store.data();
    };
    clean(P.dx, R.fx, 1, cleaned_dx, dx0);
    clean(P.dy, R.fy, size_t(w), cleaned_dy, dy0);
    poisson_l2(PoissonProblem{P.primal, dx0, dy0, 0.2}, out);
    CgOptions cg;
    cg.max_iterations = o.cg_iterations;
    cg.tolerance = o.tolerance;
    cg.preconditioner = Preconditioner::multigrid;
    RowWeights rw = normalised(R, R.wp, R.wx, R.wy);
    rep.cg_iterations += poisson_weighted(prob, &rw, cg, out).iterations;
    if (o.norm == WeightedNorm::l1) {
        std::vector<float> wp(n), wx(n), wy(n);
        CgOptions step = cg;
        step.max_iterations = std::max(2, o.cg_iterations / 10);
        const float eps = float(o.eps);
        for (int it = 0; it < o.irls_iterations; ++it) {
            // Normalised residual |e| / sigma of each row, channel-mean squared error over the row's variance.
            tbb::parallel_for(0, h, [&](int y) {
                for (int x = 0; x < w; ++x) {
                    const size_t k = size_t(y) * w + x;
                    double s0 = 0, sx = 0, sy = 0;
                    for (int ch = 0; ch < C; ++ch) {
                        const size_t i = k * C + ch;
                        const double d0 = double(out[i]) - P.primal.data[i];
                        s0 += d0 * d0;
                        if (R.ux[k]) {
                            const double d = double(out[i + C]) - out[i] - P.dx.data[i];
                            sx += d * d;
                        }
                        if (R.uy[k]) {
                            const double d = double(out[i + size_t(w) * C]) - out[i] - P.dy.data[i];
                            sy += d * d;
                        }
                    }
                    wp[k] = R.wp[k] / (float(std::sqrt(s0 / C / R.vp[k])) + eps);
                    wx[k] = R.wx[k] > 0 ? R.wx[k] / (float(std::sqrt(sx / C / R.vx[k])) + eps) : 0.f;
                    wy[k] = R.wy[k] > 0 ? R.wy[k] / (float(std::sqrt(sy / C / R.vy[k])) + eps) : 0.f;
                }
            });
            rw = normalised(R, wp, wx, wy);
            rep.cg_iterations += poisson_weighted(prob, &rw, step, out).iterations;
        }
    }
    // A pixel all of whose gradient rows are dropped is joined to nothing but
    // its own colour: its value is the primal, exactly (CG only approaches it).
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const size_t k = size_t(y) * w + x;
            const bool joined = R.wx[k] > 0 || R.wy[k] > 0 || (x > 0 && R.wx[k - 1] > 0) || (y > 0 && R.wy[k - w] > 0);
            if (!joined)
                for (int ch = 0; ch < C; ++ch) out[k * C + ch] = P.primal.data[k * C + ch];
        }
    });
    if (o.energy == EnergyMode::mean) mean_tie(P, out);
    else if (o.energy == EnergyMode::lowpass) lowpass_tie(P, o.energy_radius, o.energy_clip, o.variance_radius, out);
    check_finite_result(ImageView{out, w, h, C}, "poisson-weighted");
    return rep;
}

void combine_gradient_sets(const std::vector<GradientSet>& sets, std::vector<float>& dx, std::vector<float>& dy,
                           std::vector<float>& dx_variance, std::vector<float>& dy_variance) {
    if (sets.empty()) throw ParameterError("combine_gradient_sets: no gradient set");
    const ImageView& s0 = sets[0].dx;
    for (size_t i = 0; i < sets.size(); ++i)
        for (const ImageView* v : {&sets[i].dx, &sets[i].dy, &sets[i].dx_variance, &sets[i].dy_variance})
            if (!v->data || v->width != s0.width || v->height != s0.height || v->channels != s0.channels)
                throw ParameterError("combine_gradient_sets: set " + std::to_string(i) +
                                     " has a missing layer or one of another shape than set 0");
    const size_t len = size_t(s0.width) * s0.height * s0.channels;
    auto combine = [&](ImageView GradientSet::*g, ImageView GradientSet::*v, std::vector<float>& out,
                       std::vector<float>& out_var) {
        out.assign(len, 0.f), out_var.assign(len, 0.f);
        tbb::parallel_for(size_t(0), len, [&](size_t i) {
            double num = 0, den = 0;
            bool any_zero = false;
            for (const GradientSet& s : sets) {
                const double gi = (s.*g).data[i], vi = (s.*v).data[i];
                if (vi > 0) num += gi / vi, den += 1.0 / vi;
                else any_zero = true;
            }
            // A zero variance is an exact estimate: it alone decides (all
            // such estimates agree if they are exact; their mean otherwise).
            if (any_zero) {
                double s = 0, c = 0;
                for (const GradientSet& st : sets)
                    if (!((st.*v).data[i] > 0)) s += (st.*g).data[i], c += 1;
                out[i] = float(s / c), out_var[i] = 0.f;
                return;
            }
            out[i] = float(num / den), out_var[i] = float(1.0 / den);
        });
    };
    combine(&GradientSet::dx, &GradientSet::dx_variance, dx, dx_variance);
    combine(&GradientSet::dy, &GradientSet::dy_variance, dy, dy_variance);
}

}  // namespace gdr
