// gdr_train: renders the neural reconstructor's data set with gdr, trains the
// U-Net in resumable chunks, validates it against poisson-l1 and times its
// inference. See `gdr_train --help`.

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <sys/resource.h>
#include <string>
#include <vector>

#include "gdr/core/error.h"
#include "gdr/eval/plot.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"
#include "gdr/metrics.h"
#include "gdr/neural/neural_reconstructor.h"
#include "gdr/neural/training.h"
#include "gdr/neural/unet.h"
#include "gdr/reconstruct/reconstructor.h"

using namespace gdr;
using namespace gdr::neural;

namespace {

const char* kUsage = R"(usage:
  gdr_train data --out DIR --scenes A.json[,B.json...] [--crops 16] [--size 64]
                 [--spp 4,16,64] [--target-spp 1024] [--seed 1] [--threads 0] [--vary]
                 [--meshes A.obj[,B.obj...]] [--roam] [--lenient] [--target-integrator gpt|bdpt]
      Renders random views (gpt) into DIR/crop-NNNNN.exr; existing views are kept,
      so a stopped run continues. --vary recolours materials and emitters of odd
      views; --meshes stands one of the OBJs, in a random material, in views 2
      and 3 of every 4; --roam takes views from anywhere in the scene's open
      space, not only near its camera; --lenient loads Mitsuba scenes as
      'gdr render --lenient' does. A scene that does not load is skipped, named,
      and its views are rendered by a later run once it loads. The targets are
      gpt's primal, or with --target-integrator bdpt bdpt's colour without the
      emitters seen directly (fewer caustic fireflies at equal cost).
  gdr_train train --data DIR --checkpoint CKPT --steps N [--batch 8] [--lr 5e-4]
                  [--warmup 100] [--seed 1] [--widths 16,32,48,64]
                  [--primal-only | --poisson | --poisson-weighted]
                  [--augment] [--threads 2] [--every 50] [--weights OUT] [--validation DIR]
                  [--init W.pt]
      Trains up to N steps in all, resuming from CKPT if it exists; writes CKPT
      every --every steps, CKPT.csv (step,loss[,validation loss]) and OUT.
      --poisson: the network also reads the poisson-l1 reconstruction and
      corrects it; --poisson-weighted: the same with poisson-weighted's (the
      default final image; needs data sets with the variance layers); --augment: random mirror images, transposes and colour
      permutations of the samples; --init: a new run starts from these weights
      (a trained network of the same shape) instead of random ones.
  gdr_train validate --data DIR --weights W [--twin W2] [--threads 2] [--png OUT_DIR]
      relMSE (eps 0.01, per channel) of the noisy primal, poisson-l2, poisson-l1,
      poisson-weighted, the network and (--twin) a second network, e.g. the
      primal-only twin, against the targets, per sample count, and the largest
      deviation of the network's image mean from the target's. --png writes per
      view a sheet, a row per sample count: input, network, poisson-l1,
      poisson-weighted, (twin,) target, each under the target's exposure.
  gdr_train reconstruct IN.exr --weights W -o OUT.exr [--threads 2]
      The neural reconstruction (plus direct emitters) of a gpt render, as the
      layer "color" of OUT.exr.
  gdr_train time [--widths 16,32,48,64] [--primal-only | --poisson | --poisson-weighted] [--size 1280x720]
                 [--threads 2] [--repeat 3]
      Seconds per forward pass of an untrained network of that shape on random
      input (without --poisson's poisson-l1 solve; bench_reconstruct times it all).
  gdr_train plot --losses CKPT.csv -o CURVE.png [--window 50] [--title TEXT]
      The training curve of a run (the csv train writes): the loss of every step,
      its mean over the last --window steps and the validation loss (log scale).
)";

std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    size_t pos = 0;
    while (pos <= s.size()) {
        const size_t c = std::min(s.find(',', pos), s.size());
        if (c > pos) out.push_back(s.substr(pos, c - pos));
        pos = c + 1;
    }
    return out;
}

