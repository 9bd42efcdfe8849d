// gdr merge: pools independent renders of one scene with one integrator (for
// example parts rendered on several machines with different seeds) into the
// image of all their samples.
#include <algorithm>
#include <filesystem>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/core/params.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"

namespace gdr::cli {

namespace {

// The integrator that made a render, rebuilt from its stored name and parameters.
std::unique_ptr<Integrator> integrator_of(const StoredRender& p) {
    const auto& m = p.fb.metadata();
    Params params(p.file + " (integrator_params)");
    std::string lines = m.at("integrator_params");
    for (size_t at = 0; at < lines.size();) {
        const size_t end = std::min(lines.find('\n', at), lines.size());
        if (end > at) params.set_from_text(lines.substr(at, end - at));
        at = end + 1;
    }
    return integrator_registry().create(m.at("integrator"), params);
}

}  // namespace

int merge(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::vector<std::string> inputs;
    std::string out;
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-o" || o == "--output") out = a.value(o);
        else if (!o.empty() && o[0] == '-') throw ParameterError("merge: unknown option '" + o + "'\n" + usage());
        else inputs.push_back(o);
    }
    if (inputs.size() < 2) throw ParameterError("merge: give at least two renders\n" + usage());
    if (out.empty()) throw ParameterError("merge: no output given (-o OUT.exr)");
    check_output_path(out);

    std::vector<StoredRender> parts;
    for (const std::string& f : inputs) {
        parts.push_back(read_stored_render(f));
        // Parameters are compared between parts, so they must be recorded.
        if (!parts.back().fb.metadata().count("integrator_params"))
            throw InputError(f + ": not a gdr render (no 'integrator_params' entry)");
    }
    const auto& m0 = parts[0].fb.metadata();
    for (size_t i = 1; i < parts.size(); ++i) {
        const auto& m = parts[i].fb.metadata();
        for (const char* k : {"integrator", "integrator_params"})
            if (m.at(k) != m0.at(k))
                throw InputError(parts[i].file + ": made with another " + std::string(k) + " than " + parts[0].file +
                                 ":\n" + m.at(k) + "\nagainst\n" + m0.at(k));
        if (m.at("scene") != m0.at("scene"))
            fmt::print(stderr, "warning: {} renders {}, {} renders {}\n", parts[i].file, m.at("scene"), parts[0].file,
                       m0.at("scene"));
    }
    // Samples of one seed are numbered: two parts holding the same numbers are
    // the same samples, which would be counted twice.
    for (size_t i = 0; i < parts.size(); ++i)
        for (size_t j = i + 1; j < parts.size(); ++j) {
            const StoredRender &p = parts[i], &q = parts[j];
            if (p.seed == q.seed && p.first_sample < q.first_sample + q.spp && q.first_sample < p.first_sample + p.spp)
                throw InputError(p.file + " and " + q.file + " hold the same samples (seed " + std::to_string(p.seed) +
                                 "): merge renders with different seeds or --resume'd continuations");
        }

    FrameBuffer merged = parts[0].fb;
    double seconds = 0.0;
    bool interrupted = false;
    for (size_t i = 0; i < parts.size(); ++i) {
        if (i > 0) {
            try {
                merge_renders(merged, parts[i].fb);
            } catch (const ParameterError& e) {
                throw InputError(parts[i].file + " cannot be merged with " + parts[0].file + ": " + e.what());
            }
        }
        const auto& m = parts[i].fb.metadata();
        seconds += parts[i].seconds;
        interrupted |= m.count("interrupted") && m.at("interrupted") == "true";
    }
    // An integrator registered by another program is unknown here; its
    // non-mean layers (if it has any) cannot be recomputed, only averaged.
    std::unique_ptr<Integrator> integrator;
    try {
        integrator = integrator_of(parts[0]);
    } catch (const ParameterError& e) {
        fmt::print(stderr, "warning: {}; layers that are not sample means, if any, are averaged\n", e.what());
    }
    if (integrator) integrator->update_merged(merged);

    // One seed in one unbroken range of sample numbers is a render that --resume can continue.
    std::vector<const StoredRender*> order;
    for (const StoredRender& p : parts) order.push_back(&p);
    std::sort(order.begin(), order.end(),
              [](const StoredRender* x, const StoredRender* y) { return x->first_sample < y->first_sample; });
    bool one_sequence = true;
    for (size_t i = 1; i < order.size(); ++i)
        one_sequence &= order[i]->seed == order[0]->seed &&
                        order[i]->first_sample == order[i - 1]->first_sample + order[i - 1]->spp;
    auto& meta = merged.metadata();
    meta["seed"] = one_sequence ? std::to_string(order[0]->seed) : kMixedSeeds;
    meta["first_sample"] = one_sequence ? std::to_string(order[0]->first_sample) : kMixedSeeds;
    meta["render_seconds"] = fmt::format("{:.3f}", seconds);
    meta["interrupted"] = interrupted ? "true" : "false";
    std::string from;
    for (const StoredRender& p : parts) from += (from.empty() ? "" : ", ") + std::filesystem::absolute(p.file).string();
    meta["merged_from"] = from;

    const std::string preview = write_render(out, merged);
    fmt::print(stderr, "merged {} renders, {} spp in all{} -> {}{}\n", parts.size(), meta.at("spp"),
               one_sequence ? "" : " (several seeds: not resumable)", out, preview.empty() ? "" : " and " + preview);
    return 0;
}

}  // namespace gdr::cli
