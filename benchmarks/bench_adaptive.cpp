// Adaptive sampling at equal time: uniform against adaptive sampling
// (render_adaptive: a pilot with its own seed, then the rest of the budget at
// the pilot's density) for pt (density from the colour variance) and gpt
// (from the gradient variance, as Manzi, Kettunen, Durand, Zwicker and
// Lehtinen, "Temporal Gradient-Domain Path Tracing", 2016, propose), with
// gpt reconstructed by poisson-l1 and poisson-weighted. G-PT's budget is
// shortened by its solve time measured once, so every row's time is its whole
// cost. Error: relMSE (thesis convention, eps 0.01) against a cached PT
// reference, averaged over --runs seeds. Prints each row and the ratio of
// adaptive to uniform relMSE. The "selected" rows choose per tile between
// gradient and primal-only samples (AdaptiveRender::Mode::SelectGradients,
// Kettunen's thesis section 4.3.2) with the same pilot share.
//
// Usage: bench_adaptive [--quick] [--scenes a,b] [--width W] [--budget S]
//          [--runs N] [--pilot SHARE] [--ref-spp N] [--cache DIR] [--threads N]
//          [--density key=value]...   (AdaptiveOptions: uniform, max, epsilon, median, source)
//          [--keep-pilot]             (AdaptiveRender::keep_pilot)
//          [--select key=value]...    (GradientSelectOptions: criterion = model | measured, tile, max)
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "gdr/core/args.h"
#include "gdr/eval/equal_time.h"
#include "gdr/integrators/adaptive.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/metrics.h"
#include "gdr/reconstruct/reconstructor.h"
#include "run_stats.h"

using namespace gdr;
namespace fs = std::filesystem;

namespace {

struct SceneSpec {
    std::string name, path;
};

const std::vector<SceneSpec> kScenes = {
    {"cbox-original", GDR_SOURCE_DIR "/scenes/cornell-box/scene.json"},
    {"cbox-glossy", GDR_SOURCE_DIR "/scenes/cornell-box/glossy.json"},
    {"cbox-sphere", GDR_SOURCE_DIR "/scenes/cornell-box/sphere.json"},
    {"veach-mis", GDR_SOURCE_DIR "/scenes/veach-mis/scene.json"},
    {"bathroom", GDR_SOURCE_DIR "/scenes/bathroom/scene.json"},
};

struct Options {
    std::vector<SceneSpec> scenes = kScenes;
    int width = 160, runs = 2, threads = 0;
    double budget = 4.0, pilot = 0.125;
    long long ref_spp = 1024;
    std::string cache = eval::default_reference_cache();
    AdaptiveOptions density;  // --density key=value
    bool keep_pilot = false;  // --keep-pilot: AdaptiveRender::keep_pilot
    GradientSelectOptions select;  // --select key=value
};

// The key and value of option `opt`'s argument "key=value".
std::pair<std::string, std::string> key_value(const std::string& opt, const std::string& kv) {
    const size_t eq = kv.find('=');
    if (eq == std::string::npos) throw ParameterError("bench_adaptive: " + opt + " takes key=value, got '" + kv + "'");
    return {kv.substr(0, eq), kv.substr(eq + 1)};
}

Options parse(int argc, char** argv) {
    Options o;
    ArgReader a{std::vector<std::string>(argv + 1, argv + argc)};
    while (a.more()) {
        const std::string opt = a.next();
        if (opt == "--quick") {
            o.scenes = {kScenes[0]}, o.width = 32, o.budget = 0.4, o.runs = 1, o.ref_spp = 64;
        } else if (opt == "--scenes") {
            o.scenes.clear();
            for (const std::string& n : bench::split(a.value(opt))) {
                bool found = false;
                for (const SceneSpec& s : kScenes)
                    if (s.name == n) o.scenes.push_back(s), found = true;
                if (!found) throw ParameterError("bench_adaptive: unknown scene '" + n + "'");
            }
        } else if (opt == "--width") o.width = int(a.int_value(opt, 8, 4096));
        else if (opt == "--budget") o.budget = a.real_value(opt);
        else if (opt == "--runs") o.runs = int(a.int_value(opt, 1, 100));
        else if (opt == "--pilot") o.pilot = a.real_value(opt);
        else if (opt == "--keep-pilot") o.keep_pilot = true;
        else if (opt == "--ref-spp") o.ref_spp = a.int_value(opt, 1, 1 << 20);
        else if (opt == "--cache") o.cache = a.value(opt);
        else if (opt == "--density") {
            // key=value: uniform, max, epsilon, median (radius), source (auto, gradients, primal).
            const auto [k, v] = key_value(opt, a.value(opt));
            if (k == "uniform") o.density.uniform = std::stod(v);
            else if (k == "max") o.density.max_density = std::stod(v);
            else if (k == "epsilon") o.density.epsilon = std::stod(v);
            else if (k == "median") o.density.median_radius = std::stoi(v);
            else if (k == "source")
                o.density.source = v == "primal"      ? AdaptiveOptions::Source::Primal
                                   : v == "gradients" ? AdaptiveOptions::Source::Gradients
                                                      : AdaptiveOptions::Source::Auto;
            else throw ParameterError("bench_adaptive: unknown --density key '" + k + "'");
        }
        else if (opt == "--select") {
            // key=value: criterion (model, measured), tile, max.
            const auto [k, v] = key_value(opt, a.value(opt));
            if (k == "criterion" && (v == "model" || v == "measured"))
                o.select.criterion = v == "model" ? GradientSelectOptions::Criterion::Model
                                                  : GradientSelectOptions::Criterion::Measured;
            else if (k == "tile") o.select.tile = std::stoi(v);
            else if (k == "max") o.select.max_density = std::stod(v);
            else throw ParameterError("bench_adaptive: bad --select '" + k + "=" + v + "'");
        }
        else if (opt == "--threads") o.threads = int(a.int_value(opt, 0, 1024));
        else if (opt == "-h" || opt == "--help") {
            std::printf("bench_adaptive [--quick] [--scenes a,b] [--width W] [--budget S] [--runs N] [--pilot SHARE]\n"
                        "               [--ref-spp N] [--cache DIR] [--threads N] [--density key=value]...\n"
                        "               [--keep-pilot] [--select key=value]...\n");
            std::exit(0);
        } else throw ParameterError("bench_adaptive: unknown option '" + opt + "'");
    }
    if (!(o.budget > 0.0)) throw ParameterError("bench_adaptive: --budget must be positive");
    return o;
}

// relMSE (thesis convention) over the pixels where `mask` is `on` (1) or off (0), summed with their count.
void masked_relmse(const Image& img, const Image& ref, const Image& mask, bool on, double& sum, double& count) {
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x) {
            if ((mask.at(x, y) != 0.f) != on) continue;
            for (int c = 0; c < 3; ++c) {
                const double d = double(img.at(x, y, c)) - ref.at(x, y, c), r = ref.at(x, y, c);
                sum += d * d / (r * r + 0.01);
            }
            count += 3;
        }
}