std::vector<int> split_ints(const std::string& s, const std::string& key) {
    std::vector<int> out;
    for (const auto& t : split(s)) {
        try {
            out.push_back(std::stoi(t));
        } catch (const std::exception&) {
            throw ParameterError("gdr_train: " + key + " expects integers separated by commas, got '" + s + "'");
        }
    }
    return out;
}

/// --key value options of one sub-command; unknown keys are errors.
struct Options {
    std::map<std::string, std::string> values;
    std::vector<std::string> flags;
    Options(int argc, char** argv, const std::vector<std::string>& keys, const std::vector<std::string>& flag_keys) {
        for (int i = 2; i < argc; ++i) {
            const std::string a = argv[i];
            if (std::find(flag_keys.begin(), flag_keys.end(), a) != flag_keys.end()) {
                flags.push_back(a);
                continue;
            }
            if (std::find(keys.begin(), keys.end(), a) == keys.end())
                throw ParameterError("gdr_train " + std::string(argv[1]) + ": unknown option '" + a + "'\n" + kUsage);
            if (i + 1 >= argc) throw ParameterError("gdr_train: " + a + " needs a value");
            values[a] = argv[++i];
        }
    }
    std::string get(const std::string& k, const std::string& def = "") const {
        auto it = values.find(k);
        return it == values.end() ? def : it->second;
    }
    std::string need(const std::string& k) const {
        auto it = values.find(k);
        if (it == values.end()) throw ParameterError("gdr_train: " + k + " is required\n" + kUsage);
        return it->second;
    }
    long long num(const std::string& k, long long def) const {
        const std::string v = get(k);
        if (v.empty()) return def;
        try {
            return std::stoll(v);
        } catch (const std::exception&) {
            throw ParameterError("gdr_train: " + k + " expects an integer, got '" + v + "'");
        }
    }
    double real(const std::string& k, double def) const {
        const std::string v = get(k);
        if (v.empty()) return def;
        try {
            return std::stod(v);
        } catch (const std::exception&) {
            throw ParameterError("gdr_train: " + k + " expects a number, got '" + v + "'");
        }
    }
    bool flag(const std::string& k) const { return std::find(flags.begin(), flags.end(), k) != flags.end(); }
};

int data(int argc, char** argv) {
    const Options o(argc, argv,
                    {"--out", "--scenes", "--crops", "--size", "--spp", "--target-spp", "--seed", "--threads", "--meshes",
                     "--target-integrator"},
                    {"--vary", "--roam", "--lenient"});
    DatasetOptions d;
    d.scenes = split(o.need("--scenes"));
    d.crops = int(o.num("--crops", d.crops));
    d.size = int(o.num("--size", d.size));
    if (!o.get("--spp").empty()) d.spp = split_ints(o.get("--spp"), "--spp");
    d.target_spp = int(o.num("--target-spp", d.target_spp));
    d.seed = uint64_t(o.num("--seed", 1));
    d.threads = int(o.num("--threads", 0));
    d.vary = o.flag("--vary");
    if (!o.get("--meshes").empty()) d.meshes = split(o.get("--meshes"));
    d.roam = o.flag("--roam");
    d.lenient = o.flag("--lenient");
    if (!o.get("--target-integrator").empty()) d.target_integrator = o.get("--target-integrator");
    const auto t0 = std::chrono::steady_clock::now();
    const DatasetReport r = generate_dataset(d, o.need("--out"), [&](int done, int total) {
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        fmt::print(stderr, "\rdata: view {}/{}  {:.0f} s", done, total, s);
    });
    fmt::print(stderr, "\ndata: {} views rendered, {} kept", r.written, r.kept);
    if (r.skipped_views > 0) fmt::print(stderr, ", {} left out: their scene did not load", r.skipped_views);
    fmt::print(stderr, "\n");
    for (const auto& [scene, why] : r.skipped) fmt::print(stderr, "data: skipped {}: {}\n", scene, why);
    return 0;
}

