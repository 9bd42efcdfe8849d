#include "gdr/integrators/adaptive.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "gdr/core/error.h"
#include "gdr/core/sampler.h"
#include "gdr/integrators/gpt.h"
#include "gdr/reconstruct/reconstructor.h"

namespace gdr {

namespace {

// A layer of the pilot with the given channels, or a ParameterError naming it.
const Image& pilot_layer(const FrameBuffer& fb, const std::string& name, const char* why) {
    if (!fb.has(name))
        throw ParameterError("adaptive sampling: the pilot render has no '" + name + "' layer (" + why + ")");
    const Image& im = fb.get(name);
    if (im.channels() < 3)
        throw ParameterError("adaptive sampling: the pilot's layer '" + name + "' has " +
                             std::to_string(im.channels()) + " channels, not 3");
    return im;
}

float channel_sum(const Image& im, int x, int y) {
    const float s = im.at(x, y, 0) + im.at(x, y, 1) + im.at(x, y, 2);
    return std::isfinite(s) ? std::max(0.f, s) : 0.f;
}

// Separable filter with the symmetric kernel `k` (2r+1 taps), weights
// renormalised where the window leaves the image.
std::vector<float> separable(const std::vector<float>& v, int W, int H, const std::vector<double>& k) {
    const int r = int(k.size()) / 2;
    std::vector<float> rows(v.size()), out(v.size());
    const auto pass = [&](const std::vector<float>& in, std::vector<float>& to, bool along_rows) {
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                double s = 0.0, w = 0.0;
                for (int i = -r; i <= r; ++i) {
                    const int xi = along_rows ? x + i : x, yi = along_rows ? y : y + i;
                    if (xi < 0 || yi < 0 || xi >= W || yi >= H) continue;
                    s += k[size_t(i + r)] * in[size_t(yi) * W + xi], w += k[size_t(i + r)];
                }
                to[size_t(y) * W + x] = float(s / w);
            }
    };
    pass(v, rows, true);
    pass(rows, out, false);
    return out;
}

std::vector<float> median(const std::vector<float>& v, int W, int H, int r) {
    if (r <= 0) return v;
    std::vector<float> out(v.size()), win;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            win.clear();
            for (int j = std::max(0, y - r); j <= std::min(H - 1, y + r); ++j)
                for (int i = std::max(0, x - r); i <= std::min(W - 1, x + r); ++i) win.push_back(v[size_t(j) * W + i]);
            std::nth_element(win.begin(), win.begin() + win.size() / 2, win.end());
            out[size_t(y) * W + x] = win[win.size() / 2];
        }
    return out;
}

}  // namespace

