// Gradient-domain path tracing: every base path is shifted to its four
// neighbours; the MIS-weighted differences give the gradients dx, dy and the
// weighted base and offset contributions give the primal image.
#include <algorithm>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "gdr/integrators/gpt.h"

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include "gdr/path/dims.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/trace.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gpt_tracer.h"

namespace gdr {

template void compute_base_terms(const Scene&, const CameraPath&, MisHeuristic, BaseTerms&);
template PairEstimate evaluate_pair(const Scene&, const CameraPath&, const BaseTerms&, const OffsetPath*,
                                    const GradientMis&, bool);

namespace {

// The built-in solves' short names, kept as reconstruct= values and layer names.
constexpr std::pair<const char*, const char*> kShortNames[] = {
    {"weighted", "poisson-weighted"}, {"l1", "poisson-l1"}, {"l2", "poisson-l2"}};

// "key=value" lines as a map (a value keeps any '=' after the first).
std::map<std::string, std::string> key_values(const std::string& lines) {
    std::map<std::string, std::string> m;
    size_t pos = 0;
    while (pos < lines.size()) {
        size_t nl = lines.find('\n', pos);
        if (nl == std::string::npos) nl = lines.size();
        const std::string line = lines.substr(pos, nl - pos);
        if (const size_t eq = line.find('='); eq != std::string::npos && eq > 0)
            m[line.substr(0, eq)] = line.substr(eq + 1);
        pos = nl + 1;
    }
    return m;
}

}  // namespace

std::string reconstruction_layer(const std::string& method) {
    for (const auto& [short_name, name] : kShortNames)
        if (method == name) return std::string("reconstruction_") + short_name;
    return "reconstruction_" + method;
}

std::vector<std::string> GradientReconstructions::methods_of(const std::string& choice, const std::string& who) {
    if (choice == "none") return {};
    if (choice == "all") return {"poisson-weighted", "poisson-l1", "poisson-l2"};
    if (choice == "l1+l2") return {"poisson-l1", "poisson-l2"};
    std::vector<std::string> names;
    for (size_t pos = 0; pos <= choice.size();) {
        const size_t comma = std::min(choice.find(',', pos), choice.size());
        std::string name = choice.substr(pos, comma - pos);
        pos = comma + 1;
        if (name.empty())
            throw ParameterError(who + ": reconstruct='" + choice + "' has an empty entry; give registered "
                                       "reconstructor names separated by commas, or none");
        for (const auto& [short_name, full] : kShortNames)
            if (name == short_name) name = full;
        if (std::find(names.begin(), names.end(), name) != names.end())
            throw ParameterError(who + ": reconstruct='" + choice + "' names '" + name + "' twice");
        names.push_back(name);
    }
    return names;
}

GradientReconstructions GradientReconstructions::from(const Params& p, const std::string& who) {
    GradientReconstructions r;
    // The variance-weighted solve is the final image (the benchmark's
    // best, docs/performance.md); L1 and L2 stay, the anchors' methods.
    r.choice = p.get_string("reconstruct", "all");
    r.alpha = p.get_real("alpha", 0.2);
    if (!(r.alpha > 0.0)) throw ParameterError(who + ": alpha must be positive");
    if (p.has("neural_weights"))
        throw ParameterError(p.context() + ": " + who + "'s parameter 'neural_weights' is now reconstruct.weights "
                                                        "(reconstruct=neural reconstruct.weights=FILE)");
    const std::vector<std::string> names = methods_of(r.choice, who);
    const Registry<Reconstructor>& registry = reconstructor_registry();
    for (const std::string& name : names)
        if (!registry.has(name)) {
            std::string list;
            for (const auto& n : registry.names()) list += (list.empty() ? "" : ", ") + n;
            // Checked now, so that a render does not run to its end to fail there.
            throw ParameterError(who + ": reconstruct=" + r.choice + ": unknown reconstructor '" + name +
                                 "' (available: " + list + ")");
        }
    // reconstruct.<name>.<key> goes to that reconstructor; reconstruct.<key>
    // to the only one chosen.
    const std::vector<Params> parts = p.parts("reconstruct", names);
    for (size_t i = 0; i < names.size(); ++i) {
        const std::string& name = names[i];
        const Params& given = parts[i];
        Params mp = given;
        if ((name == "poisson-l1" || name == "poisson-l2") && !mp.has("alpha")) mp.set("alpha", r.alpha);
        Method m{name, reconstruction_layer(name), registry.create(name, mp)};
        // What describe() stores: the given keys and values, a text value as
        // its reconstructor reports it where it does (a file made absolute).
        // Numbers stay as given: threads=0 (all) must not become this
        // machine's count, which another part of a merge would not share.
        const auto reported = key_values(m.made->describe());
        for (const auto& [key, value] : given.values()) {
            const auto it = reported.find(key);
            const bool text = std::holds_alternative<std::string>(value);
            r.stored += given.key_prefix() + key + "=" + (text && it != reported.end() ? it->second : to_string(value)) +
                        "\n";
        }
        r.methods.push_back(std::move(m));
    }
    return r;
}

std::string GradientReconstructions::describe() const {
    return "reconstruct=" + choice + "\nalpha=" + fmt::format("{}", alpha) + "\n" + stored;
}

void GradientReconstructions::add(FrameBuffer& fb, int64_t spp, const std::string& /*who*/) const {
    if (methods.empty()) return;
    GradientBuffers gb = gradient_buffers(fb);
    Image spp_image;
    if (!gb.spp && spp > 0) {
        spp_image = Image(fb.width(), fb.height(), 1);
        std::fill(spp_image.values().begin(), spp_image.values().end(), float(spp));
        gb.spp = &spp_image;
    }
    // Every method reads the same input: the layers are set after all have run.
    std::vector<Image> results;
    for (const Method& m : methods) results.push_back(m.made->reconstruct(gb));
    for (size_t i = 0; i < methods.size(); ++i) fb.set(methods[i].layer, std::move(results[i]));
}

void fill_masked_gradients(FrameBuffer& fb) {
    if (!fb.has("gradient_mask")) return;
    const Image& mask = fb.get("gradient_mask");
    const Image& p = fb.get("primal");
    const Image& pv = fb.get("primal_variance");
    const Image* spp = fb.has("spp") ? &fb.get("spp") : nullptr;
    const int W = fb.width(), H = fb.height();
    // The gradient layers: dx / dy and every dx_<shift> / dy_<shift> with its variance.
    std::vector<std::pair<std::string, bool>> layers;  // name, horizontal
    for (const std::string& name : fb.names()) {
        const bool var = name.size() > 9 && name.compare(name.size() - 9, 9, "_variance") == 0;
        if (var) continue;
        if (name == "dx" || name.rfind("dx_", 0) == 0) layers.push_back({name, true});
        if (name == "dy" || name.rfind("dy_", 0) == 0) layers.push_back({name, false});
    }
    for (const auto& [name, horizontal] : layers) {
        Image& g = fb.get(name);
        Image* gv = fb.has(name + "_variance") ? &fb.get(name + "_variance") : nullptr;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const int qx = horizontal ? x + 1 : x, qy = horizontal ? y : y + 1;
                if (qx >= W || qy >= H || (mask.at(x, y) != 0.f && mask.at(qx, qy) != 0.f)) continue;
                g.set_rgb(x, y, p.rgb(qx, qy) - p.rgb(x, y));
                const float r = spp ? spp->at(x, y) / std::max(1.f, spp->at(qx, qy)) : 1.f;
                if (gv) gv->set_rgb(x, y, pv.rgb(x, y) + r * pv.rgb(qx, qy));
            }
    }
}

void register_gpt(Registry<Integrator>& r) {
    r.add("gpt",
          "gradient-domain path tracing (params: shift, threshold, classification, mis, max_depth, rr_depth, primal, reconstruct, alpha, batch)",
          [](const Params& p) { return std::make_unique<detail::GradientPathTracer>(p); });
}

}  // namespace gdr
