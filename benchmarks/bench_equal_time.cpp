// Equal-time comparison of PT, G-PT + L1, G-PT + L2, G-PT + variance-weighted
// Poisson (L2 and L1 forms), G-PT + neural (where its plugin is built), BDPT
// and G-BDPT + L1 / L2 on real scenes.
//
// For each scene: a cached high-spp reference (PT; BDPT on veach-bidir), then for every time budget
// of a geometric series one PT, one G-PT and one BDPT render (interleaved, so
// load changes on a shared machine hit all alike). G-PT's time is render +
// reconstruction wall time: its render budget is shortened by the L1 solve
// time measured once beforehand, and each method is placed at its measured
// total time. Error: relMSE with the thesis convention (per channel,
// eps = 0.01). Writes results.csv, summary.md, a log-log convergence plot
// and a crops image per scene, and prints the time each G-PT variant needs
// to reach PT's relMSE at the largest budget (and, with the neural rows, the
// time G-PT + neural needs to reach the primal-only network's relMSE at 4 s).
//
// Equal time charges everything: a G-PT + L1/L2 point's time includes its
// reconstruction, so a slow solve costs G-PT samples, as it would a user.
//
// Usage: bench_equal_time [--quick] [--references-only] [--refresh-references]
//          [--scenes a,b] [--scene [NAME=]PATH.json]... [--width W] [--budgets s1,s2,..]
//          [--ref-spp N] [--set key=value]... [--l1-set key=value]...
//          [--weighted NAME:key=value,...]... [--no-bdpt] [--no-gbdpt]
//          [--no-neural] [--neural-set key=value]... [--neural-primal-set key=value]...
//          [--out DIR] [--cache DIR] [--docs DIR] [--threads N]
//
//   --scenes a,b      built-in scenes by name (see --help); all six by default
//   --scene PATH      any scene file (repeatable), named by its file stem in the
//                     output, or NAME=PATH to name it; reference PT at 1024 spp
//                     unless --ref-spp is given. Without --scenes, only these run.
//   --set key=value   a parameter of the gpt integrator (repeatable; e.g. shift,
//                     max_depth, alpha). The render is made with reconstruct=none
//                     because the benchmark runs and times each solve itself, so
//                     'reconstruct' is refused; 'alpha' is used by both solves.
//   --l1-set key=value  a parameter of the poisson-l1 solve: its schedule, e.g.
//                     preset=reference (the slow L1D of the authors' public Mitsuba G-PT)
//                     or iterations, cg_iterations, tolerance (repeatable). The gpt
//                     integrator itself has no parameter for the L1 schedule.
//   --weighted NAME:k=v,...  a row "gpt-NAME" reconstructed by poisson-weighted with
//                     these parameters (repeatable); replaces the default rows
//                     gpt-w1 (poisson-weighted's defaults: L1) and gpt-w2 (norm=l2).
//   --no-neural       leaves the row gpt-neural out. It is there only where the
//                     neural reconstructor's plugin is built (gdr/plugin.h):
//                     the G-PT render of the other rows reconstructed by the U-Net,
//                     placed at render + inference time.
//   --neural-set key=value  a parameter of the neural reconstructor (weights, threads).
//                     With the plugin there is a second row, pt-neural-primal: the
//                     primal-only network on a render of primal-only samples (gpt
//                     with every pixel's gradients masked: PT's cost, gpt's layers)
//                     at budget minus inference time; what the gradients add at
//                     equal time, against a conventional learned denoiser.
//   --neural-primal-set key=value  a parameter of that row's network (default
//                     weights: the committed primal-only twin of the shipped model).
//   --no-bdpt         leaves BDPT out (a third of the run time).
//   --no-gbdpt        leaves G-BDPT out (it is timed as G-PT: render + solve).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "gdr/core/args.h"
#include "gdr/plugin.h"
#include "gdr/eval/equal_time.h"
#include "gdr/eval/plot.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/metrics.h"
#include "gdr/reconstruct/reconstructor.h"
#include "run_stats.h"

using namespace gdr;
using namespace gdr::eval;
using gdr::bench::split;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct SceneSpec {
    std::string name, path;
    long long ref_spp;  // full-mode reference samples per pixel: fewer where PT is slow (see README note)
    // The reference's integrator: bdpt where PT's own reference noise would
    // be as large as the errors measured (veach-bidir's lamp: a 1024-spp PT
    // reference there has an estimated relMSE of 0.026 of its own).
    std::string ref_integrator = "pt";
};

const std::vector<SceneSpec> kAllScenes = {
    {"cbox-original", GDR_SOURCE_DIR "/scenes/cornell-box/scene.json", 2048},
    {"cbox-glossy", GDR_SOURCE_DIR "/scenes/cornell-box/glossy.json", 2048},
    {"cbox-sphere", GDR_SOURCE_DIR "/scenes/cornell-box/sphere.json", 2048},
    {"veach-mis", GDR_SOURCE_DIR "/scenes/veach-mis/scene.json", 2048},
    {"veach-bidir", GDR_SOURCE_DIR "/scenes/veach-bidir/scene.json", 1024, "bdpt"},
    {"bathroom", GDR_SOURCE_DIR "/scenes/bathroom/scene.json", 512},
};

// A scene file's cost is unknown: 1024 spp is the middle of the built-ins' range.
constexpr long long kCustomSceneRefSpp = 1024;