Image adaptive_sample_density(const FrameBuffer& pilot, const AdaptiveOptions& o) {
    if (!(o.uniform >= 0.0 && o.uniform <= 1.0))
        throw ParameterError(fmt::format("adaptive sampling: the uniform share must be between 0 and 1, got {}", o.uniform));
    if (!(o.max_density >= 1.0 && o.max_density <= double(kMaxSampleDensity)))
        throw ParameterError(fmt::format("adaptive sampling: the largest density must be between 1 and {}, got {}",
                                         kMaxSampleDensity, o.max_density));
    if (!(o.epsilon > 0.0)) throw ParameterError("adaptive sampling: epsilon must be positive");
    if (o.median_radius < 0 || o.median_radius > 8)
        throw ParameterError("adaptive sampling: the median radius must be between 0 and 8");
    const int W = pilot.width(), H = pilot.height();
    const size_t n = size_t(W) * size_t(H);
    const bool gradients = o.source == AdaptiveOptions::Source::Gradients ||
                           (o.source == AdaptiveOptions::Source::Auto && pilot.has("dx_variance"));
    const char* colour = pilot.has("primal") ? "primal" : "color";
    const Image& primal = pilot_layer(pilot, colour, "the brightness the error is relative to");
    std::vector<float> error(n, 0.f), bright(n);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) bright[size_t(y) * W + x] = channel_sum(primal, x, y) / 3.f;
    if (gradients) {
        const Image& vx = pilot_layer(pilot, "dx_variance", "the gradient-domain integrators write it");
        const Image& vy = pilot_layer(pilot, "dy_variance", "the gradient-domain integrators write it");
        // The gradients on the pixel's four edges (the last column of dx and row of dy are unused).
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                float e = 0.f;
                if (x + 1 < W) e += channel_sum(vx, x, y);
                if (x > 0) e += channel_sum(vx, x - 1, y);
                if (y + 1 < H) e += channel_sum(vy, x, y);
                if (y > 0) e += channel_sum(vy, x, y - 1);
                error[size_t(y) * W + x] = e;
            }
    } else {
        // gpt's primal_variance, or pt's "variance" of its colour.
        const std::string var = pilot.has("primal_variance") ? "primal_variance" : "variance";
        if (!pilot.has(var))
            throw ParameterError("adaptive sampling: the pilot render has neither a 'primal_variance' layer (as gpt "
                                 "writes) nor a 'variance' layer (as pt writes)");
        const Image& v = pilot_layer(pilot, var, "a render with variances");
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) error[size_t(y) * W + x] = channel_sum(v, x, y);
    }
    const std::vector<float> L = separable(bright, W, H, std::vector<double>(5, 1.0));  // 5x5 box
    std::vector<float> r(n);
    for (size_t p = 0; p < n; ++p) {
        const double v = std::sqrt(double(error[p]) / (double(L[p]) * double(L[p]) + o.epsilon));
        r[p] = std::isfinite(v) ? float(v) : 0.f;
    }
    // The publication's [.1 .2 .4 .2 .1] splat of the median-filtered densities.
    r = separable(median(r, W, H, o.median_radius), W, H, {.1, .2, .4, .2, .1});

    // Density = uniform share + adaptive share, the adaptive part of mean 1
    // capped so that no pixel exceeds max_density: capped pixels are fixed
    // and the rest rescaled until the mean holds (water filling).
    Image density(W, H, 1);
    double mean = 0.0;
    for (float v : r) mean += v;
    mean /= double(std::max<size_t>(n, 1));
    if (!(mean > 0.0) || o.uniform >= 1.0) {
        std::fill(density.values().begin(), density.values().end(), 1.f);  // noiseless pilot: nothing to adapt to
        return density;
    }
    const double cap = (o.max_density - o.uniform) / (1.0 - o.uniform);
    std::vector<double> a(n);
    for (size_t p = 0; p < n; ++p) a[p] = double(r[p]) / mean;
    for (int it = 0; it < 50; ++it) {
        double fixed = 0.0, free = 0.0;
        for (double v : a) (v >= cap ? fixed : free) += std::min(v, cap);
        const double want = double(n) - fixed;  // what the uncapped pixels must sum to
        if (free <= 0.0 || std::abs(want - free) <= 1e-9 * double(n)) break;
        const double s = want / free;
        for (double& v : a) v = v >= cap ? cap : std::min(cap, v * s);
    }
    for (size_t p = 0; p < n; ++p)
        density.values()[p] = float(o.uniform + (1.0 - o.uniform) * std::min(a[p], cap));
    return density;
}

double gls_variance_factor(double r) {
    if (!(r > 0.0)) return 0.0;
    if (!std::isfinite(r)) return 1.0;
    // Mean of r / (r + lambda) over the cosine (DCT) frequencies of an
    // N x N image, lambda = 4 sin^2(pi i / 2N) + 4 sin^2(pi j / 2N): the
    // spectrum of the solution's covariance (w_p + w_g L)^-1 over the
    // primal's variance 1 / w_p. N = 64 is within 1% of larger images for
    // r >= 1e-4; the constant term (lambda = 0) gives the floor 1 / N^2.
    constexpr int N = 64;
    static const std::vector<double> lambda = [] {
        std::vector<double> l(size_t(N) * N);
        const double pi = 3.14159265358979323846;
        for (int j = 0; j < N; ++j)
            for (int i = 0; i < N; ++i) {
                const double a = std::sin(pi * i / (2.0 * N)), b = std::sin(pi * j / (2.0 * N));
                l[size_t(j) * N + i] = 4.0 * (a * a + b * b);
            }
        return l;
    }();
    double s = 0.0;
    for (double l : lambda) s += r / (r + l);
    return s / double(lambda.size());
}

