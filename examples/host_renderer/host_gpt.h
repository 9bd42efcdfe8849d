// Gradient-domain path tracing on the toy renderer through gdr's templated
// path-space core: the toy's own scene, materials, light and camera, gdr's
// walk, shift mapping, Jacobians and gradient MIS (Kettunen, Manzi, Aittala,
// Lehtinen, Durand and Zwicker, "Gradient-Domain Path Tracing", 2015). One
// base path per sample is shifted to the four neighbouring pixels; each pair
// splits its estimates between the two pixels and the edge between them.
#pragma once

#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "gdr/core/sampler.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/shift/builtin.h"
#include "gdr/shift/gradient_estimate.h"
#include "gdr/shift/offset_path.h"
#include "host.h"

namespace toy {

/// How the G-PT render samples: spp, base paths per pixel; seed, the
/// sampler's seed; shift, a registered shift's name; max_depth, the longest
/// path in segments; rr_depth, Russian roulette from that vertex on.
struct GptOptions {
    int spp = 16;
    uint32_t seed = 1;
    std::string shift = "half-vector";
    int max_depth = 16;
    int rr_depth = 5;
};

/// A G-PT render's estimates, row-major RGB (W/(m^2 sr)): primal, the image
/// without directly visible emitters; direct, those emitters; dx and dy, the
/// differences I(x+1, y) - I(x, y) and I(x, y+1) - I(x, y) (0 on the last
/// column or row).
struct GptImages {
    int width = 0, height = 0;
    std::vector<float> primal, direct, dx, dy;
};

/// Renders `host`'s image with G-PT (see GptOptions).
template <gdr::PathHost H>
GptImages render_gpt(const H& host, const GptOptions& o) {
    constexpr int dxs[4] = {1, -1, 0, 0}, dys[4] = {0, 0, 1, -1};  // the neighbour of each pair
    const int W = host.camera().width(), Hh = host.camera().height();
    const auto shift = gdr::make_shift_on<H>(o.shift);
    gdr::WalkOptions walk;
    walk.max_vertices = o.max_depth, walk.rr_depth = o.rr_depth;
    walk.reverse_densities = false, walk.forward_densities = false;  // G-PT's MIS reads solid-angle densities only
    const gdr::ShiftConfig config;
    const gdr::GradientMis mis;
    // Per pixel sums: the base's own share, each offset's share of its
    // neighbour, each one-sided gradient, and directly visible emission.
    const size_t n = size_t(W) * Hh;
    std::vector<Color> self(n, Color(0.f)), direct(n, Color(0.f));
    std::vector<Color> share(4 * n, Color(0.f)), grad(4 * n, Color(0.f));
    tbb::parallel_for(0, Hh, [&](int y) {
        gdr::BasicCameraPath<H> path;
        gdr::BasicOffsetPath<H> offset;
        gdr::BaseTerms terms;
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * W + x;
            for (int i = 0; i < o.spp; ++i) {
                gdr::Sampler s(gdr::SampleKey{o.seed, uint32_t(x), uint32_t(y), uint32_t(i)});
                s.set_dimension(gdr::dims::kFilm);
                const Vec2 film = Vec2(float(x), float(y)) + s.next2d();
                gdr::trace_camera_path(host, film, s, walk, path);
                if (path.size() <= 1) continue;
                gdr::compute_base_terms(host, path, mis.heuristic, terms);
                direct[p] += terms.v[1].emitted;  // directly visible emitters stay out of the gradients
                for (int d = 0; d < 4; ++d) {
                    const int nx = x + dxs[d], ny = y + dys[d];
                    if (nx < 0 || ny < 0 || nx >= W || ny >= Hh) {
                        // No neighbour: the base alone estimates its quarter.
                        self[p] += 0.25f * gdr::evaluate_pair(host, path, terms, nullptr, mis).base;
                        continue;
                    }
                    gdr::shift_camera_path(host, *shift, config, path, Vec2(float(dxs[d]), float(dys[d])), offset);
                    const gdr::PairEstimate e = gdr::evaluate_pair(host, path, terms, &offset, mis);
                    self[p] += 0.25f * e.base;  // each of the four pairs carries a quarter of both primals
                    share[4 * p + d] += 0.25f * e.offset;
                    grad[4 * p + d] += e.gradient;
                }
            }
        }
    });
    GptImages out;
    out.width = W, out.height = Hh;
    for (auto* v : {&out.primal, &out.direct, &out.dx, &out.dy}) v->assign(3 * n, 0.f);
    const float inv = 1.f / float(o.spp);
    const auto put = [&](std::vector<float>& im, size_t p, const Color& c) {
        for (int k = 0; k < 3; ++k) im[3 * p + k] = c[k] * inv;
    };
    for (int y = 0; y < Hh; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * W + x;
            Color c = self[p];
            for (int d = 0; d < 4; ++d) {  // the neighbours whose offsets landed here
                const int qx = x - dxs[d], qy = y - dys[d];
                if (qx >= 0 && qy >= 0 && qx < W && qy < Hh) c += share[4 * (size_t(qy) * W + qx) + d];
            }
            put(out.primal, p, c);
            put(out.direct, p, direct[p]);
            // Both pairs across an edge estimate its difference, each with its share of the MIS weight.
            if (x + 1 < W) put(out.dx, p, grad[4 * p + 0] - grad[4 * (p + 1) + 1]);
            if (y + 1 < Hh) put(out.dy, p, grad[4 * p + 2] - grad[4 * (p + W) + 3]);
        }
    return out;
}

}  // namespace toy
