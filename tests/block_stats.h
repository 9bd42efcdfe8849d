// Block statistics over independent renders, the statistical tool of the
// integrator tests: per-block means of a per-pixel value over runs with
// different seeds, their standard errors from the run-to-run spread (no
// per-pixel variance estimate is trusted), and the largest block z between
// two such sets. Plus the McGuire Cornell boxes at test resolutions.
#pragma once

#include <catch2/catch.hpp>

#include <cmath>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"
#include "gdr/shift/validate.h"

namespace gdr::test {

/// Integrator or reconstructor parameters from key/value text pairs, parsed as on the command line.
inline Params params(std::initializer_list<std::pair<const char*, const char*>> kv) {
    Params p("test");
    for (const auto& [k, v] : kv) p.set_from_text(std::string(k) + "=" + v);
    return p;
}

inline std::string box(const std::string& variant) {
    return std::string(GDR_SOURCE_DIR) + "/scenes/cornell-box/CornellBox-" + variant + ".obj";
}

// The McGuire box at a small resolution, so statistical tests can afford many runs.
inline std::unique_ptr<Scene> small_box(const std::string& variant, int res) {
    TriangleMesh mesh;
    std::vector<Material> mats;
    load_obj(box(variant), Mat4(1.f), mesh, mats);
    CameraDesc cd;
    cd.position = {0.f, 1.f, 3.5f};
    cd.target = {0.f, 1.f, 0.f};
    cd.fov_deg = 45.f;
    cd.width = cd.height = res;
    return std::make_unique<Scene>(std::move(mesh), std::move(mats), Camera(cd), box(variant));
}

inline FrameBuffer render(const Scene& scene, const std::string& integrator, const Params& p, long long spp, uint64_t seed) {
    auto integ = integrator_registry().create(integrator, p);
    RenderSettings st;
    st.spp = spp;
    st.seed = seed;
    FrameBuffer fb;
    integ->render(scene, st, fb);
    return fb;
}

// Per-block means of a per-pixel statistic over independent runs: mean and standard error per block.
struct BlockStats {
    std::vector<double> mean, se;
};

template <typename F>
BlockStats block_stats(int runs, int w, int h, int block, F&& value_of_run) {
    const int bw = (w + block - 1) / block, bh = (h + block - 1) / block;
    std::vector<std::vector<double>> per_run(bw * bh);
    for (int r = 0; r < runs; ++r) {
        std::vector<double> sum(bw * bh, 0.0), cnt(bw * bh, 0.0);
        value_of_run(r, [&](int x, int y, double v) {
            const int b = (y / block) * bw + x / block;
            sum[b] += v, cnt[b] += 1.0;
        });
        for (size_t b = 0; b < sum.size(); ++b) per_run[b].push_back(cnt[b] > 0 ? sum[b] / cnt[b] : 0.0);
    }
    BlockStats s;
    for (const auto& v : per_run) {
        double m = 0.0, q = 0.0;
        for (double x : v) m += x;
        m /= double(v.size());
        for (double x : v) q += (x - m) * (x - m);
        s.mean.push_back(m);
        s.se.push_back(std::sqrt(q / double(v.size() - 1) / double(v.size())));
    }
    return s;
}

inline double grey(const Image& img, int x, int y) {
    const Color c = img.rgb(x, y);
    return (double(c.r) + c.g + c.b) / 3.0;
}

// Largest |z| over blocks between two sets of block statistics.
inline double max_z(const BlockStats& a, const BlockStats& b) {
    double worst = 0.0;
    for (size_t i = 0; i < a.mean.size(); ++i) {
        const double se = std::sqrt(a.se[i] * a.se[i] + b.se[i] * b.se[i]);
        if (se == 0.0) {
            REQUIRE(std::abs(a.mean[i] - b.mean[i]) < 1e-6);
            continue;
        }
        worst = std::max(worst, std::abs(a.mean[i] - b.mean[i]) / se);
    }
    return worst;
}

// Block statistics scaled by `gain`: a deliberately wrong estimate, for the
// power checks.
inline BlockStats scaled(BlockStats s, double gain) {
    for (double& m : s.mean) m *= gain;
    for (double& e : s.se) e *= gain;
    return s;
}

// Block statistics of the grey value of layer `layer` over renders `fbs`
// (one per run), in blocks of `block` pixels.
inline BlockStats grey_stats(const std::vector<FrameBuffer>& fbs, const std::string& layer, int block) {
    const int w = fbs.at(0).width(), h = fbs.at(0).height();
    return block_stats(int(fbs.size()), w, h, block, [&](int r, auto&& add) {
        const Image& c = fbs[r].get(layer);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) add(x, y, grey(c, x, y));
    });
}