namespace {

void check_select_options(const GradientSelectOptions& o) {
    if (o.tile < 1) throw ParameterError(fmt::format("gradient selection: tile must be >= 1, got {}", o.tile));
    if (!(o.max_density >= 1.0 && o.max_density <= kMaxSampleDensity))
        throw ParameterError(fmt::format("gradient selection: max_density must be in [1, {}], got {}",
                                         kMaxSampleDensity, o.max_density));
}

void check_seconds(double tg, double tp) {
    if (!(tg > 0.0 && tp > 0.0 && std::isfinite(tg) && std::isfinite(tp)))
        throw ParameterError(fmt::format("gradient selection: seconds per pass must be positive, got {} and {}", tg, tp));
}

// The mask and densities from per-pixel costs (variance times seconds, any
// common unit) with and without gradients: a tile keeps its gradients iff
// the sum of `with` over it is below the sum of `without`.
GradientSelection tile_selection(int W, int H, double cost, const GradientSelectOptions& o,
                                 const std::vector<double>& with, const std::vector<double>& without) {
    GradientSelection sel;
    sel.cost_ratio = cost;
    sel.mask = Image(W, H, 1);
    long long on = 0;
    for (int ty = 0; ty < H; ty += o.tile)
        for (int tx = 0; tx < W; tx += o.tile) {
            double a = 0, b = 0;
            for (int y = ty; y < std::min(H, ty + o.tile); ++y)
                for (int x = tx; x < std::min(W, tx + o.tile); ++x)
                    a += with[size_t(y) * W + x], b += without[size_t(y) * W + x];
            const bool pays = W * H > 1 && a < b;
            for (int y = ty; y < std::min(H, ty + o.tile); ++y)
                for (int x = tx; x < std::min(W, tx + o.tile); ++x) sel.mask.at(x, y) = pays ? 1.f : 0.f;
            if (pays) on += (std::min(H, ty + o.tile) - ty) * (std::min(W, tx + o.tile) - tx);
        }
    const double n = double(W) * double(H);
    sel.gradient_share = n > 0 ? double(on) / n : 1.0;
    // Equal time per pixel: a primal-only pixel takes `cost` samples per
    // gradient pixel's one, then all scaled to mean 1.
    const double k = std::clamp(cost, 1.0, o.max_density);
    const double mean = sel.gradient_share + (1.0 - sel.gradient_share) * k;
    sel.density = Image(W, H, 1);
    for (size_t i = 0; i < sel.density.values().size(); ++i)
        sel.density.values()[i] = float((sel.mask.values()[i] != 0.f ? 1.0 : k) / mean);
    return sel;
}

}  // namespace

GradientSelection select_gradient_pixels(const FrameBuffer& g, double tg, const FrameBuffer& p, double tp,
                                         const GradientSelectOptions& o) {
    check_select_options(o);
    check_seconds(tg, tp);
    const int W = g.width(), H = g.height();
    if (p.width() != W || p.height() != H)
        throw ParameterError(fmt::format("gradient selection: the pilots are {}x{} and {}x{}", W, H, p.width(),
                                         p.height()));
    const Image& vp = pilot_layer(g, "primal_variance", "the gradient pilot's primal variance");
    const Image& vx = pilot_layer(g, "dx_variance", "the gradients' variance");
    const Image& vy = pilot_layer(g, "dy_variance", "the gradients' variance");
    const Image& vpt = pilot_layer(p, "primal_variance", "the primal-only pilot's variance");
    // F on a grid of log r (1e-6 to 1e6, 16 steps a decade), interpolated:
    // the exact mean over 4096 frequencies per pixel would cost seconds at 720p.
    static const std::vector<double> table = [] {
        std::vector<double> t(12 * 16 + 1);
        for (size_t i = 0; i < t.size(); ++i) t[i] = gls_variance_factor(std::pow(10.0, -6.0 + double(i) / 16.0));
        return t;
    }();
    const auto F = [&](double r) {
        if (!(r > 0.0)) return 0.0;
        const double u = std::clamp((std::log10(r) + 6.0) * 16.0, 0.0, double(table.size() - 1));
        const size_t i = std::min(size_t(u), table.size() - 2);
        return table[i] + (u - double(i)) * (table[i + 1] - table[i]);
    };
    // Per pixel, the weighted solve's variance vp F(vg / vp) with vg the mean
    // of its edges' gradient variances: bounded by vp, so one outlier
    // gradient (which the solve drops anyway) cannot outweigh its tile.
    std::vector<double> with(size_t(W) * H), without(size_t(W) * H);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            double gv = 0.0;
            int m = 0;
            if (x + 1 < W) gv += channel_sum(vx, x, y), ++m;
            if (x > 0) gv += channel_sum(vx, x - 1, y), ++m;
            if (y + 1 < H) gv += channel_sum(vy, x, y), ++m;
            if (y > 0) gv += channel_sum(vy, x, y - 1), ++m;
            const double v = channel_sum(vp, x, y);
            with[size_t(y) * W + x] = tg * (m > 0 && v > 0.0 ? v * F(gv / m / v) : v);
            without[size_t(y) * W + x] = tp * channel_sum(vpt, x, y);
        }
    return tile_selection(W, H, tg / tp, o, with, without);
}