UNetConfig config_of(const Options& o) {
    UNetConfig c;
    if (!o.get("--widths").empty()) c.widths = split_ints(o.get("--widths"), "--widths");
    c.gradients = !o.flag("--primal-only");
    c.weighted = o.flag("--poisson-weighted");
    c.poisson = o.flag("--poisson") || c.weighted;
    if (c.poisson && !c.gradients)
        throw ParameterError("gdr_train: --poisson (or --poisson-weighted) and --primal-only exclude each other");
    return c;
}

int train(int argc, char** argv) {
    const Options o(argc, argv,
                    {"--data", "--checkpoint", "--steps", "--batch", "--lr", "--warmup", "--seed", "--widths", "--threads",
                     "--every", "--weights", "--validation", "--init"},
                    {"--primal-only", "--poisson", "--poisson-weighted", "--augment"});
    TrainOptions t;
    t.config = config_of(o);
    t.augment = o.flag("--augment");
    t.batch = int(o.num("--batch", t.batch));
    t.learning_rate = o.real("--lr", t.learning_rate);
    t.warmup = int(o.num("--warmup", t.warmup));
    t.seed = uint64_t(o.num("--seed", 1));
    torch::set_num_threads(int(o.num("--threads", 2)));
    const long long steps = o.num("--steps", 0), every = std::max(1LL, o.num("--every", 50));
    const std::string ckpt = o.need("--checkpoint");
    Trainer trainer(t, load_dataset(o.need("--data"), t.config));
    std::vector<Sample> validation;
    if (!o.get("--validation").empty()) validation = load_dataset(o.get("--validation"), t.config);
    if (std::filesystem::exists(ckpt)) {
        trainer.load_checkpoint(ckpt);
        fmt::print(stderr, "train: resuming {} at step {}\n", ckpt, trainer.steps());
    } else if (!o.get("--init").empty()) {
        UNet init = load_weights(o.get("--init"));
        trainer.start_from(init);
        fmt::print(stderr, "train: starting from the weights of {}\n", o.get("--init"));
    }
    fmt::print(stderr, "train: {} parameters, {} steps of {} crops\n", trainer.net()->parameter_count(), steps, t.batch);
    std::map<long long, double> val_loss;
    const std::string csv = ckpt + ".csv";
    // Validation losses of earlier chunks are kept in the csv; reread them.
    if (std::ifstream in(csv); in && trainer.steps() > 0) {
        std::string line;
        while (std::getline(in, line)) {
            const auto f = split(line);
            if (f.size() == 3 && f[0] != "step" && std::stoll(f[0]) <= trainer.steps()) val_loss[std::stoll(f[0])] = std::stod(f[2]);
        }
    }
    const auto t0 = std::chrono::steady_clock::now();
    const long long first = trainer.steps();
    while (trainer.steps() < steps) {
        trainer.step();
        const long long k = trainer.steps();
        if (k % every == 0 || k == steps) {
            trainer.save_checkpoint(ckpt);
            const auto& l = trainer.losses();
            double mean = 0.0;
            const long long n = std::min<long long>(every, (long long)l.size());
            for (long long i = (long long)l.size() - n; i < (long long)l.size(); ++i) mean += l[size_t(i)] / double(n);
            std::string v;
            if (!validation.empty()) {
                val_loss[k] = trainer.evaluate(validation);
                v = fmt::format("  validation {:.5f}", val_loss[k]);
            }
            const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            const double per = s / double(k - first);
            fmt::print(stderr, "step {}/{}  loss {:.5f}  mean of last {}: {:.5f}{}  {:.2f} s/step  eta {:.0f} s\n", k, steps,
                       l.back(), n, mean, v, per, per * double(steps - k));
        }
    }
    {
        std::ofstream out(csv);
        out << "step,loss,validation_loss\n";
        for (size_t i = 0; i < trainer.losses().size(); ++i) {
            const long long k = (long long)i + 1;
            out << k << "," << fmt::format("{}", trainer.losses()[i]);
            if (val_loss.count(k)) out << "," << fmt::format("{}", val_loss[k]);
            out << "\n";
        }
    }
    if (!o.get("--weights").empty()) {
        save_weights(trainer.net(), o.get("--weights"));
        fmt::print(stderr, "train: weights -> {}\n", o.get("--weights"));
    }
    return 0;
}

