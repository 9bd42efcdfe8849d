#include "gdr/integrators/adaptive.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "gdr/core/error.h"
#include "gdr/core/sampler.h"

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

// Fewest passes a timed pilot takes: per-sample variances from fewer are mostly noise.
constexpr long long kMinPilotSpp = 4;

uint64_t pilot_seed(uint64_t seed) { return mix64(seed ^ 0x70696c6f74ull); }  // "pilot"

RenderStats render_adaptive(Integrator& integrator, const Scene& scene, const RenderSettings& st, FrameBuffer& out,
                            const AdaptiveRender& ad, const ProgressFn& progress) {
    if (!(ad.pilot > 0.0 && ad.pilot <= 0.5))
        throw ParameterError(fmt::format("adaptive sampling: the pilot's share must be above 0 and at most 0.5, got {}",
                                         ad.pilot));
    if (st.sample_density)
        throw ParameterError("adaptive sampling: the render already has a sample density (a resumed render keeps its own)");
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
    FrameBuffer pilot_fb;
    const double share = timed ? ad.pilot : double(pilot_spp) / double(st.spp);
    const ProgressFn pilot_progress = progress ? ProgressFn([&](const Progress& p) {
        Progress q = p;
        q.fraction = share * p.fraction;
        progress(q);
    }) : ProgressFn();
    RenderStats ps = integrator.render(scene, pilot, pilot_fb, pilot_progress);
    if (timed) {
        const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (spent < ad.pilot * st.time_budget && !(st.cancel && st.cancel->load())) {
            RenderSettings more = pilot;
            more.spp = 0;
            more.first_sample = ps.spp;
            more.time_budget = ad.pilot * st.time_budget - spent;
            FrameBuffer rest;
            const RenderStats ms = integrator.render(scene, more, rest, pilot_progress);
            merge_renders(pilot_fb, rest);
            ps.spp += ms.spp, ps.samples += ms.samples, ps.rays += ms.rays, ps.nonfinite += ms.nonfinite;
        }
    }
    const Image density = adaptive_sample_density(pilot_fb, ad.density);
    if (!ad.keep_pilot) pilot_fb = FrameBuffer();
    const double pilot_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    RenderSettings main = st;
    main.sample_density = &density;
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
        // Each pixel weighted by its own counts in both renders.
        merge_renders(out, pilot_fb);
        integrator.update_merged(out);
        out.metadata()["adaptive_pilot_kept"] = "true";
    }
    out.metadata()["adaptive_pilot_spp"] = std::to_string(ps.spp);
    out.metadata()["adaptive_pilot_seconds"] = fmt::format("{:.3f}", pilot_seconds);
    rs.seconds += pilot_seconds;
    rs.samples += ps.samples;
    rs.rays += ps.rays;
    rs.nonfinite += ps.nonfinite;
    return rs;
}

}  // namespace gdr