GradientSelection select_gradient_pixels(const SelectionPilots& pl, const GradientSelectOptions& o) {
    check_select_options(o);
    check_seconds(pl.gradient_seconds_per_pass, pl.primal_seconds_per_pass);
    for (const FrameBuffer* fb : {pl.gradient[0], pl.gradient[1], pl.primal[0], pl.primal[1]})
        if (!fb) throw ParameterError("gradient selection: a pilot is missing (two of each kind are needed)");
    if (pl.gradient_passes < 1 || pl.primal_passes < 1)
        throw ParameterError(fmt::format("gradient selection: the pilots' passes must be >= 1, got {} and {}",
                                         pl.gradient_passes, pl.primal_passes));
    const int W = pl.gradient[0]->width(), H = pl.gradient[0]->height();
    for (const FrameBuffer* fb : {pl.gradient[1], pl.primal[0], pl.primal[1]})
        if (fb->width() != W || fb->height() != H)
            throw ParameterError(fmt::format("gradient selection: the pilots are {}x{} and {}x{}", W, H, fb->width(),
                                             fb->height()));
    // Each gradient pilot's reconstruction: its own layer where it has the
    // method's (made with the render's reconstruct.* parameters).
    Image rec[2];
    for (int i = 0; i < 2; ++i) {
        const FrameBuffer& fb = *pl.gradient[i];
        if (fb.has(reconstruction_layer(o.method))) rec[i] = fb.get(reconstruction_layer(o.method));
        else rec[i] = reconstruct(o.method, Params("gradient selection"), gradient_buffers(fb));
    }
    const Image& pa = pilot_layer(*pl.primal[0], "color", "the primal-only pilot's colour");
    const Image& pb = pilot_layer(*pl.primal[1], "color", "the primal-only pilot's colour");
    const Image& ca = pilot_layer(*pl.gradient[0], "color", "the gradient pilot's colour");
    const Image& cb = pilot_layer(*pl.gradient[1], "color", "the gradient pilot's colour");
    // Variance per sample times seconds per sample, in relMSE's units.
    const double kg = double(pl.gradient_passes) * pl.gradient_seconds_per_pass;
    const double kp = double(pl.primal_passes) * pl.primal_seconds_per_pass;
    std::vector<double> with(size_t(W) * H), without(size_t(W) * H);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            double a = 0.0, b = 0.0;
            for (int c = 0; c < 3; ++c) {
                const double m = 0.25 * (double(pa.at(x, y, c)) + pb.at(x, y, c) + ca.at(x, y, c) + cb.at(x, y, c));
                const double den = 2.0 * (m * m + 0.01);
                const double dr = double(rec[0].at(x, y, c)) - rec[1].at(x, y, c);
                const double dp = double(pa.at(x, y, c)) - pb.at(x, y, c);
                a += std::isfinite(dr) ? dr * dr / den : 0.0;
                b += std::isfinite(dp) ? dp * dp / den : 0.0;
            }
            with[size_t(y) * W + x] = kg * a, without[size_t(y) * W + x] = kp * b;
        }
    return tile_selection(W, H, pl.gradient_seconds_per_pass / pl.primal_seconds_per_pass, o, with, without);
}

// Fewest passes a timed pilot takes: per-sample variances from fewer are mostly noise.
constexpr long long kMinPilotSpp = 4;

uint64_t pilot_seed(uint64_t seed) { return mix64(seed ^ 0x70696c6f74ull); }  // "pilot"