/// Mean of each colour channel of an image (radiance).
Color channel_means(const Image& img) {
    Color m(0.f);
    double sum[3] = {0, 0, 0};
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x)
            for (int c = 0; c < 3; ++c) sum[c] += img.at(x, y, c);
    const double n = double(img.width()) * img.height();
    for (int c = 0; c < 3; ++c) m[c] = float(sum[c] / n);
    return m;
}

/// Largest relative difference of a channel mean from the target's (0.01 = 1%).
double mean_deviation(const Image& img, const Image& target) {
    const Color a = channel_means(img), b = channel_means(target);
    double worst = 0.0;
    for (int c = 0; c < 3; ++c)
        if (b[c] > 0.f) worst = std::max(worst, std::abs(double(a[c]) / double(b[c]) - 1.0));
    return worst;
}

/// One row of a side-by-side sheet: the panels of one sample count, each
/// drawn at `scale` pixels per image pixel under the target's exposure, with
/// its name and relMSE written above it.
void draw_sheet_row(eval::Canvas& sheet, int y0, int scale, float exposure,
                    const std::vector<std::pair<std::string, const Image*>>& panels, const Image& target) {
    const eval::Rgb8 black{0, 0, 0};
    const int label = eval::Canvas::text_height() + 6, gap = 6;
    for (size_t k = 0; k < panels.size(); ++k) {
        const Image& img = *panels[k].second;
        const int x0 = gap + int(k) * (img.width() * scale + gap);
        std::string text = panels[k].first;
        if (&img != &target) text += fmt::format(" {:.3g}", relmse(img, target));
        sheet.text(x0, y0 + 2, text, black);
        const std::vector<uint8_t> px = preview_bytes(img, exposure);
        const int ch = img.channels() == 1 ? 1 : img.channels() == 2 ? 3 : img.channels();
        for (int y = 0; y < img.height() * scale; ++y)
            for (int x = 0; x < img.width() * scale; ++x) {
                const size_t i = (size_t(y / scale) * img.width() + size_t(x / scale)) * size_t(ch);
                const eval::Rgb8 c = ch == 1 ? eval::Rgb8{px[i], px[i], px[i]} : eval::Rgb8{px[i], px[i + 1], px[i + 2]};
                sheet.set(x0 + x, y0 + label + y, c);
            }
    }
}