struct Options {
    bool quick = false, references_only = false, refresh = false;
    std::vector<SceneSpec> scenes;  // in the order given
    std::vector<std::string> gpt_sets, l1_sets;  // "key=value" texts, in the order given
    std::vector<std::pair<std::string, std::string>> weighted;  // (row name, "k=v,k=v") of poisson-weighted rows
    bool bdpt = true, gbdpt = true, neural = true;
    std::vector<std::string> neural_sets;  // "key=value" texts of the neural reconstructor
    std::vector<std::string> neural_primal_sets;  // the same for the primal-only network's row
    // 192 px and 8 s keep the full run, references included, near 20 minutes on 2 cores.
    int width = 192;
    std::vector<double> budgets{0.25, 0.5, 1, 2, 4, 8};
    long long ref_spp = 0;  // 0: each scene's own default
    std::string out = "equal-time", cache = default_reference_cache(), docs;
    int threads = 0;
};

const SceneSpec& builtin_scene(const std::string& name) {
    auto it = std::find_if(kAllScenes.begin(), kAllScenes.end(), [&](const SceneSpec& s) { return s.name == name; });
    if (it == kAllScenes.end()) {
        std::string names;
        for (const SceneSpec& s : kAllScenes) names += " " + s.name;
        throw ParameterError("--scenes: unknown scene '" + name + "' (built-in:" + names + "; any file: --scene PATH.json)");
    }
    return *it;
}

// "--scene PATH.json" or "--scene NAME=PATH.json". A '=' after a '/' belongs to the path.
SceneSpec scene_option(const std::string& v) {
    const size_t eq = v.find('=');
    SceneSpec s;
    if (eq != std::string::npos && v.find('/') > eq) s.name = v.substr(0, eq), s.path = v.substr(eq + 1);
    else s.path = v, s.name = fs::path(v).stem().string();
    if (s.name.empty() || s.path.empty())
        throw ParameterError("--scene '" + v + "': expected PATH.json or NAME=PATH.json");
    // The name becomes part of output and cache file names.
    if (s.name.find_first_of("/\\") != std::string::npos || s.name == "." || s.name == "..")
        throw ParameterError("--scene '" + v + "': the name '" + s.name + "' cannot be part of a file name");
    // Checked now, so that a typing error is found before the other scenes' references are rendered.
    std::error_code ec;
    if (!fs::is_regular_file(s.path, ec)) throw InputError("--scene '" + v + "': no scene file " + s.path);
    s.ref_spp = kCustomSceneRefSpp;
    return s;
}

Options parse(int argc, char** argv) {
    Options o;
    bool width_set = false, budgets_set = false, spp_set = false;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) throw ParameterError(a + " needs a value");
            return argv[++i];
        };
        if (a == "--quick") o.quick = true;
        else if (a == "--references-only") o.references_only = true;
        else if (a == "--refresh-references") o.refresh = true;
        else if (a == "--scenes") {
            for (const std::string& n : split(next())) o.scenes.push_back(builtin_scene(n));
        } else if (a == "--scene") o.scenes.push_back(scene_option(next()));
        else if (a == "--set") o.gpt_sets.push_back(next());
        else if (a == "--l1-set") o.l1_sets.push_back(next());
        else if (a == "--weighted") {
            const std::string v = next();
            const size_t colon = v.find(':');
            const std::string name = v.substr(0, colon);
            if (name.empty() || name.find_first_of(",/\\ ") != std::string::npos)
                throw ParameterError("--weighted '" + v + "': expected NAME:key=value,... with a plain NAME");
            o.weighted.push_back({"gpt-" + name, colon == std::string::npos ? "" : v.substr(colon + 1)});
        } else if (a == "--no-neural") o.neural = false;
        else if (a == "--neural-set") o.neural_sets.push_back(next());
        else if (a == "--neural-primal-set") o.neural_primal_sets.push_back(next());
        else if (a == "--no-bdpt") o.bdpt = false;
        else if (a == "--no-gbdpt") o.gbdpt = false;
        else if (a == "--width") o.width = int(ArgReader::parse_int(a, next(), 1, 65536)), width_set = true;
        else if (a == "--budgets") {
            o.budgets.clear();
            for (const std::string& b : split(next())) o.budgets.push_back(ArgReader::parse_real(a, b));
            budgets_set = true;
        } else if (a == "--ref-spp") o.ref_spp = ArgReader::parse_int(a, next(), 1, 1LL << 32), spp_set = true;
        else if (a == "--out") o.out = next();
        else if (a == "--cache") o.cache = next();
        else if (a == "--docs") o.docs = next();
        else if (a == "--threads") o.threads = int(ArgReader::parse_int(a, next(), 0, 1 << 16));
        else if (a == "-h" || a == "--help") {
            std::printf("usage: bench_equal_time [--quick] [--references-only] [--refresh-references] [--scenes a,b]\n"
                        "         [--scene [NAME=]PATH.json]... [--width W] [--budgets s1,s2,..] [--ref-spp N]\n"
                        "         [--set key=value]... [--l1-set key=value]... [--out DIR] [--cache DIR] [--docs DIR]\n"
                        "         [--threads N]\n"
                        "  --scene       any scene file (repeatable), named by its stem or NAME=\n"
                        "  --set         a gpt integrator parameter (not 'reconstruct': the benchmark times the solves)\n"
                        "  --l1-set      a poisson-l1 parameter, e.g. preset=reference, iterations=N\n"
                        "  --weighted    NAME:k=v,... a poisson-weighted row gpt-NAME (default rows w1: its defaults, w2: norm=l2)\n"
                        "  --no-neural   leave G-PT + neural out (it runs where its plugin is built)\n"
                        "  --neural-set  a neural reconstructor parameter: weights=W.pt, threads=N\n"
                        "  --neural-primal-set  the same for the primal-only network of row pt-neural-primal\n"
                        "  --no-bdpt     leave BDPT out\n"
                        "  --no-gbdpt    leave G-BDPT out\n"
                        "G-PT times include the reconstruction: equal time charges everything.\n"
                        "built-in scenes:");
            for (const SceneSpec& s : kAllScenes) std::printf(" %s", s.name.c_str());
            std::printf("\n");
            std::exit(0);
        } else
            throw ParameterError("unknown argument " + a);
    }
    // Quick mode (CI): tiny images, three short budgets, two scenes, cheap references.
    if (o.quick) {
        if (!width_set) o.width = 96;
        if (!budgets_set) o.budgets = {0.25, 0.5, 1};
        if (!spp_set) o.ref_spp = 1024;
        if (o.scenes.empty()) o.scenes = {builtin_scene("cbox-original"), builtin_scene("cbox-glossy")};
    }
    if (o.scenes.empty()) o.scenes = kAllScenes;
    if (o.weighted.empty()) o.weighted = {{"gpt-w1", ""}, {"gpt-w2", "norm=l2"}};
    // Two scenes of one name would write over each other's outputs.
    for (size_t i = 0; i < o.scenes.size(); ++i)
        for (size_t j = 0; j < i; ++j)
            if (o.scenes[i].name == o.scenes[j].name)
                throw ParameterError("scene name '" + o.scenes[i].name + "' is given twice (" + o.scenes[j].path +
                                     ", " + o.scenes[i].path + "); name one with --scene NAME=PATH.json");
    std::sort(o.budgets.begin(), o.budgets.end());
    if (o.budgets.empty() || o.budgets.front() <= 0) throw ParameterError("--budgets must be positive seconds");
    return o;
}