FrameBuffer reference(const Options& o, const SceneSpec& spec, const Scene& scene) {
    const std::string file = (fs::path(o.cache) / ("adaptive-" + spec.name + "-" + std::to_string(scene.camera().width()) +
                                                   "x" + std::to_string(scene.camera().height()) + "-spp" +
                                                   std::to_string(o.ref_spp) + ".exr"))
                                 .string();
    if (fs::exists(file)) {
        try {
            return read_exr(file);
        } catch (const Error&) {
        }
    }
    std::printf("  rendering reference %s ...\n", file.c_str());
    std::fflush(stdout);
    RenderSettings st;
    st.spp = o.ref_spp;
    st.seed = 0x5eed5eedull;
    st.threads = o.threads;
    FrameBuffer fb;
    integrator_registry().create("pt", Params())->render(scene, st, fb);
    fs::create_directories(o.cache);
    write_exr(file + ".tmp", fb);
    fs::rename(file + ".tmp", file);
    return fb;
}

}  // namespace

int main(int argc, char** argv) try {
    const Options o = parse(argc, argv);
    std::printf("machine: %s\n", gdr::bench::machine_description().c_str());
    std::printf("adaptive sampling at equal time: width %d, %g s per render, %d run(s) each, pilot %g of the budget\n",
                o.width, o.budget, o.runs, o.pilot);
    std::printf("error: relMSE, thesis convention (per channel, eps = 0.01), mean over runs\n");
    AdaptiveRender ad;
    ad.pilot = o.pilot;
    ad.density = o.density;
    ad.keep_pilot = o.keep_pilot;
    for (const SceneSpec& spec : o.scenes) {
        const auto scene = eval::load_scene_at_width(spec.path, o.width);
        const Image ref = reference(o, spec, *scene).get("color");
        auto pt = integrator_registry().create("pt", Params());
        Params gp;
        gp.set_from_text("reconstruct=none");
        auto gpt = integrator_registry().create("gpt", gp);
        const double solve = eval::solve_seconds(*gpt, *scene, o.threads, "poisson-l1", Params());
        RenderSettings st;
        st.threads = o.threads;
        st.spp = 0;
        FrameBuffer fb;
        // rows: pt, pt adaptive, gpt+L1, gpt+weighted, adaptive gpt+L1, adaptive gpt+weighted,
        // selected gpt+L1, selected gpt+weighted (AdaptiveRender::Mode::SelectGradients)
        constexpr int kRows = 8;
        const char* names[kRows] = {"pt", "pt adaptive", "gpt + L1", "gpt + weighted", "gpt adaptive + L1",
                                    "gpt adaptive + weighted", "gpt selected + L1", "gpt selected + weighted"};
        double err[kRows] = {}, spp[kRows] = {}, share = 0.0;
        // Per region of the selected render's mask (0: primal-only, 1: gradients):
        // relMSE sums and counts of the selected and of the uniform weighted result.
        double region_sel[2] = {}, region_uni[2] = {}, region_n[2] = {}, region_m[2] = {};
        Image uniform_weighted;
        AdaptiveRender sel = ad;
        sel.mode = AdaptiveRender::Mode::SelectGradients;
        sel.keep_pilot = o.keep_pilot;
        sel.select = o.select;
        for (int r = 0; r < o.runs; ++r) {
            for (int adaptive = 0; adaptive < 3; ++adaptive) {
                st.seed = uint64_t(100 * r + 1);
                st.time_budget = o.budget;
                RenderStats rs;
                if (adaptive < 2) {
                    rs = adaptive ? render_adaptive(*pt, *scene, st, fb, ad) : pt->render(*scene, st, fb);
                    err[adaptive] += relmse(fb.get("color"), ref, RelMseOptions::thesis()) / o.runs;
                    spp[adaptive] += double(rs.samples) / double(ref.pixel_count()) / o.runs;
                }

                st.seed = uint64_t(100 * r + 2);
                st.time_budget = std::max(0.1 * o.budget, o.budget - 2.0 * solve);  // both solves' worth
                rs = adaptive == 2 ? render_adaptive(*gpt, *scene, st, fb, sel)
                     : adaptive   ? render_adaptive(*gpt, *scene, st, fb, ad)
                                  : gpt->render(*scene, st, fb);
                if (adaptive == 2) share += std::stod(fb.metadata().at("gradient_share")) / o.runs;
                const GradientBuffers gb = gradient_buffers(fb);
                const Image l1 = reconstruct("poisson-l1", Params(), gb);
                const Image w = reconstruct("poisson-weighted", Params(), gb);
                if (adaptive == 0) uniform_weighted = w;
                if (adaptive == 2)
                    for (int on = 0; on < 2; ++on) {
                        masked_relmse(w, ref, fb.get("gradient_mask"), on, region_sel[on], region_n[on]);
                        masked_relmse(uniform_weighted, ref, fb.get("gradient_mask"), on, region_uni[on], region_m[on]);
                    }
                for (int k = 0; k < 2; ++k) {
                    const int row = 2 + 2 * adaptive + k;
                    err[row] += relmse(k ? w : l1, ref, RelMseOptions::thesis()) / o.runs;
                    spp[row] += double(rs.samples) / double(ref.pixel_count()) / o.runs;
                }
            }
        }
        std::printf("\n== %s (%dx%d)\n", spec.name.c_str(), scene->camera().width(), scene->camera().height());
        for (int k = 0; k < kRows; ++k) std::printf("  %-24s %7.1f spp  relMSE %.5f\n", names[k], spp[k], err[k]);
        std::printf("%-14s adaptive/uniform relMSE: pt %.3f, gpt + L1 %.3f, gpt + weighted %.3f\n", spec.name.c_str(),
                    err[1] / err[0], err[4] / err[2], err[5] / err[3]);
        std::printf("%-14s selected/uniform relMSE: gpt + L1 %.3f, gpt + weighted %.3f; selected weighted/pt %.3f, "
                    "uniform weighted/pt %.3f; gradients at %.0f%% of pixels\n",
                    spec.name.c_str(), err[6] / err[2], err[7] / err[3], err[7] / err[0], err[3] / err[0], 100.0 * share);
        const auto ratio = [](double a, double b) { return b > 0.0 ? a / b : 0.0; };
        std::printf("%-14s selected/uniform weighted relMSE where primal-only %.3f (%.5f), where gradients %.3f (%.5f)\n",
                    spec.name.c_str(), ratio(region_sel[0], region_uni[0]),
                    region_n[0] > 0 ? region_sel[0] / region_n[0] : 0.0, ratio(region_sel[1], region_uni[1]),
                    region_n[1] > 0 ? region_sel[1] / region_n[1] : 0.0);
        std::fflush(stdout);
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "bench_adaptive: %s\n", e.what());
    return 1;
}
