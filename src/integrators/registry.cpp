#include "gdr/integrators/integrator.h"

#include <cmath>
#include <cstdlib>
#include <vector>

#include "gdr/integrators/bdpt.h"
#include "gdr/integrators/gbdpt.h"
#include "gdr/integrators/gpt.h"
#include "gdr/integrators/pt.h"
#include "gdr/integrators/tgpt.h"

namespace gdr {

void register_builtin_integrators(Registry<Integrator>& r) {
    register_pt(r);
    register_gpt(r);
    register_bdpt(r);
    register_gbdpt(r);
    register_tgpt(r);
}

Registry<Integrator>& integrator_registry() {
    return process_registry<Integrator>("integrator", register_builtin_integrators);
}

static long long spp_of(const FrameBuffer& fb, const char* which) {
    auto it = fb.metadata().find("spp");
    if (it == fb.metadata().end()) throw ParameterError(std::string("merge: the ") + which + " render has no 'spp' entry");
    char* end = nullptr;
    const long long n = std::strtoll(it->second.c_str(), &end, 10);
    // A zero count would divide by zero in the weights; a malformed one would throw a bare "stoll".
    if (it->second.empty() || *end || n <= 0)
        throw ParameterError(std::string("merge: the ") + which + " render's 'spp' entry is not a positive count: '" +
                             it->second + "'");
    return n;
}

void merge_renders(FrameBuffer& into, const FrameBuffer& other) {
    if (into.width() != other.width() || into.height() != other.height())
        throw ParameterError("merge: renders differ in resolution");
    const long long na = spp_of(into, "first"), nb = spp_of(other, "second");
    // Reconstructions are not means of samples: update_merged() recomputes
    // them, so a render whose reconstructions were skipped (an aborted
    // render) still merges.
    const auto derived = [](const std::string& name) { return name.rfind("reconstruction", 0) == 0; };
    const auto own = [](const std::string& name) { return name == "sample_density"; };  // see below
    // Which pixels took gradient samples: pooling renders of different masks
    // would mix primal-difference edges with estimated ones.
    if (into.has("gradient_mask") != other.has("gradient_mask") ||
        (into.has("gradient_mask") && into.get("gradient_mask").values() != other.get("gradient_mask").values()))
        throw ParameterError("merge: the renders took gradient samples at different pixels (their 'gradient_mask' "
                             "layers differ or only one has one)");
    for (const auto& name : into.names())
        if (!other.has(name) && !derived(name) && !own(name))
            throw ParameterError("merge: layer '" + name + "' is missing from the second render");
    for (const auto& name : other.names())
        if (!into.has(name) && !derived(name) && !own(name))
            throw ParameterError("merge: layer '" + name + "' is missing from the first render");
    for (const auto& name : std::vector<std::string>(into.names()))
        if (derived(name) && !other.has(name)) into.remove(name);
    // Adaptive renders hold a count per pixel ("spp" layer), fixed by a
    // density chosen before their samples were taken: each pixel is then
    // weighted by its own counts, which keeps it unbiased even when the two
    // densities differ. The density layer is kept when both share it (the
    // merged render can then be continued); otherwise the result records
    // that its pixels' counts come from several densities.
    const auto is_adaptive = [](const FrameBuffer& fb) {
        const auto it = fb.metadata().find("sample_density");
        return fb.has("sample_density") || (it != fb.metadata().end() && it->second == "mixed");
    };
    const bool adaptive = is_adaptive(into) || is_adaptive(other);
    if (adaptive) {
        if (!into.has("spp") || !other.has("spp")) throw ParameterError("merge: an adaptive render without its 'spp' layer");
        const bool same = into.has("sample_density") && other.has("sample_density") &&
                          into.get("sample_density").values() == other.get("sample_density").values();
        if (!same) {
            into.remove("sample_density");
            into.metadata()["sample_density"] = "mixed";
        }
    }
    const size_t npix = size_t(into.width()) * size_t(into.height());
    std::vector<double> ca(npix, double(na)), cb(npix, double(nb));  // per pixel: the two renders' counts
    if (adaptive)
        for (size_t p = 0; p < npix; ++p)
            ca[p] = into.get("spp").values()[p], cb[p] = other.get("spp").values()[p];
    // Variances first: pooling needs both means before they are overwritten.
    for (const auto& name : into.names()) {
        const bool is_var = name.size() >= 8 && name.compare(name.size() - 8, 8, "variance") == 0;
        if (!is_var) continue;
        std::string mean_name = name == "variance" ? (into.has("color") ? "color" : "primal") : name.substr(0, name.size() - 9);
        Image& va = into.get(name);
        const Image& vb = other.get(name);
        const bool has_mean = into.has(mean_name) && into.get(mean_name).same_shape(va);
        const size_t ch = size_t(va.channels());
        for (size_t i = 0; i < va.values().size(); ++i) {
            const double a = ca[i / ch], b = cb[i / ch], m = a + b;
            double m2 = double(va.values()[i]) * (a - 1.0) + double(vb.values()[i]) * (b - 1.0);
            if (has_mean) {
                const double d = double(into.get(mean_name).values()[i]) - double(other.get(mean_name).values()[i]);
                m2 += d * d * a * b / m;
            }
            va.values()[i] = float(m2 / std::max(1.0, m - 1.0));
        }
    }
    for (const auto& name : into.names()) {
        const bool is_var = name.size() >= 8 && name.compare(name.size() - 8, 8, "variance") == 0;
        if (is_var) continue;
        Image& a = into.get(name);
        const Image& b = other.get(name);
        if (!a.same_shape(b)) throw ParameterError("merge: layer '" + name + "' differs in shape");
        if (name == "spp") {
            for (size_t i = 0; i < a.values().size(); ++i) a.values()[i] += b.values()[i];
            continue;
        }
        if (name == "sample_density" || name == "gradient_mask") continue;  // equal in both
        const size_t ch = size_t(a.channels());
        for (size_t i = 0; i < a.values().size(); ++i)
            a.values()[i] = float((double(a.values()[i]) * ca[i / ch] + double(b.values()[i]) * cb[i / ch]) /
                                  (ca[i / ch] + cb[i / ch]));
    }
    into.metadata()["spp"] = std::to_string(na + nb);
}

}  // namespace gdr
