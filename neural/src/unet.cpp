// The U-Net, its input encodings and its weights files (gdr/neural/unet.h).

#include "gdr/neural/unet.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "gdr/core/error.h"
#include "tensor_memory.h"

namespace gdr::neural {
namespace {

namespace nn = torch::nn;

nn::Conv2d conv(int in, int out, int kernel, int stride = 1) {
    // Zero padding inside the network: the frame itself is extended by
    // replicate padding first (make_input), so no real pixel sees these zeros
    // through the full-resolution convolutions.
    return nn::Conv2d(nn::Conv2dOptions(in, out, kernel).stride(stride).padding(kernel == 3 ? 1 : 0));
}

torch::Tensor act(const torch::Tensor& x) { return torch::leaky_relu(x, 0.01); }

// The format tag of a weights file; bumped if the layout of the layers
// changes. Format 2 added the Poisson input (gdr_unet_poisson), format 3 its
// weighted form (gdr_unet_weighted); older files are networks without them
// and are still read.
constexpr int64_t kFormat = 3;

/// A tensor entry of an archive. (InputArchive::read into a Tensor calls
/// .device() on its argument, which fails on an undefined tensor.)
torch::Tensor read_tensor(torch::serialize::InputArchive& ar, const std::string& key) {
    c10::IValue v;
    ar.read(key, v);
    return v.toTensor();
}

std::string first_line(const std::string& s) { return s.substr(0, s.find('\n')); }

}  // namespace

int input_channels(const UNetConfig& config) {
    if (config.poisson && !config.gradients)
        throw ParameterError("U-Net: the Poisson input needs the gradient inputs (poisson without gradients)");
    if (config.weighted && !config.poisson)
        throw ParameterError("U-Net: the weighted Poisson input needs the Poisson input (weighted without poisson)");
    return config.poisson ? 19 : config.gradients ? 16 : 10;
}

InputLayout input_layout(const UNetConfig& config) {
    input_channels(config);  // validates
    InputLayout l;
    int c = 0;
    if (config.poisson) l.poisson = c, c += 3;
    l.primal = c, c += 3;
    if (config.gradients) l.dx = c, l.dy = c + 3, c += 6;
    l.albedo = c, l.normal = c + 3, l.depth = c + 6;
    return l;
}

UNetImpl::UNetImpl(const UNetConfig& config) : config_(config) {
    use_large_page_tensors();
    const auto& w = config_.widths;
    if (w.empty() || w.size() > 8)
        throw ParameterError("U-Net: 1 to 8 levels, got " + std::to_string(w.size()));
    for (int c : w)
        if (c < 1 || c > 1024) throw ParameterError("U-Net: level widths must be in 1..1024, got " + std::to_string(c));
    const int levels = int(w.size());
    for (int l = 0; l < levels; ++l) {
        const std::string s = std::to_string(l);
        enc_a_.push_back(register_module("enc_a" + s, conv(l == 0 ? input_channels(config_) : w[l], w[l], 3)));
        enc_b_.push_back(register_module("enc_b" + s, conv(w[l], w[l], 3)));
        if (l + 1 < levels) {
            down_.push_back(register_module("down" + s, conv(w[l], w[l + 1], 2, 2)));
            up_.push_back(register_module("up" + s, conv(w[l + 1], 4 * w[l], 1)));
            dec_a_.push_back(register_module("dec_a" + s, conv(2 * w[l], w[l], 3)));
            dec_b_.push_back(register_module("dec_b" + s, conv(w[l], w[l], 3)));
        }
    }
    out_ = register_module("out", conv(w[0], 3, 1));
    // Zero output layer: the untrained network returns its input's colour
    // (the residual is zero), a safe start that training only improves.
    torch::NoGradGuard guard;
    out_->weight.zero_();
    out_->bias.zero_();
}

torch::Tensor UNetImpl::forward(const torch::Tensor& x) {
    const int levels = int(config_.widths.size());
    std::vector<torch::Tensor> skip;
    torch::Tensor h = x;
    for (int l = 0; l < levels; ++l) {
        if (l > 0) h = act(down_[l - 1]->forward(h));
        h = act(enc_b_[l]->forward(act(enc_a_[l]->forward(h))));
        skip.push_back(h);
    }
    for (int l = levels - 2; l >= 0; --l) {
        h = torch::pixel_shuffle(up_[l]->forward(h), 2);
        h = torch::cat({act(h), skip[l]}, 1);
        h = act(dec_b_[l]->forward(act(dec_a_[l]->forward(h))));
    }
    return x.slice(1, 0, 3) + out_->forward(h);
}

long long UNetImpl::parameter_count() const {
    long long n = 0;
    for (const auto& p : parameters()) n += p.numel();
    return n;
}

torch::Tensor encode_colour(const torch::Tensor& radiance) { return torch::log1p(torch::clamp_min(radiance, 0)); }

torch::Tensor decode_colour(const torch::Tensor& y) {
    // nan_to_num first: clamp passes NaN through, and no output may hold it.
    return torch::expm1(torch::clamp(torch::nan_to_num(y, 0.0, 80.0, 0.0), 0.0, 80.0));
}

torch::Tensor encode_signed(const torch::Tensor& g) { return torch::sign(g) * torch::log1p(torch::abs(g)); }

torch::Tensor decode_signed(const torch::Tensor& y) { return torch::sign(y) * torch::expm1(torch::abs(y)); }

/// CG iterations of the weighted solve that makes the network's input (see make_input).
constexpr long long kInputSolveCgIterations = 40;

int padded_size(int size, int levels) {
    const int multiple = 1 << std::max(0, levels - 1);
    return (size + 2 * kMargin + multiple - 1) / multiple * multiple;
}

torch::Tensor make_input(const GradientBuffers& in, const UNetConfig& config) {
    const int W = in.primal->width(), H = in.primal->height(), levels = int(config.widths.size());
    const int Wp = padded_size(W, levels), Hp = padded_size(H, levels);
    // dx and dy are zero outside the frame and in their unused last column / row.
    enum class Kind { colour, dx, dy, albedo, normal, depth };
    struct Source {
        const Image* img;
        int channels;
        Kind kind;
        const char* name;
    };
    std::vector<Source> sources;
    Image poisson;
    if (config.poisson) {
        // Without `direct`: the network works on the primal's radiance and
        // infer()'s caller adds the directly visible emitters afterwards.
        GradientBuffers solve_in = in;
        solve_in.direct = nullptr;
        const char* method = config.weighted ? "poisson-weighted" : "poisson-l1";
        // The weighted solve with kInputSolveCgIterations (40) CG iterations instead of its default
        // 100 (a tenth of that per IRLS step): on a 1280x720 living-room
        // render at 2 spp its image differs from the default's by a relMSE
        // of 1.1e-5 (the network's own error there is above 1e-2) and it
        // takes about 0.9 s less.
        Params solve_params("neural input");
        if (config.weighted) solve_params.set("cg_iterations", kInputSolveCgIterations);
        poisson = reconstruct(method, solve_params, solve_in);
        sources.push_back({&poisson, 3, Kind::colour, config.weighted ? "poisson-weighted reconstruction"
                                                                      : "poisson-l1 reconstruction"});
    }
    sources.push_back({in.primal, 3, Kind::colour, "primal"});
    if (config.gradients) sources.push_back({in.dx, 3, Kind::dx, "dx"}), sources.push_back({in.dy, 3, Kind::dy, "dy"});
    sources.push_back({in.layer("albedo"), 3, Kind::albedo, "albedo"});
    sources.push_back({in.layer("normal"), 3, Kind::normal, "normal"});
    sources.push_back({in.layer("depth"), 1, Kind::depth, "depth"});
    for (const Source& s : sources) {
        if (!s.img) throw InputError(std::string("neural reconstruction needs the layer '") + s.name + "'");
        if (s.img->channels() < s.channels || s.img->width() != W || s.img->height() != H)
            throw InputError(std::string("neural reconstruction: layer '") + s.name + "' has " +
                             std::to_string(s.img->width()) + "x" + std::to_string(s.img->height()) + "x" +
                             std::to_string(s.img->channels()) + " values, needs " + std::to_string(W) + "x" +
                             std::to_string(H) + "x" + std::to_string(s.channels));
    }
    const Image& depth = *sources.back().img;
    float max_depth = 0.f;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) max_depth = std::max(max_depth, depth.at(x, y, 0));
    const float depth_scale = max_depth > 0.f ? 1.f / max_depth : 0.f;