namespace {

// Adds r's samples, rays and non-finite samples (not its spp or seconds) to `into`.
void add_work(RenderStats& into, const RenderStats& r) {
    into.samples += r.samples, into.rays += r.rays, into.nonfinite += r.nonfinite;
}

// A pilot render of `st` (its seed, spp and sample 0 already set): with a
// time budget > 0 in `seconds`, at least st.spp passes and then whole
// passes until `seconds` are spent (or the render is cancelled).
RenderStats run_pilot(Integrator& integrator, const Scene& scene, const RenderSettings& st, double seconds,
                      FrameBuffer& fb, const ProgressFn& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    RenderStats ps = integrator.render(scene, st, fb, progress);
    if (seconds > 0.0) {
        const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (spent < seconds && !(st.cancel && st.cancel->load())) {
            RenderSettings more = st;
            more.spp = 0;
            more.first_sample = ps.spp;
            more.time_budget = seconds - spent;
            FrameBuffer rest;
            const RenderStats ms = integrator.render(scene, more, rest, progress);
            merge_renders(fb, rest);
            ps.spp += ms.spp;
            add_work(ps, ms);
        }
    }
    ps.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return ps;
}

// The pilots of AdaptiveRender::Mode::SelectGradients for `pilot` (seed,
// spp and sample 0 set) and their choice: primal-only renders first (an
// integrator without gradients refuses the mask before any time is spent),
// then gradient renders, the first of which spends what is left of `seconds`
// (> 0 with a time budget); two of each kind for Criterion::Measured. `kept`
// receives the gradient pilots (merged) and `ps` their passes and every
// pilot's work.
GradientSelection selection_pilots(Integrator& integrator, const Scene& scene, const RenderSettings& pilot,
                                   double seconds, const GradientSelectOptions& o, FrameBuffer& kept, RenderStats& ps,
                                   const ProgressFn& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    const bool measured = o.criterion == GradientSelectOptions::Criterion::Measured;
    const int halves = measured ? 2 : 1;  // independent renders of each kind
    const Image none(scene.camera().width(), scene.camera().height(), 1);
    RenderSettings primal = pilot;
    primal.gradient_mask = &none;
    if (measured) primal.spp = std::max(1LL, primal.spp / 2);
    FrameBuffer primal_fb[2], gradient_fb[2];
    double primal_seconds = 0.0;
    for (int i = 0; i < halves; ++i) {
        primal.seed = mix64(pilot.seed ^ (0x7072696d616cull + uint64_t(i)));  // "primal"
        const RenderStats pp = integrator.render(scene, primal, primal_fb[i], progress);
        primal_seconds += pp.seconds;
        add_work(ps, pp);
    }
    const double primal_per_pass = primal_seconds / double(halves * primal.spp);
    // The gradient pilots: the first takes its share of the time, the second as many passes.
    RenderSettings gradient = pilot;
    if (measured) gradient.spp = std::max(1LL, gradient.spp / 2);
    const double left = seconds - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const RenderStats g0 =
        run_pilot(integrator, scene, gradient, seconds > 0.0 ? std::max(0.0, left / halves) : 0.0, gradient_fb[0], progress);
    ps.spp += g0.spp;
    add_work(ps, g0);
    GradientSelection selection;
    if (measured) {
        gradient.seed = mix64(pilot.seed ^ 0x6772616469656e74ull);  // "gradient"
        gradient.spp = g0.spp;
        const RenderStats g1 = integrator.render(scene, gradient, gradient_fb[1], progress);
        ps.spp += g1.spp;
        add_work(ps, g1);
        SelectionPilots pilots;
        pilots.gradient[0] = &gradient_fb[0], pilots.gradient[1] = &gradient_fb[1];
        pilots.primal[0] = &primal_fb[0], pilots.primal[1] = &primal_fb[1];
        pilots.gradient_passes = g0.spp, pilots.primal_passes = primal.spp;
        pilots.gradient_seconds_per_pass = (g0.seconds + g1.seconds) / double(2 * g0.spp);
        pilots.primal_seconds_per_pass = primal_per_pass;
        selection = select_gradient_pixels(pilots, o);
        kept = std::move(gradient_fb[0]);
        merge_renders(kept, gradient_fb[1]);  // kept, if it is, as one pilot
    } else {
        selection = select_gradient_pixels(gradient_fb[0], g0.seconds / double(std::max(1LL, g0.spp)), primal_fb[0],
                                           primal_per_pass, o);
        kept = std::move(gradient_fb[0]);
    }
    return selection;
}

}  // namespace

