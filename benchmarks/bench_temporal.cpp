// Temporal gradient-domain rendering, two parts.
//
// Videos (default): the bundled animations (a camera swinging through the
// Cornell box, the cow walking in it) rendered at equal render time per
// frame by PT, per-frame gpt with its L1 and weighted reconstructions, and
// tgpt with the spatio-temporal L1 and L2 reconstructions; per-frame relMSE
// (mean over frames) and the flicker error (relMSE of frame-to-frame
// differences, metrics.h) against a high-spp PT reference video, cached.
// Reconstruction time is printed separately from the render budget.
//
//   bench_temporal [--time T] [--frames F] [--first K] [--width W] [--ref-spp N]
//                  [--cache DIR] [--scenes camera,object] [--strip FILE.png] [--set key=value]...
//                  [--adaptive SHARE]
//                  [--quick]
//
// --set passes an option to the spatio-temporal solve (gdr reconstruct
// --frames --set: w_t, alpha, window, ...); norm is set per row.
//
// --adaptive SHARE adds rows sampled adaptively by gradient variance
// (render_adaptive, a pilot of SHARE of each frame's time): gpt + L1, tgpt
// per-frame L1 and tgpt + temporal L1 / L2.
//
// --strip FILE.png writes FILE-camera.png and FILE-object.png: the first,
// middle and last frame (columns) of PT, gpt + L1, tgpt + temporal L1 and
// the reference (rows).
//
// Solver (--solver): time, CG iterations and, for L1, the energy gap to a
// converged IRLS of one window of a synthetic noisy video, per solver and
// preconditioner (gdr/reconstruct/temporal.h).
//
//   bench_temporal --solver [--width W] [--height H] [--frames F]
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "gdr/integrators/adaptive.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"
#include "gdr/io/scene_file.h"
#include "gdr/metrics.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/reconstruct/temporal.h"
#include "gdr/scene/animated_scene.h"

using namespace gdr;