    const int C = input_channels(config);
    torch::Tensor t = torch::empty({1, C, Hp, Wp}, torch::kFloat32);
    float* out = t.data_ptr<float>();
    const size_t plane = size_t(Hp) * Wp;
    tbb::parallel_for(0, Hp, [&](int py) {
        const int y = py - kMargin, sy = std::clamp(y, 0, H - 1);
        for (int px = 0; px < Wp; ++px) {
            const int x = px - kMargin, sx = std::clamp(x, 0, W - 1);
            const bool inside = x == sx && y == sy;
            int c = 0;
            for (const Source& s : sources) {
                const float* v = s.img->data() + (size_t(sy) * W + sx) * s.img->channels();
                const bool used = s.kind == Kind::dx ? inside && x + 1 < W : s.kind == Kind::dy ? inside && y + 1 < H : true;
                for (int j = 0; j < s.channels; ++j, ++c) {
                    float e = 0.f;
                    switch (s.kind) {
                        case Kind::colour: e = std::log1p(std::max(0.f, v[j])); break;
                        case Kind::dx:
                        case Kind::dy: e = used ? std::copysign(std::log1p(std::fabs(v[j])), v[j]) : 0.f; break;
                        case Kind::albedo: e = std::clamp(v[j], 0.f, 1.f); break;
                        case Kind::normal: e = v[j]; break;
                        case Kind::depth: e = v[j] * depth_scale; break;
                    }
                    out[size_t(c) * plane + size_t(py) * Wp + px] = e;
                }
            }
        }
    });
    return t;
}