RenderStats render_adaptive(Integrator& integrator, const Scene& scene, const RenderSettings& st, FrameBuffer& out,
                            const AdaptiveRender& ad, const ProgressFn& progress) {
    if (!(ad.pilot > 0.0 && ad.pilot <= 0.5))
        throw ParameterError(fmt::format("adaptive sampling: the pilot's share must be above 0 and at most 0.5, got {}",
                                         ad.pilot));
    if (st.sample_density)
        throw ParameterError("adaptive sampling: the render already has a sample density (a resumed render keeps its own)");
    const bool select = ad.mode == AdaptiveRender::Mode::SelectGradients;
    if (select && st.gradient_mask)
        throw ParameterError("gradient selection: the render already has a gradient mask (a resumed render keeps its own)");
    const bool timed = st.time_budget > 0.0;
    if (!timed && st.spp < 2) throw ParameterError("adaptive sampling needs at least 2 spp: 1 for the pilot, 1 to adapt");
    RenderSettings pilot = st;
    pilot.seed = pilot_seed(st.seed);
    pilot.first_sample = 0;
    pilot.frame_sampling = nullptr;  // the pilot estimates variances only: no seed sharing
    long long pilot_spp = 0;
    if (!timed) {
        pilot_spp = std::clamp((long long)std::llround(ad.pilot * double(st.spp)), 1LL, st.spp - 1);
        pilot.spp = pilot_spp;
    } else {
        // At least kMinPilotSpp passes, or the variances are mostly noise; then
        // whole passes until the pilot's share of the time is spent.
        pilot.spp = kMinPilotSpp;
        pilot.time_budget = 0.0;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const double share = timed ? ad.pilot : double(pilot_spp) / double(st.spp);
    const ProgressFn pilot_progress = progress ? ProgressFn([&](const Progress& p) {
        Progress q = p;
        q.fraction = share * p.fraction;
        progress(q);
    }) : ProgressFn();

    const double pilot_budget = timed ? ad.pilot * st.time_budget : 0.0;  // seconds; 0: the pilot's spp
    RenderStats ps;
    FrameBuffer pilot_fb;
    Image density;
    GradientSelection selection;
    if (select) {
        selection = selection_pilots(integrator, scene, pilot, pilot_budget, ad.select, pilot_fb, ps, pilot_progress);
        density = std::move(selection.density);
    } else {
        ps = run_pilot(integrator, scene, pilot, pilot_budget, pilot_fb, pilot_progress);
        density = adaptive_sample_density(pilot_fb, ad.density);
    }
    if (!ad.keep_pilot) pilot_fb = FrameBuffer();
    const double pilot_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    RenderSettings main = st;
    main.sample_density = &density;
    if (select) main.gradient_mask = &selection.mask;
    if (timed) main.time_budget = std::max(1e-3, st.time_budget - pilot_seconds);
    else main.spp = st.spp - pilot_spp;
    RenderStats rs = integrator.render(scene, main, out, progress ? ProgressFn([&](const Progress& p) {
        Progress q = p;
        q.fraction = share + (1.0 - share) * p.fraction;
        q.samples += ps.samples;
        q.seconds += pilot_seconds;
        progress(q);
    }) : ProgressFn());
    if (ad.keep_pilot) {
        // Each pixel weighted by its own counts in both renders. The gradient
        // pilot has gradients everywhere: where the render has none, the
        // merged edges become the merged primal's differences.
        if (select) pilot_fb.set("gradient_mask", selection.mask);
        merge_renders(out, pilot_fb);
        if (select) fill_masked_gradients(out);
        integrator.update_merged(out);
        out.metadata()["adaptive_pilot_kept"] = "true";
    }
    if (select) {
        out.metadata()["gradient_share"] = fmt::format("{:.4f}", selection.gradient_share);
        out.metadata()["gradient_cost_ratio"] = fmt::format("{:.3f}", selection.cost_ratio);
    }
    out.metadata()["adaptive_pilot_spp"] = std::to_string(ps.spp);
    out.metadata()["adaptive_pilot_seconds"] = fmt::format("{:.3f}", pilot_seconds);
    rs.seconds += pilot_seconds;
    add_work(rs, ps);
    return rs;
}

}  // namespace gdr