int validate(int argc, char** argv) {
    const Options o(argc, argv, {"--data", "--weights", "--twin", "--threads", "--png"}, {});
    torch::set_num_threads(int(o.num("--threads", 2)));
    UNet net = load_weights(o.need("--weights"));
    std::optional<UNet> twin;
    if (!o.get("--twin").empty()) twin = load_weights(o.get("--twin"));
    const std::string dir = o.need("--data"), png_dir = o.get("--png");
    if (!png_dir.empty()) std::filesystem::create_directories(png_dir);
    std::vector<std::string> files;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.path().filename().string().rfind("crop-", 0) == 0) files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    if (files.empty()) throw InputError("validate: no crop-*.exr in " + dir);
    // Per view and sample count; the mean is dominated by a few views with
    // fireflies, so the median is printed too.
    struct Values { std::vector<double> noisy, l2, l1, weighted, net, twin, bias, weighted_bias; };
    std::map<int, Values> by_spp;
    for (const auto& f : files) {
        const FrameBuffer fb = read_exr(f);
        const Image& target = fb.get("target");
        std::vector<int> levels;
        try {
            levels = split_ints(fb.metadata().at("spp"), "spp");
        } catch (const std::exception&) {
            throw InputError(f + ": not a gdr_train data set file (no 'spp' entry)");
        }
        // Scaled so that the sheet of a 96-pixel view is about 1000 pixels wide.
        const int scale = std::max(1, 200 / std::max(1, target.width()));
        const int panels = 4 + bool(twin) + fb.has(fmt::format("s{}_primal_variance", levels.at(0))), label = eval::Canvas::text_height() + 6, gap = 6;
        eval::Canvas sheet(gap + panels * (target.width() * scale + gap),
                           gap + int(levels.size()) * (target.height() * scale + label + gap));
        // One exposure for every panel: the target's mean luminance at 0.18.
        const Color tm = channel_means(target);
        const float lum = 0.2126f * tm.r + 0.7152f * tm.g + 0.0722f * tm.b;
        const float exposure = lum > 0.f ? std::log2(0.18f / lum) : 0.f;
        for (size_t li = 0; li < levels.size(); ++li) {
            const int s = levels[li];
            const FrameBuffer frame = view_frame(fb, s);
            // Data sets made before the variance layers were kept have no weighted column.
            const bool has_variance = frame.has("primal_variance");
            const GradientBuffers gb = gradient_buffers(frame);
            const Image l1 = reconstruct("poisson-l1", Params("validate"), gb);
            const Image weighted = has_variance ? reconstruct("poisson-weighted", Params("validate"), gb) : Image();
            const Image out = infer(net, gb);
            Values& v = by_spp[s];
            v.noisy.push_back(relmse(frame.get("primal"), target));
            v.l2.push_back(relmse(reconstruct("poisson-l2", Params("validate"), gb), target));
            v.l1.push_back(relmse(l1, target));
            if (has_variance)
                v.weighted.push_back(relmse(weighted, target)), v.weighted_bias.push_back(mean_deviation(weighted, target));
            v.net.push_back(relmse(out, target));
            v.bias.push_back(mean_deviation(out, target));
            Image twin_out;
            if (twin) twin_out = infer(*twin, gb), v.twin.push_back(relmse(twin_out, target));
            if (!png_dir.empty()) {
                std::vector<std::pair<std::string, const Image*>> row = {
                    {fmt::format("{} spp", s), &frame.get("primal")}, {"neural", &out}, {"l1", &l1}};
                if (has_variance) row.push_back({"weighted", &weighted});
                if (twin) row.push_back({"twin", &twin_out});
                row.push_back({"target", &target});
                draw_sheet_row(sheet, gap + int(li) * (target.height() * scale + label + gap), scale, exposure, row,
                               target);
            }
        }
        if (!png_dir.empty())
            sheet.write_png((std::filesystem::path(png_dir) / std::filesystem::path(f).stem()).string() + ".png");
    }
    const auto mean = [](const std::vector<double>& x) {
        if (x.empty()) return std::numeric_limits<double>::quiet_NaN();
        double m = 0.0;
        for (double v : x) m += v / double(x.size());
        return m;
    };
    // A column without values (no variance layers, no twin) prints as nan.
    const auto median = [](std::vector<double> x) {
        if (x.empty()) return std::numeric_limits<double>::quiet_NaN();
        std::sort(x.begin(), x.end());
        return x.size() % 2 ? x[x.size() / 2] : 0.5 * (x[x.size() / 2 - 1] + x[x.size() / 2]);
    };
    fmt::print("relMSE (eps 0.01, per channel) over {} views of {}: mean | median over views\n", files.size(), dir);
    fmt::print("{:>6} {:>21} {:>21} {:>21} {:>21} {:>21}{} {:>9} {:>9} {:>9}\n", "spp", "noisy", "poisson-l2",
               "poisson-l1", "poisson-weighted", "neural", twin ? fmt::format(" {:>21}", "twin") : "", "med n/l1",
               "mean dev", "w dev");
    for (const auto& [s, v] : by_spp)
        fmt::print("{:>6} {:>10.5f} {:>10.5f} {:>10.5f} {:>10.5f} {:>10.5f} {:>10.5f} {:>10.5f} {:>10.5f} {:>10.5f} "
                   "{:>10.5f}{} {:>9.3f} {:>9.4f} {:>9.4f}\n",
                   s, mean(v.noisy), median(v.noisy), mean(v.l2), median(v.l2), mean(v.l1), median(v.l1),
                   mean(v.weighted), median(v.weighted), mean(v.net), median(v.net),
                   twin ? fmt::format(" {:>10.5f} {:>10.5f}", mean(v.twin), median(v.twin)) : "",
                   median(v.net) / median(v.l1), *std::max_element(v.bias.begin(), v.bias.end()),
                   v.weighted_bias.empty() ? std::numeric_limits<double>::quiet_NaN()
                                           : *std::max_element(v.weighted_bias.begin(), v.weighted_bias.end()));
    fmt::print("(med n/l1: the network's median over poisson-l1's; mean dev, w dev: the largest relative difference "
               "of a view's channel mean from the target's, of the network's and of poisson-weighted's image)\n");
    if (!png_dir.empty())
        fmt::print("side-by-side PNGs (per view, a row per sample count: input, neural, poisson-l1, poisson-weighted{}, "
                   "target; relMSE above each) -> {}\n", twin ? ", twin" : "", png_dir);
    return 0;
}