Image infer(UNet& net, const GradientBuffers& in) {
    if (in.primal->channels() != 3)
        throw InputError("neural reconstruction needs a 3-channel primal, got " + std::to_string(in.primal->channels()));
    torch::InferenceMode guard;
    const int W = in.primal->width(), H = in.primal->height();
    // Channels-last (NHWC) input: libtorch then runs the convolutions through
    // oneDNN's direct kernels, 2-3x faster at these narrow widths than its
    // NCHW path (measured at 1280x720 on two cores); the values are the same
    // up to the order of float sums.
    torch::Tensor y = net->forward(make_input(in, net->config()).contiguous(torch::MemoryFormat::ChannelsLast));
    y = decode_colour(y.slice(2, kMargin, kMargin + H).slice(3, kMargin, kMargin + W));
    // [1, 3, H, W] -> interleaved H x W x 3.
    y = y[0].permute({1, 2, 0}).contiguous();
    Image img(W, H, 3);
    std::copy(y.data_ptr<float>(), y.data_ptr<float>() + size_t(W) * H * 3, img.data());
    return img;
}

void save_weights(UNet& net, const std::string& path) {
    torch::serialize::OutputArchive ar;
    std::vector<int64_t> widths(net->config().widths.begin(), net->config().widths.end());
    ar.write("gdr_unet_format", torch::tensor(int64_t(kFormat)));
    ar.write("gdr_unet_widths", torch::tensor(widths));
    ar.write("gdr_unet_gradients", torch::tensor(int64_t(net->config().gradients)));
    ar.write("gdr_unet_poisson", torch::tensor(int64_t(net->config().poisson)));
    ar.write("gdr_unet_weighted", torch::tensor(int64_t(net->config().weighted)));
    net->save(ar);
    // Written next to the target and renamed: a reader never sees half a file.
    const std::string tmp = path + ".partial";
    try {
        ar.save_to(tmp);
    } catch (const c10::Error& e) {
        throw InputError("cannot write weights file " + path + ": " + first_line(e.what()));
    }
    std::filesystem::rename(tmp, path);
}

UNet load_weights(const std::string& path) {
    if (!std::filesystem::is_regular_file(path))
        throw InputError("neural: weights file " + path + " does not exist (or is not a file)");
    try {
        torch::serialize::InputArchive ar;
        ar.load_from(path);
        torch::Tensor format, widths, gradients;
        format = read_tensor(ar, "gdr_unet_format");
        const int64_t fmt_was = format.numel() == 1 ? format.item<int64_t>() : -1;
        if (fmt_was < 1 || fmt_was > kFormat)
            throw InputError("neural: weights file " + path + " has format " + std::to_string(fmt_was) +
                             ", this gdr reads formats 1 to " + std::to_string(kFormat));
        widths = read_tensor(ar, "gdr_unet_widths");
        gradients = read_tensor(ar, "gdr_unet_gradients");
        UNetConfig cfg;
        cfg.widths.clear();
        for (int64_t i = 0; i < widths.numel(); ++i) cfg.widths.push_back(int(widths[i].item<int64_t>()));
        cfg.gradients = gradients.item<int64_t>() != 0;
        cfg.poisson = fmt_was >= 2 && read_tensor(ar, "gdr_unet_poisson").item<int64_t>() != 0;
        cfg.weighted = fmt_was >= 3 && read_tensor(ar, "gdr_unet_weighted").item<int64_t>() != 0;
        UNet net(cfg);
        // torch's reader replaces each tensor without comparing shapes: compare them here.
        std::vector<std::pair<std::string, std::vector<int64_t>>> expect;
        for (const auto& p : net->named_parameters()) expect.emplace_back(p.key(), p.value().sizes().vec());
        net->load(ar);
        for (const auto& [name, sizes] : expect) {
            const torch::Tensor p = net->named_parameters()[name];  // a copy: the dictionary is a temporary
            if (p.sizes().vec() != sizes)
                throw InputError("neural: weights file " + path + ": tensor '" + name + "' has shape " +
                                 c10::str(p.sizes()) + ", the network stored there needs " + c10::str(sizes));
            if (!torch::isfinite(p).all().item<bool>())
                throw InputError("neural: weights file " + path + ": tensor '" + name + "' holds NaN or Inf");
        }
        net->eval();
        return net;
    } catch (const InputError&) {
        throw;
    } catch (const ParameterError& e) {
        throw InputError("neural: weights file " + path + ": " + e.what());
    } catch (const std::exception& e) {
        // c10::Error for a file that is not a torch archive, a TorchScript
        // attribute error for one without the entries of a gdr U-Net.
        throw InputError("neural: weights file " + path + " is not a gdr U-Net weights file or is corrupt: " +
                         first_line(e.what()));
    }
}

}  // namespace gdr::neural