// Block statistics of the differences of neighbouring pixels' grey values,
// along x (or y), of layer `layer` over renders `fbs` (one per run), in
// blocks of `block` pixels. With `add_direct`, `layer` is a gradient layer
// (dx, dy): gradients leave directly visible emitters (and an environment
// seen directly) to the "direct" layer, whose differences are added back.
inline BlockStats difference_stats(const std::vector<FrameBuffer>& fbs, const char* layer, bool along_x,
                                   bool add_direct, int block) {
    const int w = fbs.at(0).width(), h = fbs.at(0).height();
    return block_stats(int(fbs.size()), w, h, block, [&](int r, auto&& add) {
        const Image& d = fbs[r].get(layer);
        for (int y = 0; y < h - !along_x; ++y)
            for (int x = 0; x < w - along_x; ++x) {
                if (!add_direct) {
                    add(x, y, grey(d, x + along_x, y + !along_x) - grey(d, x, y));
                    continue;
                }
                const Image& e = fbs[r].get("direct");
                add(x, y, grey(d, x, y) + grey(e, x + along_x, y + !along_x) - grey(e, x, y));
            }
    });
}

// `runs` renders of `scene` by `integrator` with seeds seed0, seed0 + 1, ...
inline std::vector<FrameBuffer> render_runs(const Scene& scene, const std::string& integrator, const Params& p,
                                            long long spp, int runs, uint64_t seed0) {
    std::vector<FrameBuffer> fbs;
    for (int r = 0; r < runs; ++r) fbs.push_back(render(scene, integrator, p, spp, seed0 + uint64_t(r)));
    return fbs;
}

/// gpt renders `g` against pt renders `pt` of one scene: the largest block |z|
/// of E[dx] and E[dy] against pt's pixel differences, of the negated dx (a
/// power check: it must be rejected), of the primal against pt's image, and of
/// the primal scaled by 0.95 (power again).
struct GradientZ {
    double zx = 0, zy = 0, z_neg = 0, zp = 0, zp_dark = 0;
};
inline GradientZ gradient_z(const std::vector<FrameBuffer>& pt, const std::vector<FrameBuffer>& g, int block) {
    GradientZ z;
    const BlockStats ref_dx = difference_stats(pt, "color", true, false, block);
    const BlockStats dx = difference_stats(g, "dx", true, true, block);
    z.zx = max_z(dx, ref_dx);
    z.zy = max_z(difference_stats(g, "dy", false, true, block), difference_stats(pt, "color", false, false, block));
    BlockStats neg = dx;
    for (double& m : neg.mean) m = -m;
    z.z_neg = max_z(neg, ref_dx);
    const BlockStats ref = grey_stats(pt, "color", block), primal = grey_stats(g, "color", block);
    z.zp = max_z(primal, ref);
    z.zp_dark = max_z(scaled(primal, 0.95), ref);
    return z;
}
/// The gradient tests' bounds on gradient_z: |z| < 5 for the gradients' tests, 4.5 for the primal's.
inline void check_unbiased_gradients(const GradientZ& z) {
    CAPTURE(z.zx, z.zy, z.z_neg, z.zp, z.zp_dark);
    CHECK(z.zx < 5.0);
    CHECK(z.zy < 5.0);
    CHECK(z.z_neg > 5.0);
    CHECK(z.zp < 4.5);
    CHECK(z.zp_dark > 4.5);
}

/// Runs the shift validator for built-in shift `name` on `scene` over `paths`
/// base paths and checks that it passes with more than `min_base_paths` of
/// them scattering; returns the report for further checks.
inline ShiftReport check_validated_shift(const Scene& scene, const char* name, long long min_base_paths = 1000,
                                         int paths = 3000) {
    ValidateOptions opt;
    opt.paths = paths;
    const auto shift = shift_registry().create(name, Params());
    const ShiftReport rep = validate_shift(scene, *shift, ShiftConfig{}, opt);
    INFO(name << "\n" << rep.summary());
    CHECK(rep.passed);
    CHECK(rep.base_paths > min_base_paths);
    return rep;
}

}  // namespace gdr::test