// Cache key: the scene file's bytes and the loaded geometry (so an edited OBJ
// also misses), plus the resolution and sample count in the name.
uint64_t scene_key(const std::string& path, const Scene& scene) {
    uint64_t h = hash_file(path);
    auto mix = [&](const void* p, size_t n) {
        const unsigned char* b = static_cast<const unsigned char*>(p);
        for (size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
    };
    const TriangleMesh& m = scene.mesh();
    mix(m.positions.data(), m.positions.size() * sizeof(Vec3));
    mix(m.material_ids.data(), m.material_ids.size() * sizeof(uint32_t));
    for (const Material& mat : scene.materials()) mix(mat.name.data(), mat.name.size()), mix(&mat.emission, sizeof(Color));
    return h;
}

// The reference's own relMSE expected from its noise: mean of Var[mean]/(r^2 + eps).
double reference_self_relmse(const FrameBuffer& ref, double eps) {
    const Image& c = ref.get("color");
    const Image& v = ref.get("variance");
    const double spp = std::stod(ref.metadata().at("spp"));
    double s = 0;
    for (int y = 0; y < c.height(); ++y)
        for (int x = 0; x < c.width(); ++x)
            for (int ch = 0; ch < 3; ++ch) {
                const double r = c.at(x, y, ch);
                s += double(v.at(x, y, ch)) / spp / (r * r + eps);
            }
    return s / (3.0 * double(c.pixel_count()));
}

FrameBuffer get_reference(const Options& o, const SceneSpec& spec, const Scene& scene, std::string& file_out) {
    const long long ref_spp = o.ref_spp > 0 ? o.ref_spp : spec.ref_spp;
    char name[256];
    const std::string tag = spec.ref_integrator == "pt" ? "" : "-" + spec.ref_integrator;
    std::snprintf(name, sizeof name, "%s-%dx%d-spp%lld%s-%016llx.exr", spec.name.c_str(), scene.camera().width(),
                  scene.camera().height(), ref_spp, tag.c_str(), (unsigned long long)scene_key(spec.path, scene));
    const std::string file = (fs::path(o.cache) / name).string();
    file_out = file;
    if (!o.refresh && fs::exists(file)) {
        // A damaged cache entry (an interrupted copy, a full disk) is rendered
        // again rather than ending the benchmark.
        try {
            FrameBuffer fb = read_exr(file);
            if (fb.has("color") && fb.has("variance") && fb.metadata().count("spp")) return fb;
            std::printf("  cached reference %s is incomplete; re-rendering\n", file.c_str());
        } catch (const InputError& e) {
            std::printf("  cached reference unreadable (%s); re-rendering\n", e.what());
        }
    }
    std::printf("  rendering reference %s (%s, %lld spp) ...\n", file.c_str(), spec.ref_integrator.c_str(), ref_spp);
    std::fflush(stdout);
    auto pt = integrator_registry().create(spec.ref_integrator, Params());
    RenderSettings st;
    st.spp = ref_spp;
    st.seed = 0x5eed5eedull;  // never one of the benchmark's seeds
    st.threads = o.threads;
    FrameBuffer fb;
    int last = -1;
    const RenderStats rs = pt->render(scene, st, fb, [&](const Progress& p) {
        const int pct = int(p.fraction * 10) * 10;
        if (pct != last) {  // the callback may run on any thread: a torn print is harmless
            last = pct;
            std::printf("    %3d%% (%.0f s)\n", pct, p.seconds);
            std::fflush(stdout);
        }
    });
    fb.metadata()["spp"] = std::to_string(rs.spp);
    fb.metadata()["scene"] = spec.path;
    fb.metadata()["reference_seconds"] = std::to_string(rs.seconds);
    fb.metadata()["reference_integrator"] = spec.ref_integrator;
    fs::create_directories(o.cache);
    // Only the layers the benchmark reads: keeps the cache small.
    FrameBuffer keep(fb.width(), fb.height());
    keep.set("color", fb.get("color"));
    keep.set("variance", fb.get("variance"));
    keep.metadata() = fb.metadata();
    write_exr(file, keep);  // through a temporary: a reader never sees half a file
    std::printf("  reference done in %.1f s\n", rs.seconds);
    return keep;
}

struct Row {
    std::string scene, method;
    int width = 0, height = 0;
    double budget = 0, seconds = 0, render_s = 0, solve_s = 0;
    long long spp = 0;
    double relmse = 0, mse = 0, ssim = 0;
    double mean_dev = 0;  // image mean / reference mean - 1, the worst channel
};

struct Equal {
    Image pt, l1, l2;  // images at the crops budget
    double e_pt = 0, e_l1 = 0, e_l2 = 0, budget = 0;
};

// The primal-only network of row pt-neural-primal, unless --neural-primal-set weights= says otherwise:
// the committed twin of the shipped model (same data and training, no gradient inputs).
const char* const kPrimalModel = GDR_SOURCE_DIR "/neural/models/unet-v4-primal.pt";

// The fixed methods; the poisson-weighted rows (--weighted) follow them.
constexpr int kNumFixed = 7;
const char* const kFixedMethods[kNumFixed] = {"pt", "gpt-l1", "gpt-l2", "gpt-primal", "bdpt", "gbdpt-l1", "gbdpt-l2"};
const Rgb8 kFixedColors[kNumFixed] = {{30, 30, 30},   {215, 48, 39}, {44, 123, 182}, {120, 170, 90},
                                      {150, 80, 170}, {240, 90, 190}, {100, 60, 30}};
const char* const kFixedLabels[kNumFixed] = {"PT",   "G-PT + L1",     "G-PT + L2",    "G-PT primal (no solve)",
                                             "BDPT", "G-BDPT + L1", "G-BDPT + L2"};
const Rgb8 kWeightedColors[] = {{230, 145, 30}, {0, 150, 150}, {200, 60, 150}, {110, 110, 0}, {90, 90, 220}, {160, 100, 40}};

// The parameters of a poisson-weighted row: alpha is not one of them (the colour weights come from the variances).
Params make_weighted_params(const std::string& row, const std::string& sets) {
    Params p("bench_equal_time --weighted " + row);
    for (const std::string& kv : split(sets)) p.set_from_text(kv);
    return p;
}

// Per channel mean of img over the mean of ref, minus 1, the channel farthest from 0 (unitless).
double mean_deviation(const Image& img, const Image& ref) {
    double worst = 0;
    for (int c = 0; c < 3; ++c) {
        double a = 0, b = 0;
        for (int y = 0; y < ref.height(); ++y)
            for (int x = 0; x < ref.width(); ++x) a += img.at(x, y, c), b += ref.at(x, y, c);
        const double d = b > 0 ? a / b - 1.0 : 0.0;
        if (std::abs(d) > std::abs(worst)) worst = d;
    }
    return worst;
}

// The crop window (size s, stride s/4) where PT's relative squared error is largest:
// where the methods differ most visibly.
void worst_window(const Image& img, const Image& ref, int s, int& bx, int& by) {
    double best = -1;
    bx = by = 0;
    const int stride = std::max(1, s / 4);
    for (int y0 = 0; y0 + s <= img.height(); y0 += stride)
        for (int x0 = 0; x0 + s <= img.width(); x0 += stride) {
            double e = 0;
            for (int y = y0; y < y0 + s; ++y)
                for (int x = x0; x < x0 + s; ++x)
                    for (int c = 0; c < 3; ++c) {
                        const double r = ref.at(x, y, c), d = img.at(x, y, c) - r;
                        e += d * d / (r * r + 0.01);
                    }
            if (e > best) best = e, bx = x0, by = y0;
        }
}

Canvas magnify(const Canvas& c, int x0, int y0, int s, int k) {
    Canvas out(s * k, s * k);
    for (int y = 0; y < s * k; ++y)
        for (int x = 0; x < s * k; ++x) out.set(x, y, c.get(x0 + x / k, y0 + y / k));
    return out;
}

// Columns reference / PT / L1 / L2; row 1 full frames with the crop outlined,
// row 2 the crop magnified. `frames` false leaves out row 1 (small docs images).
Canvas compose_crops(const std::string& title, const Image& ref, const Equal& eq, bool frames, int crop_px) {
    const float scale = auto_exposure(ref);
    const Image* imgs[4] = {&ref, &eq.pt, &eq.l1, &eq.l2};
    char buf[4][96];
    std::snprintf(buf[0], 96, "Reference");
    std::snprintf(buf[1], 96, "PT  relMSE %.3g", eq.e_pt);
    std::snprintf(buf[2], 96, "G-PT+L1  relMSE %.3g", eq.e_l1);
    std::snprintf(buf[3], 96, "G-PT+L2  relMSE %.3g", eq.e_l2);
    const int W = ref.width(), H = ref.height();
    const int s = std::max(8, std::min(W, H) / 4);
    int cx, cy;
    worst_window(eq.pt, ref, s, cx, cy);
    const int k = std::max(1, crop_px / s);
    const int colw = std::max(frames ? W : 0, s * k), gap = 6, head = 40, lab = 16;
    const int rows_h = (frames ? H + gap : 0) + s * k;
    Canvas out(4 * colw + 3 * gap, head + lab + rows_h + 4);
    out.text(4, 4, title, {0, 0, 0});
    for (int i = 0; i < 4; ++i) {
        const int x = i * (colw + gap);
        out.text(x + 2, head - 6, buf[i], {0, 0, 0});
        const Canvas t = tonemap(*imgs[i], scale);
        int y = head + lab - 6;
        if (frames) {
            out.blit(t, x, y);
            const Rgb8 red{255, 40, 40};
            out.line(x + cx, y + cy, x + cx + s, y + cy, red);
            out.line(x + cx, y + cy + s, x + cx + s, y + cy + s, red);
            out.line(x + cx, y + cy, x + cx, y + cy + s, red);
            out.line(x + cx + s, y + cy, x + cx + s, y + cy + s, red);
            y += H + gap;
        }
        out.blit(magnify(t, cx, cy, s, k), x, y);
    }
    return out;
}

// Outside the measured range a speed-up is only bounded: reached already at
// the first point gives ">= t_pt / t_first"; never reached gives "< t_pt / t_last".
// Extrapolating a noisy segment would invent a number.
std::string fmt_speedup(double t_pt, const ReachTime& r, const std::vector<CurvePoint>& curve, double* value = nullptr) {
    char b[64];
    double t_first = curve.front().seconds, t_last = curve.front().seconds;
    for (const CurvePoint& p : curve) t_first = std::min(t_first, p.seconds), t_last = std::max(t_last, p.seconds);
    double v = std::nan("");
    if (r.how == Reach::Interpolated) v = t_pt / r.seconds, std::snprintf(b, sizeof b, "%.2fx", v);
    else if (r.how == Reach::ExtrapolatedBelow) v = t_pt / t_first, std::snprintf(b, sizeof b, ">= %.2fx", v);
    else v = t_pt / t_last, std::snprintf(b, sizeof b, "< %.2fx", v);
    if (value) *value = v;
    return b;
}

// The one line that states what an equal-time point charges (console and summary.md).
constexpr const char* kTimeCharge =
    "Time charges everything: a G-PT+L1/L2 point is placed at its render + reconstruction wall time (the render "
    "budget is the budget minus the L1 solve time measured beforehand, at least a tenth of it); G-PT primal is the render alone.";

// The gpt integrator's parameters: --set, with the in-render solves off because
// the benchmark times the L1 and L2 solves itself.
Params make_gpt_params(const Options& o) {
    Params gp("bench_equal_time --set");
    for (const std::string& s : o.gpt_sets) {
        gp.set_from_text(s);
        if (gp.has("reconstruct"))
            throw ParameterError("--set '" + s + "': the benchmark renders G-PT with reconstruct=none and runs and times "
                                 "each solve itself (choose the L1 schedule with --l1-set)");
    }
    gp.set("reconstruct", std::string("none"));
    return gp;
}

// alpha as gpt would pass it to its own solves (0.2 unless --set alpha=...).
double solve_alpha(const Params& gpt_params) { return gpt_params.get_real("alpha", 0.2); }

Params make_l1_params(const Options& o, const Params& gpt_params) {
    Params rp("bench_equal_time --l1-set");
    rp.set("alpha", solve_alpha(gpt_params));
    for (const std::string& s : o.l1_sets) {
        Params one("--l1-set");
        one.set_from_text(s);
        if (one.has("alpha"))
            throw ParameterError("--l1-set '" + s + "': alpha is shared by both solves; give it with --set");
        rp.set_from_text(s);
    }
    return rp;
}

Params make_l2_params(const Params& gpt_params) {
    Params rp("bench_equal_time");
    rp.set("alpha", solve_alpha(gpt_params));
    return rp;
}

// describe()'s "key=value" lines joined with spaces.
std::string one_line(std::string text) {
    while (!text.empty() && text.back() == '\n') text.pop_back();
    for (char& c : text)
        if (c == '\n') c = ' ';
    return text;
}

}  // namespace