int reconstruct_file(int argc, char** argv) {
    if (argc < 3 || argv[2][0] == '-') throw ParameterError(std::string("gdr_train reconstruct: no input given\n") + kUsage);
    const std::string in = argv[2];
    std::vector<char*> rest{argv[0], argv[1]};
    for (int i = 3; i < argc; ++i) rest.push_back(argv[i]);
    const Options o(int(rest.size()), rest.data(), {"--weights", "-o", "--threads"}, {});
    const std::string out = o.need("-o");
    if (std::filesystem::exists(out) && std::filesystem::equivalent(in, out))
        throw ParameterError("gdr_train reconstruct: the output " + out + " is the input");
    Registry<Reconstructor> reg("reconstructor");
    register_neural_reconstructor(reg);
    Params p("gdr_train reconstruct");
    p.set("weights", o.need("--weights"));
    p.set("threads", o.num("--threads", 2));
    const auto rec = reg.create("neural", p);
    const FrameBuffer fb = read_exr(in);
    GradientBuffers gb;
    try {
        gb = gradient_buffers(fb);
    } catch (const InputError& e) {
        throw InputError(in + ": not a gradient-domain render: " + e.what());
    }
    const auto t0 = std::chrono::steady_clock::now();
    Image img;
    try {
        img = rec->reconstruct(gb);
    } catch (const Error& e) {
        throw InputError(in + ": " + e.what());
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    FrameBuffer result(img.width(), img.height());
    result.set("color", img);
    result.metadata()["reconstruction"] = "neural";
    result.metadata()["reconstruction_params"] = rec->describe();
    write_exr(out, result);
    fmt::print(stderr, "reconstructed {} ({}x{}) with neural in {:.2f} s -> {}\n", in, img.width(), img.height(), s, out);
    return 0;
}

int time_inference(int argc, char** argv) {
    const Options o(argc, argv, {"--widths", "--size", "--threads", "--repeat"},
                    {"--primal-only", "--poisson", "--poisson-weighted"});
    const UNetConfig c = config_of(o);
    int W = 1280, H = 720;
    if (const std::string s = o.get("--size"); !s.empty() && std::sscanf(s.c_str(), "%dx%d", &W, &H) != 2)
        throw ParameterError("gdr_train time: --size expects WxH, got '" + s + "'");
    const int threads = int(o.num("--threads", 2));
    torch::set_num_threads(threads);
    torch::manual_seed(1);
    UNet net(c);
    // Random weights everywhere (the output layer starts at zero), like a trained network's.
    {
        torch::NoGradGuard g;
        for (auto& p : net->parameters()) p.normal_(0.0, 0.05);
    }
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    FrameBuffer fb(W, H);
    for (const auto& [name, ch] : std::vector<std::pair<std::string, int>>{
             {"primal", 3}, {"dx", 3}, {"dy", 3}, {"albedo", 3}, {"normal", 3}, {"depth", 1},
             {"primal_variance", 3}, {"dx_variance", 3}, {"dy_variance", 3}}) {
        Image& img = fb.add(name, ch);
        for (float& v : img.values()) v = u(rng);
    }
    for (float& v : fb.add("spp", 1).values()) v = 16.f;
    const GradientBuffers gb = gradient_buffers(fb);
    // CPU seconds of the process: on a machine shared with other work, CPU
    // time / threads bounds the wall time the run would take alone.
    const auto cpu = [] {
        rusage u{};
        getrusage(RUSAGE_SELF, &u);
        return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
    };
    std::vector<double> times, cpus;
    for (int r = 0; r < std::max<long long>(1, o.num("--repeat", 3)) + 1; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        const double c0 = cpu();
        const Image out = infer(net, gb);
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (r > 0) times.push_back(s), cpus.push_back(cpu() - c0);  // the first run includes one-time set-up
    }
    std::sort(times.begin(), times.end());
    std::sort(cpus.begin(), cpus.end());
    fmt::print("U-Net widths {} ({} inputs, {} parameters): {}x{} on {} threads: wall median {:.3f} s, min {:.3f} s; "
               "CPU median {:.3f} s ({} runs)\n",
               o.get("--widths", "16,32,48,64"), input_channels(c), net->parameter_count(), W, H, threads,
               times[times.size() / 2], times.front(), cpus[cpus.size() / 2], times.size());
    return 0;
}

/// A training curve on a canvas: steps on a linear axis (training progress is
/// even in steps), loss on a log axis (it falls by factors); each series a
/// polyline without markers (thousands of steps), legend at the top right.
eval::Canvas draw_training_curve(const std::string& title, const std::vector<eval::Series>& series, int W, int H) {
    using eval::Canvas;
    Canvas c(W, H);
    const eval::Rgb8 black{0, 0, 0}, grid{228, 228, 228};
    double xhi = 1, ylo = std::numeric_limits<double>::infinity(), yhi = 0;
    for (const auto& s : series)
        for (const auto& p : s.points)
            if (p.error > 0) xhi = std::max(xhi, p.seconds), ylo = std::min(ylo, p.error), yhi = std::max(yhi, p.error);
    const double ly0 = std::floor(std::log10(ylo) * 2) / 2, ly1 = std::ceil(std::log10(yhi) * 2) / 2;
    const int L = 64, R = W - 20, T = 48, B = H - 46;
    const auto X = [&](double v) { return L + v / xhi * (R - L); };
    const auto Y = [&](double v) { return B - (std::log10(v) - ly0) / (ly1 - ly0) * (B - T); };
    // x ticks every 1, 2 or 5 x 10^k steps, about 5 of them.
    const double raw = xhi / 5, mag = std::pow(10.0, std::floor(std::log10(raw)));
    const double step = raw / mag < 2 ? mag : raw / mag < 5 ? 2 * mag : 5 * mag;
    for (double t = 0; t <= xhi * 1.0001; t += step) {
        const int x = int(std::lround(X(t)));
        c.line(x, T, x, B, grid);
        c.line(x, B, x, B + 4, black);
        const std::string lab = fmt::format("{}", t);
        c.text(x - Canvas::text_width(lab) / 2, B + 7, lab, black);
    }
    for (int e = int(std::floor(ly0)); e <= int(std::ceil(ly1)); ++e)
        for (double m : {1.0, 2.0, 5.0}) {
            const double v = m * std::pow(10.0, e);
            if (std::log10(v) < ly0 - 1e-9 || std::log10(v) > ly1 + 1e-9) continue;
            const int y = int(std::lround(Y(v)));
            c.line(L, y, R, y, grid);
            c.line(L - 4, y, L, y, black);
            const std::string lab = fmt::format("{:g}", v);
            c.text(L - 7 - Canvas::text_width(lab), y - 4, lab, black);
        }
    for (const auto& s : series)
        for (size_t i = 1; i < s.points.size(); ++i) {
            const auto &a = s.points[i - 1], &b = s.points[i];
            if (a.error > 0 && b.error > 0) c.line(X(a.seconds), Y(a.error), X(b.seconds), Y(b.error), s.color, s.dashed ? 1 : 2);
        }
    c.line(L, T, L, B, black), c.line(L, B, R, B, black), c.line(R, T, R, B, black), c.line(L, T, R, T, black);
    int lw = 0;
    for (const auto& s : series) lw = std::max(lw, Canvas::text_width(s.label));
    const int lx = R - lw - 46;
    int ly = T + 8;
    c.fill_rect(lx - 6, ly - 5, R - 6, ly + int(series.size()) * 16 + 1, {255, 255, 255});
    for (const auto& s : series) {
        c.line(lx, ly + 4, lx + 28, ly + 4, s.color, 2);
        c.text(lx + 34, ly, s.label, black);
        ly += 16;
    }
    c.text(L, 8, title, black, 2);
    const std::string xl = "training step", yl = "loss: L1 of tone-mapped values + 0.01 relMSE (log scale)";
    c.text((L + R) / 2 - Canvas::text_width(xl) / 2, H - 18, xl, black);
    c.text(L, T - 14, yl, black);
    return c;
}

int plot_losses(int argc, char** argv) {
    const Options o(argc, argv, {"--losses", "-o", "--window", "--title"}, {});
    const std::string csv = o.need("--losses"), out = o.need("-o");
    const long long window = o.num("--window", 50);
    if (window < 1) throw ParameterError("gdr_train plot: --window must be at least 1");
    std::ifstream in(csv);
    if (!in) throw InputError("gdr_train plot: cannot read " + csv);
    std::vector<eval::CurvePoint> loss, validation;
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
        const auto f = split(line);
        if (f.empty() || f[0] == "step") continue;
        try {
            const double step = std::stod(f.at(0));
            loss.push_back({step, std::stod(f.at(1))});
            if (f.size() > 2) validation.push_back({step, std::stod(f[2])});
        } catch (const std::exception&) {
            throw InputError(fmt::format("gdr_train plot: {} line {}: expected step,loss[,validation_loss], got '{}'", csv,
                                         n, line));
        }
    }
    if (loss.empty()) throw InputError("gdr_train plot: " + csv + " holds no losses");
    // The per-step loss is one minibatch's: the trend shows in its running mean.
    std::vector<eval::CurvePoint> mean;
    double sum = 0.0;
    for (size_t i = 0; i < loss.size(); ++i) {
        sum += loss[i].error;
        if (i >= size_t(window)) sum -= loss[i - size_t(window)].error;
        mean.push_back({loss[i].seconds, sum / double(std::min(i + 1, size_t(window)))});
    }
    std::vector<eval::Series> series;
    series.push_back({"loss of each step (one minibatch of 8)", {200, 200, 200}, loss, true});
    series.push_back({fmt::format("mean of the last {} steps", window), {200, 40, 40}, mean, false});
    if (!validation.empty()) series.push_back({"validation loss", {40, 90, 200}, validation, false});
    const std::string title = o.get("--title", "training loss, " + std::filesystem::path(csv).filename().string());
    draw_training_curve(title, series, 760, 440).write_png(out);
    fmt::print(stderr, "plot: {} steps of {} -> {} (mean of the last {} steps {:.5f})\n", loss.size(), csv, out, window,
               mean.back().error);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        const std::string cmd = argc > 1 ? argv[1] : "";
        if (cmd == "data") return data(argc, argv);
        if (cmd == "train") return train(argc, argv);
        if (cmd == "validate") return validate(argc, argv);
        if (cmd == "time") return time_inference(argc, argv);
        if (cmd == "reconstruct") return reconstruct_file(argc, argv);
        if (cmd == "plot") return plot_losses(argc, argv);
        std::fputs(kUsage, cmd == "-h" || cmd == "--help" ? stdout : stderr);
        return cmd == "-h" || cmd == "--help" ? 0 : 2;
    } catch (const Error& e) {
        std::fprintf(stderr, "gdr_train: error: %s\n", e.what());
        return 1;
    } catch (const c10::Error& e) {
        const std::string what = e.what();
        std::fprintf(stderr, "gdr_train: torch error: %s\n", what.substr(0, what.find('\n')).c_str());
        return 1;
    }
}