namespace {

/// A translating, brightening smooth video with edges; motion (mx, 0) px per frame.
std::vector<TemporalFrame> video(int w, int h, int F, int mx, uint32_t seed) {
    auto value = [&](int f, int x, int y, int c) {
        const float u = float(x - f * mx), v = float(y);
        const float edge = (int(std::floor(u / 37.f)) + int(std::floor(v / 29.f))) % 2 == 0 ? 0.4f : 0.f;
        return (1.f + 0.03f * f) * (0.5f + 0.3f * std::sin(0.05f * u + 0.07f * v + c) + edge);
    };
    std::mt19937 rng(seed);
    std::normal_distribution<float> n(0.f, 1.f);
    std::vector<TemporalFrame> frames(F);
    for (int f = 0; f < F; ++f) {
        TemporalFrame& fr = frames[f];
        fr.name = "frame " + std::to_string(f);
        fr.primal = Image(w, h, 3), fr.dx = Image(w, h, 3), fr.dy = Image(w, h, 3);
        if (f + 1 < F) fr.dt = Image(w, h, 3), fr.motion = Image(w, h, 2);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int c = 0; c < 3; ++c) {
                    const float v = value(f, x, y, c);
                    fr.primal.at(x, y, c) = v + 0.3f * n(rng);
                    fr.dx.at(x, y, c) = (x + 1 < w ? value(f, x + 1, y, c) - v : 0.f) + 0.05f * n(rng);
                    fr.dy.at(x, y, c) = (y + 1 < h ? value(f, x, y + 1, c) - v : 0.f) + 0.05f * n(rng);
                    if (f + 1 < F) {
                        fr.dt.at(x, y, c) = value(f + 1, x + mx, y, c) - v + 0.05f * n(rng);
                        fr.motion.at(x, y, 0) = float(mx);
                    }
                }
    }
    return frames;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct VideoOptions {
    double time = 1.0;      // render seconds per frame, every method
    int frames = 12;        // frames per video
    int first = 12;         // first frame
    int width = 128;        // square frames
    long long ref_spp = 1024;
    std::string cache = "temporal-reference-cache";
    std::vector<std::string> scenes{"camera", "object"};
    std::vector<std::string> temporal_sets;  // --set key=value: options of the spatio-temporal solve
    std::string strip;  // if set: a PNG per scene of three frames by method (rows) and the reference
    double adaptive = 0.0;  // > 0: also rows of adaptively sampled gpt and tgpt with this pilot share
};

// A montage: rows of images (all one shape), 2 pixels of black between them.
Image montage(const std::vector<std::vector<const Image*>>& rows) {
    const int w = rows[0][0]->width(), h = rows[0][0]->height(), gap = 2;
    const int cols = int(rows[0].size());
    Image out(cols * (w + gap) - gap, int(rows.size()) * (h + gap) - gap, 3);
    for (size_t r = 0; r < rows.size(); ++r)
        for (int c = 0; c < cols; ++c)
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    out.set_rgb(c * (w + gap) + x, int(r) * (h + gap) + y, rows[r][size_t(c)]->rgb(x, y));
    return out;
}

// Frame `k` of scene file `path` at the benchmark's resolution.
SceneFile frame_scene(const std::string& path, int k, int width) {
    SceneFile sf = load_scene_file(path);
    set_resolution(sf, width, width);
    set_frame(sf, k);
    return sf;
}

// One frame by `integrator` as `gdr render --frames` renders it: the frame's
// seed (and, for tgpt, the next frame's and the replay map), its motion layers.
// Returns the frame and the render's seconds.
// With `adaptive` > 0 the frame is sampled adaptively (render_adaptive) with that pilot share.
std::pair<FrameBuffer, double> render_frame(const std::string& path, int k, int width, const std::string& integrator,
                                            const Params& params, double time, long long spp, uint64_t base_seed,
                                            double adaptive = 0.0) {
    SceneFile sf = frame_scene(path, k, width);
    auto integ = integrator_registry().create(integrator, params);
    RenderSettings st;
    st.seed = frame_seed(base_seed, k);
    if (time > 0.0) st.time_budget = time;
    else st.spp = spp;
    FrameSampling fs;
    if (integ->shares_frame_samples()) {
        fs.next_seed = frame_seed(base_seed, k + 1);
        fs.replay = replay_map(*sf.animation, *sf.scene, k);
        st.frame_sampling = &fs;
    }
    FrameBuffer fb;
    AdaptiveRender ad;
    ad.pilot = adaptive;
    const RenderStats rs =
        adaptive > 0.0 ? render_adaptive(*integ, *sf.scene, st, fb, ad) : integ->render(*sf.scene, st, fb);
    add_motion_layers(fb, *sf.animation, *sf.scene, k);
    return {std::move(fb), rs.seconds};
}

// The cached PT reference of frame k (rendered and cached when missing).
Image reference_frame(const VideoOptions& o, const std::string& scene, const std::string& path, int k) {
    namespace fs = std::filesystem;
    fs::create_directories(o.cache);
    const std::string file =
        (fs::path(o.cache) / fmt::format("{}-{}px-{}spp-{:04d}.exr", scene, o.width, o.ref_spp, k)).string();
    if (fs::exists(file)) {
        try {
            return read_exr(file).get("color");
        } catch (const std::exception& e) {
            std::printf("  cached reference %s unreadable (%s); re-rendering\n", file.c_str(), e.what());
        }
    }
    const auto t0 = std::chrono::steady_clock::now();
    FrameBuffer fb = render_frame(path, k, o.width, "pt", Params("reference"), 0.0, o.ref_spp, 0x5eed).first;
    // Written under a temporary name and renamed: an interrupted run leaves no damaged entry.
    write_exr(file + ".part.exr", fb);
    fs::rename(file + ".part.exr", file);
    std::printf("  reference frame %d: %lld spp in %.1f s\n", k, o.ref_spp, seconds_since(t0));
    std::fflush(stdout);
    return fb.get("color");
}

struct Row {
    std::string method;
    std::vector<Image> frames;
    double render_s = 0, reconstruct_s = 0;  // per frame
};

void print_row(const std::string& scene, const Row& r, const std::vector<Image>& refs, double pt_flicker) {
    double rel = 0;
    for (size_t i = 0; i < refs.size(); ++i) rel += relmse(r.frames[i], refs[i]);
    rel /= double(refs.size());
    const double flicker = temporal_relmse(r.frames, refs);
    std::printf("%-7s %-27s relMSE %.5f  flicker %.5f (%.2fx PT's)  render %.2f s  reconstruct %.3f s per frame\n",
                scene.c_str(), r.method.c_str(), rel, flicker, pt_flicker > 0 ? pt_flicker / flicker : 1.0,
                r.render_s, r.reconstruct_s);
    std::fflush(stdout);
}

int run_videos(const VideoOptions& o) {
    const std::string dir = std::string(GDR_SOURCE_DIR) + "/scenes/cornell-box/";
    std::printf("equal render time per frame: %.2f s, frames %d..%d, %dx%d, reference PT %lld spp\n", o.time,
                o.first, o.first + o.frames - 1, o.width, o.width, o.ref_spp);
    for (const std::string& scene : o.scenes) {
        const std::string path = dir + (scene == "camera" ? "animation.json" : "moving-object.json");
        std::vector<Image> refs;
        for (int k = o.first; k < o.first + o.frames; ++k) refs.push_back(reference_frame(o, scene, path, k));
        // Frames by `integrator` (rendered without reconstructions), then each
        // of `methods` ({row name, reconstructor; "" = the "color" layer}) timed
        // on its own.
        const auto per_frame = [&](const std::string& integrator,
                                   const std::vector<std::pair<std::string, std::string>>& methods,
                                   double adaptive = 0.0) {
            std::vector<Row> rows(methods.size());
            for (size_t m = 0; m < methods.size(); ++m) rows[m].method = methods[m].first;
            std::vector<FrameBuffer> fbs;
            Params p(integrator);
            if (integrator != "pt") p.set("reconstruct", "none");
            for (int k = o.first; k < o.first + o.frames; ++k) {
                auto [fb, render_s] = render_frame(path, k, o.width, integrator, p, o.time, 0, 1, adaptive);
                for (size_t m = 0; m < methods.size(); ++m) {
                    rows[m].render_s += render_s / o.frames;
                    if (methods[m].second.empty()) {
                        rows[m].frames.push_back(fb.get("color"));
                        continue;
                    }
                    const auto t0 = std::chrono::steady_clock::now();
                    Params rp(methods[m].second);
                    rows[m].frames.push_back(reconstruct(methods[m].second, rp, gradient_buffers(fb)));
                    rows[m].reconstruct_s += seconds_since(t0) / o.frames;
                }
                fbs.push_back(std::move(fb));
            }
            return std::pair{rows, std::move(fbs)};
        };
        std::vector<Row> shown;  // the rows of the strip
        auto [pt, pt_fbs] = per_frame("pt", {{"PT", ""}});
        shown.push_back(pt[0]);
        const double pt_flicker = temporal_relmse(pt[0].frames, refs);
        print_row(scene, pt[0], refs, pt_flicker);
        auto [gpt, gpt_fbs] = per_frame("gpt", {{"gpt + L1", "poisson-l1"}, {"gpt + weighted", "poisson-weighted"}});
        for (const Row& r : gpt) print_row(scene, r, refs, pt_flicker);
        shown.push_back(gpt[0]);
        auto [tgpt, tgpt_fbs] = per_frame("tgpt", {{"tgpt per-frame L1", "poisson-l1"}});
        print_row(scene, tgpt[0], refs, pt_flicker);
        // The spatio-temporal solves of a tgpt video, one row per norm.
        const auto temporal_rows = [&](const std::string& label, const Row& frames_row,
                                       const std::vector<FrameBuffer>& fbs) {
            std::vector<Row> out;
            for (TemporalNorm norm : {TemporalNorm::l1, TemporalNorm::l2}) {
                Params tp("bench_temporal --set");
                for (const std::string& kv : o.temporal_sets) tp.set_from_text(kv);
                TemporalOptions to = temporal_options(tp);
                to.norm = norm;
                Row r;
                r.method = label + (norm == TemporalNorm::l1 ? " + temporal L1" : " + temporal L2");
                r.render_s = frames_row.render_s;
                const auto t0 = std::chrono::steady_clock::now();
                TemporalReconstructor rec(to);
                for (size_t i = 0; i < fbs.size(); ++i) {
                    FrameBuffer fb = fbs[i];
                    if (i + 1 < fbs.size()) add_temporal_difference(fb, fbs[i + 1], "frame", "next frame");
                    rec.push(temporal_frame(fb, "frame " + std::to_string(o.first + int(i))));
                    while (rec.ready()) r.frames.push_back(rec.pop());
                }
                rec.finish();
                while (rec.ready()) r.frames.push_back(rec.pop());
                r.reconstruct_s = seconds_since(t0) / o.frames;
                print_row(scene, r, refs, pt_flicker);
                out.push_back(std::move(r));
            }
            return out;
        };
        shown.push_back(temporal_rows("tgpt", tgpt[0], tgpt_fbs)[0]);
        if (o.adaptive > 0.0) {
            // Adaptive sampling by gradient variance (each frame its own pilot).
            auto [agpt, agpt_fbs] = per_frame("gpt", {{"gpt adaptive + L1", "poisson-l1"}}, o.adaptive);
            print_row(scene, agpt[0], refs, pt_flicker);
            auto [atgpt, atgpt_fbs] = per_frame("tgpt", {{"tgpt adaptive per-frame L1", "poisson-l1"}}, o.adaptive);
            print_row(scene, atgpt[0], refs, pt_flicker);
            temporal_rows("tgpt adaptive", atgpt[0], atgpt_fbs);
        }
        if (!o.strip.empty()) {
            // Rows: PT, gpt + L1, tgpt + temporal L1, the reference; columns: first, middle, last frame.
            const size_t cols[3] = {0, refs.size() / 2, refs.size() - 1};
            std::vector<std::vector<const Image*>> rows;
            for (const Row& r : shown) rows.push_back({&r.frames[cols[0]], &r.frames[cols[1]], &r.frames[cols[2]]});
            rows.push_back({&refs[cols[0]], &refs[cols[1]], &refs[cols[2]]});
            const std::string path = o.strip.substr(0, o.strip.rfind('.')) + "-" + scene + ".png";
            write_png_preview(path, montage(rows));
            std::printf("wrote %s (rows: PT, gpt + L1, tgpt + temporal L1, reference; frames %d, %d, %d)\n",
                        path.c_str(), o.first + int(cols[0]), o.first + int(cols[1]), o.first + int(cols[2]));
        }
    }
    return 0;
}


int run_solver(int w, int h, int F) {
    fmt::print("window of {} frames of {}x{}x3\n", F, w, h);
    auto run = [&](const std::vector<TemporalFrame>& frames, const TemporalOptions& o, std::vector<Image>& out) {
        std::vector<TemporalFrameView> v;
        std::vector<float*> p;
        out.clear();
        for (const auto& f : frames) v.push_back(f.view()), out.emplace_back(w, h, 3);
        for (auto& img : out) p.push_back(img.data());
        const auto t0 = std::chrono::steady_clock::now();
        const TemporalReport r = solve_temporal_window(v, o, p);
        return std::pair{r, seconds_since(t0)};
    };
    std::vector<Image> out;
    for (int mx : {0, 1}) {
        const auto frames = video(w, h, F, mx, 1);
        TemporalOptions l2;
        l2.norm = TemporalNorm::l2;
        for (auto [name, solver, pre] :
             {std::tuple{"auto", TemporalSolver::automatic, TemporalPreconditioner::dct},
              std::tuple{"cg+dct", TemporalSolver::cg, TemporalPreconditioner::dct},
              std::tuple{"cg+multigrid", TemporalSolver::cg, TemporalPreconditioner::frame_multigrid}}) {
            l2.solver = solver, l2.l2_preconditioner = pre;
            const auto [r, s] = run(frames, l2, out);
            fmt::print("L2 motion {} {:<13} {:6.3f} s  direct {}  CG {:3d}  residual {:.1e}\n", mx, name, s,
                       r.direct_solve, r.cg_iterations, r.relative_residual);
        }
        TemporalOptions conv;
        conv.irls_cg_iterations = 100, conv.irls_tolerance = 1e-6, conv.irls_iterations = 20;
        const double ref = run(frames, conv, out).first.energy;
        for (auto pre : {TemporalPreconditioner::frame_multigrid, TemporalPreconditioner::dct})
            for (int cg : {1, 2, 4, 8}) {
                TemporalOptions l1;
                l1.irls_cg_iterations = cg, l1.irls_preconditioner = pre;
                const auto [r, s] = run(frames, l1, out);
                fmt::print("L1 motion {} {:<10} x{}  {:6.3f} s  CG {:4d}  energy gap {:.3f}%\n", mx,
                           pre == TemporalPreconditioner::dct ? "dct" : "multigrid", cg, s, r.irls_cg_iterations,
                           100.0 * (r.energy - ref) / ref);
            }
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    bool solver = false;
    int w = 320, h = 180, F = 10;
    VideoOptions vo;
    std::vector<std::string> args(argv + 1, argv + argc);
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& a = args[i];
        const auto next = [&]() -> const std::string& {
            if (i + 1 >= args.size()) {
                std::fprintf(stderr, "bench_temporal: %s needs a value\n", a.c_str());
                std::exit(2);
            }
            return args[++i];
        };
        if (a == "--solver") solver = true;
        else if (a == "--quick") vo.time = 0.1, vo.frames = 3, vo.width = 24, vo.ref_spp = 32, vo.first = 20;
        else if (a == "--width") w = vo.width = std::stoi(next());
        else if (a == "--height") h = std::stoi(next());
        else if (a == "--frames") F = vo.frames = std::stoi(next());
        else if (a == "--first") vo.first = std::stoi(next());
        else if (a == "--time") vo.time = std::stod(next());
        else if (a == "--ref-spp") vo.ref_spp = std::stoll(next());
        else if (a == "--cache") vo.cache = next();
        else if (a == "--strip") vo.strip = next();
        else if (a == "--set") vo.temporal_sets.push_back(next());
        else if (a == "--adaptive") vo.adaptive = std::stod(next());
        else if (a == "--scenes") {
            vo.scenes.clear();
            std::string list = next();
            for (size_t at = 0; at <= list.size();) {
                const size_t comma = std::min(list.find(',', at), list.size());
                vo.scenes.push_back(list.substr(at, comma - at));
                at = comma + 1;
            }
        } else {
            std::fprintf(stderr, "bench_temporal: unknown option %s\n", a.c_str());
            return 2;
        }
    }
    for (const std::string& sc : vo.scenes)
        if (sc != "camera" && sc != "object") {
            std::fprintf(stderr, "bench_temporal: unknown scene '%s' (camera, object)\n", sc.c_str());
            return 2;
        }
    if (vo.frames < 2) {
        std::fprintf(stderr, "bench_temporal: --frames must be at least 2 (flicker needs frame pairs)\n");
        return 2;
    }
    return solver ? run_solver(w, h, F) : run_videos(vo);
}