int main(int argc, char** argv) try {
    const Options o = parse(argc, argv);
    fs::create_directories(o.out);
    std::printf("machine: %s\n", gdr::bench::machine_description().c_str());
    std::printf("equal-time benchmark: width %d, budgets", o.width);
    for (double b : o.budgets) std::printf(" %g", b);
    if (o.ref_spp > 0) std::printf(" s, reference PT (BDPT on veach-bidir) %lld spp cached in %s\n", o.ref_spp, o.cache.c_str());
    else std::printf(" s, reference PT (BDPT on veach-bidir; per-scene spp) cached in %s\n", o.cache.c_str());
    std::printf("error: relMSE, thesis convention (per channel, eps = 0.01)\n");
    const Params gpt_params = make_gpt_params(o), l1_params = make_l1_params(o, gpt_params),
                 l2_params = make_l2_params(gpt_params);
    // Created once here so that a misspelt key ends the run before any reference is rendered.
    const std::string gpt_desc = one_line(integrator_registry().create("gpt", gpt_params)->describe());
    const std::string l1_desc = one_line(reconstructor_registry().create("poisson-l1", l1_params)->describe());
    std::string settings = "G-PT: " + gpt_desc + "; L1 solve: " + l1_desc;
    // Method names, labels and colours: the fixed ones, then the weighted rows.
    std::vector<std::string> methods(kFixedMethods, kFixedMethods + kNumFixed), labels(kFixedLabels, kFixedLabels + kNumFixed);
    std::vector<Rgb8> colors(kFixedColors, kFixedColors + kNumFixed);
    std::vector<Params> weighted_params;
    for (size_t i = 0; i < o.weighted.size(); ++i) {
        const auto& [row, sets] = o.weighted[i];
        weighted_params.push_back(make_weighted_params(row, sets));
        const std::string desc = one_line(reconstructor_registry().create("poisson-weighted", weighted_params.back())->describe());
        settings += "; " + row + ": poisson-weighted " + desc;
        methods.push_back(row), labels.push_back("G-PT + weighted " + row.substr(4) + " (" + (sets.empty() ? "defaults" : sets) + ")");
        colors.push_back(kWeightedColors[i % (sizeof kWeightedColors / sizeof kWeightedColors[0])]);
    }
    // G-PT + neural: the same render, reconstructed by the U-Net, where the
    // plugin is built (otherwise the run is what it is without it).
    std::unique_ptr<Reconstructor> neural, neural_primal;
    int neural_m = -1, primal_m = -1;  // their rows
    if (o.neural) {
        // The build tree's plugin, unless GDR_PLUGIN_PATH says otherwise; libtorch's
        // OpenMP threads wait passively, as the gdr tool sets them.
        setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
        const PluginLoad plugin = load_plugins_from(plugin_path_dirs({GDR_PLUGIN_BUILD_DIR}));
        if (reconstructor_registry().has("neural")) {
            // A neural row: its reconstructor from `defaults` then the `sets` texts.
            const auto add_row = [&](const std::string& row, const std::string& label, Rgb8 colour, Params p,
                                     const std::vector<std::string>& sets) {
                for (const std::string& s : sets) p.set_from_text(s);
                auto rec = reconstructor_registry().create("neural", p);
                settings += "; " + row + ": neural " + one_line(rec->describe());
                methods.push_back(row), labels.push_back(label), colors.push_back(colour);
                return rec;
            };
            neural_m = int(methods.size());
            neural = add_row("gpt-neural", "G-PT + neural (U-Net)", {20, 20, 140}, Params("bench_equal_time --neural-set"),
                             o.neural_sets);
            // The primal-only network: its own weights, the gradient network's thread count.
            Params pp("bench_equal_time --neural-primal-set");
            pp.set("weights", std::string(kPrimalModel));
            for (const std::string& s : o.neural_sets)
                if (s.rfind("threads=", 0) == 0) pp.set_from_text(s);
            primal_m = int(methods.size());
            neural_primal = add_row("pt-neural-primal", "primal-only samples + primal-only U-Net", {140, 140, 220}, pp,
                                    o.neural_primal_sets);
        } else {
            std::string why = "its plugin is not built (it needs libtorch)";
            for (const auto& [file, reason] : plugin.skipped) why = file + ": " + reason;
            std::printf("G-PT + neural left out: %s\n", why.c_str());
        }
    }
    const int kNumMethods = int(methods.size());
    std::printf("%s\n%s\n", settings.c_str(), kTimeCharge);
    const auto t_start = Clock::now();
    std::vector<Row> rows;
    std::ostringstream summary;
    summary << kTimeCharge << "\n\n" << settings << "\n\n";
    summary << "| scene | resolution | PT relMSE at " << o.budgets.back()
            << " s | reference relMSE (own noise) | G-PT+L1 speed-up | G-PT+L2 speed-up | G-PT primal speed-up | BDPT speed-up"
               " | G-BDPT+L1 speed-up | G-BDPT+L2 speed-up |";
    for (size_t i = kNumFixed; i < methods.size(); ++i) summary << " " << methods[i] << " speed-up |";
    summary << "\n|---|---|---|---|---|---|---|---|---|---|";
    for (size_t i = kNumFixed; i < methods.size(); ++i) summary << "---|";
    summary << "\n";
    std::vector<std::string> console;
    std::ofstream csv(fs::path(o.out) / "results.csv");
    csv << "scene,width,height,method,budget_s,seconds,render_s,solve_s,spp,relmse,mse,ssim,mean_dev\n";
    // t_method_s: interpolated (or, flagged, extrapolated) time to reach target_relmse.
    std::ofstream speed(fs::path(o.out) / "speedups.csv");
    speed << "scene,method,target_relmse,t_pt_s,t_method_s,how,speedup,reported\n";
    for (const SceneSpec& spec : o.scenes) {
        std::printf("\n== %s (%s)\n", spec.name.c_str(), spec.path.c_str());
        const auto scene = load_scene_at_width(spec.path, o.width);
        const int W = scene->camera().width(), H = scene->camera().height();
        std::string ref_file;
        const FrameBuffer ref_fb = get_reference(o, spec, *scene, ref_file);
        const Image& ref = ref_fb.get("color");
        const double ref_self = reference_self_relmse(ref_fb, 0.01);
        std::printf("  reference %dx%d, %s spp, own estimated relMSE %.3g\n", W, H, ref_fb.metadata().at("spp").c_str(),
                    ref_self);
        if (o.references_only) continue;

        auto pt = integrator_registry().create("pt", Params());
        auto gpt = integrator_registry().create("gpt", gpt_params);
        auto bdpt = integrator_registry().create("bdpt", Params());
        // G-BDPT with the G-PT rows' shift and depth settings, its solves timed here as G-PT's.
        auto gbdpt = integrator_registry().create("gbdpt", gpt_params);
        // The L1 solve time (independent of the sample count) is taken out of G-PT's
        // render budget so that render + solve matches the budget.
        const double l1_est = solve_seconds(*gpt, *scene, o.threads, "poisson-l1", l1_params);
        std::printf("  L1 solve %.3f s at this resolution\n", l1_est);
        RenderSettings st;
        st.threads = o.threads;
        FrameBuffer fb;
        auto t0 = Clock::now();
        // Primal-only samples: every pixel's gradients masked (gpt then traces
        // no offset paths, at PT's cost, and still writes the layers the
        // networks read).
        Image no_gradients(W, H, 1);
        double primal_est = 0;
        if (neural) {
            st.spp = 1;
            gpt->render(*scene, st, fb);  // buffers to time the network on
            // Twice: the first run includes torch's one-time set-up, which a
            // renderer that keeps the network loaded pays once.
            const auto second_run = [&](const Reconstructor& rec) {
                (void)rec.reconstruct(gradient_buffers(fb));
                const auto t = Clock::now();
                (void)rec.reconstruct(gradient_buffers(fb));
                return since(t);
            };
            std::printf("  neural inference %.3f s at this resolution\n", second_run(*neural));
            primal_est = second_run(*neural_primal);
            std::printf("  primal-only network inference %.3f s\n", primal_est);
        }

        std::vector<std::vector<CurvePoint>> curve(kNumMethods);
        std::vector<std::vector<double>> at_budget(kNumMethods);  // relMSE per budget index
        Equal eq;
        const size_t crop_i = o.budgets.size() / 2;
        eq.budget = o.budgets[crop_i];
        auto add = [&](int m, double budget, double secs, double render_s, double solve_s, long long spp, const Image& img) {
            Row r{spec.name, methods[m], W, H, budget, secs, render_s, solve_s, spp, relmse(img, ref, RelMseOptions::thesis()),
                  mse(img, ref), ssim(img, ref), mean_deviation(img, ref)};
            rows.push_back(r);
            curve[m].push_back({secs, r.relmse});
            at_budget[m].push_back(r.relmse);
            csv << r.scene << ',' << r.width << ',' << r.height << ',' << r.method << ',' << r.budget << ',' << r.seconds
                << ',' << r.render_s << ',' << r.solve_s << ',' << r.spp << ',' << r.relmse << ',' << r.mse << ','
                << r.ssim << ',' << r.mean_dev << '\n';
            csv.flush();
            std::printf("  %-10s budget %6.2f s  time %7.3f s  %5lld spp  relMSE %.4g  mean %+.2f%%\n", methods[m].c_str(),
                        budget, secs, spp, r.relmse, 100.0 * r.mean_dev);
            return r.relmse;
        };
        for (size_t i = 0; i < o.budgets.size(); ++i) {
            const double T = o.budgets[i];
            st.spp = 0;
            st.seed = uint64_t(1 + 2 * i);
            st.time_budget = T;
            t0 = Clock::now();
            RenderStats rs = pt->render(*scene, st, fb);
            double secs = since(t0);
            const double e_pt = add(0, T, secs, secs, 0, rs.spp, fb.get("color"));
            if (i == crop_i) eq.pt = fb.get("color"), eq.e_pt = e_pt;

            st.seed = uint64_t(2 + 2 * i);
            st.time_budget = std::max(T - l1_est, 0.1 * T);
            t0 = Clock::now();
            rs = gpt->render(*scene, st, fb);
            const double render_s = since(t0);
            const GradientBuffers gb = gradient_buffers(fb);
            t0 = Clock::now();
            Image l1 = reconstruct("poisson-l1", l1_params, gb);
            const double s1 = since(t0);
            t0 = Clock::now();
            Image l2 = reconstruct("poisson-l2", l2_params, gb);
            const double s2 = since(t0);
            const double e1 = add(1, T, render_s + s1, render_s, s1, rs.spp, l1);
            const double e2 = add(2, T, render_s + s2, render_s, s2, rs.spp, l2);
            add(3, T, render_s, render_s, 0, rs.spp, fb.get("color"));
            if (i == crop_i) eq.l1 = std::move(l1), eq.l2 = std::move(l2), eq.e_l1 = e1, eq.e_l2 = e2;
            for (size_t v = 0; v < weighted_params.size(); ++v) {
                t0 = Clock::now();
                Image wimg = reconstruct("poisson-weighted", weighted_params[v], gb);
                const double sw = since(t0);
                add(kNumFixed + int(v), T, render_s + sw, render_s, sw, rs.spp, wimg);
            }
            if (neural) {
                t0 = Clock::now();
                const Image nimg = neural->reconstruct(gb);
                const double sn = since(t0);
                add(neural_m, T, render_s + sn, render_s, sn, rs.spp, nimg);

                RenderSettings ps = st;
                ps.seed = uint64_t(3001 + i);
                ps.time_budget = std::max(T - primal_est, 0.1 * T);
                ps.gradient_mask = &no_gradients;
                t0 = Clock::now();
                const RenderStats prs = gpt->render(*scene, ps, fb);
                const double prender_s = since(t0);
                t0 = Clock::now();
                const Image pimg = neural_primal->reconstruct(gradient_buffers(fb));
                const double sp = since(t0);
                add(primal_m, T, prender_s + sp, prender_s, sp, prs.spp, pimg);
            }
            if (!o.bdpt) continue;

            st.seed = uint64_t(1001 + i);
            st.time_budget = T;
            t0 = Clock::now();
            rs = bdpt->render(*scene, st, fb);
            secs = since(t0);
            add(4, T, secs, secs, 0, rs.spp, fb.get("color"));
            if (!o.gbdpt) continue;

            st.seed = uint64_t(2001 + i);
            st.time_budget = std::max(T - l1_est, 0.1 * T);
            t0 = Clock::now();
            rs = gbdpt->render(*scene, st, fb);
            const double grender_s = since(t0);
            const GradientBuffers gbb = gradient_buffers(fb);
            t0 = Clock::now();
            const Image gl1 = reconstruct("poisson-l1", l1_params, gbb);
            const double gs1 = since(t0);
            t0 = Clock::now();
            const Image gl2 = reconstruct("poisson-l2", l2_params, gbb);
            const double gs2 = since(t0);
            add(5, T, grender_s + gs1, grender_s, gs1, rs.spp, gl1);
            add(6, T, grender_s + gs2, grender_s, gs2, rs.spp, gl2);
        }

        // Speed-up at PT's error at the largest budget.
        const CurvePoint last = curve[0].back();
        std::vector<ReachTime> reach(kNumMethods);
        std::vector<std::string> sp(kNumMethods, "-");
        for (int m = 1; m < kNumMethods; ++m)
            if (!curve[m].empty()) reach[m] = time_to_reach(curve[m], last.error), sp[m] = fmt_speedup(last.seconds, reach[m], curve[m]);
        char line[512];
        std::snprintf(line, sizeof line,
                      "%-14s PT relMSE %.4g at %.1f s (ref own %.2g) | L1 %s | L2 %s | primal %s | BDPT %s | G-BDPT L1 %s | "
                      "G-BDPT L2 %s",
                      spec.name.c_str(), last.error, last.seconds, ref_self, sp[1].c_str(), sp[2].c_str(), sp[3].c_str(),
                      sp[4].c_str(), sp[5].c_str(), sp[6].c_str());
        std::string wline = line;
        // G-BDPT's target is BDPT: the time each G-BDPT row needs to reach BDPT's relMSE at the largest budget.
        if (!curve[4].empty() && !curve[5].empty()) {
            const CurvePoint bd = curve[4].back();
            char b[200];
            std::snprintf(b, sizeof b, " | vs BDPT (relMSE %.4g at %.1f s): G-BDPT L1 %s, L2 %s, G-PT L1 %s", bd.error,
                          bd.seconds, fmt_speedup(bd.seconds, time_to_reach(curve[5], bd.error), curve[5]).c_str(),
                          fmt_speedup(bd.seconds, time_to_reach(curve[6], bd.error), curve[6]).c_str(),
                          fmt_speedup(bd.seconds, time_to_reach(curve[1], bd.error), curve[1]).c_str());
            wline += b;
        }
        // Each row after the fixed ones (weighted, neural): speed-up and the largest relMSE ratio to PT at an equal budget.
        for (int m = kNumFixed; m < kNumMethods; ++m) {
            double worst = 0;
            for (size_t i = 0; i < at_budget[m].size(); ++i) worst = std::max(worst, at_budget[m][i] / at_budget[0][i]);
            char b[200];
            std::snprintf(b, sizeof b, " | %s %s (worst relMSE/PT %.2f)", methods[m].c_str(), sp[m].c_str(), worst);
            wline += b;
        }
        // The learned-denoiser baseline (path tracing plus a denoiser): the time
        // G-PT + neural needs to reach the relMSE that primal-only samples plus
        // the primal-only network reach at the budget nearest 4 s.
        if (neural_m >= 0 && primal_m >= 0 && !curve[neural_m].empty() && !curve[primal_m].empty()) {
            CurvePoint base = curve[primal_m].front();
            for (const CurvePoint& p : curve[primal_m])
                if (std::abs(std::log(p.seconds / 4.0)) < std::abs(std::log(base.seconds / 4.0))) base = p;
            char b[200];
            std::snprintf(b, sizeof b, " | vs pt-neural-primal (relMSE %.4g at %.1f s): gpt-neural %s", base.error,
                          base.seconds,
                          fmt_speedup(base.seconds, time_to_reach(curve[neural_m], base.error), curve[neural_m]).c_str());
            wline += b;
        }
        console.push_back(wline);
        std::printf("  %s\n", wline.c_str());
        char cell[96];
        std::snprintf(cell, sizeof cell, "%.3g", last.error);
        summary << "| " << spec.name << " | " << W << "x" << H << " | " << cell << " | ";
        std::snprintf(cell, sizeof cell, "%.2g", ref_self);
        summary << cell << " |";
        for (int m = 1; m < kNumMethods; ++m) summary << " " << sp[m] << " |";
        summary << "\n";
        for (int m = 1; m < kNumMethods; ++m) {
            if (curve[m].empty()) continue;
            double v = 0;
            const std::string txt = fmt_speedup(last.seconds, reach[m], curve[m], &v);
            speed << spec.name << ',' << methods[m] << ',' << last.error << ',' << last.seconds << ','
                  << reach[m].seconds << ',' << to_string(reach[m].how) << ',' << v << ",\"" << txt << "\"\n";
        }
        speed.flush();

        LogLogPlot plot;
        plot.title = spec.name + "  " + std::to_string(W) + "x" + std::to_string(H);
        plot.xlabel = "wall time per image [s] (G-PT: render + reconstruction)";
        plot.ylabel = "relMSE (eps 0.01)";
        for (int m = 0; m < kNumMethods; ++m)
            if (!curve[m].empty()) plot.series.push_back({labels[m], colors[m], curve[m], m == 3});
        plot.xticks = o.budgets;
        plot.hline = last.error;
        plot.hline_label = "PT at the largest budget";
        const Canvas pc = draw_loglog(plot);
        pc.write_png((fs::path(o.out) / (spec.name + "-convergence.png")).string());
        char title[160];
        std::snprintf(title, sizeof title, "%s at equal time %.3g s (budget), relMSE eps 0.01", spec.name.c_str(), eq.budget);
        compose_crops(title, ref, eq, true, 256).write_png((fs::path(o.out) / (spec.name + "-crops.png")).string());
        if (!o.docs.empty()) {
            pc.write_png((fs::path(o.docs) / ("equal-time-" + spec.name + "-convergence.png")).string());
            compose_crops(title, ref, eq, false, 160).write_png((fs::path(o.docs) / ("equal-time-" + spec.name + "-crops.png")).string());
        }
    }
    if (o.references_only) return 0;
    std::ofstream(fs::path(o.out) / "summary.md") << summary.str();
    std::printf("\nSpeed-up = time PT took at its largest budget / time the method first reaches PT's relMSE there\n"
                "(log-log interpolation between measured points; '>=' = already below at the shortest budget,\n"
                "'<' = not reached within the largest budget: bounds, not estimates).\n");
    for (const std::string& l : console) std::printf("%s\n", l.c_str());
    std::printf("\n%s\nwrote %s/{results.csv,summary.md,*-convergence.png,*-crops.png} in %.0f s\n", summary.str().c_str(),
                o.out.c_str(), since(t_start));
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "bench_equal_time: %s\n", e.what());
    return 1;
}
