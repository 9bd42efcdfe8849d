// gdr merge: pools independent renders of one scene with one integrator (for
// example parts rendered on several machines with different seeds) into the
// image of all their samples.
#include <algorithm>
#include <filesystem>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/cli/plugins.h"
#include "frames.h"
#include "output_lock.h"
#include "say.h"
#include "gdr/core/error.h"
#include "gdr/core/params.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"

namespace gdr::cli {

namespace {

// The integrator that made a render, rebuilt from its stored name and parameters.
std::unique_ptr<Integrator> integrator_of(const StoredRender& p) {
    const Params params = stored_params(p);
    require_integrator(p.fb.metadata().at("integrator"), "gdr merge " + p.file);
    require_plugins_of(params, "gdr merge " + p.file);
    return integrator_registry().create(p.fb.metadata().at("integrator"), params);
}

}  // namespace

int merge(const std::vector<std::string>& args) {
    // --frames A:B: one merge per frame of an animation, every file name a %04d pattern.
    for (size_t i = 0; i < args.size(); ++i) {
        if (args[i] == "-h" || args[i] == "--help") break;
        if (args[i] == "-o" || args[i] == "--output") {
            ++i;
            continue;
        }
        if (args[i] != "--frames") continue;
        if (i + 1 >= args.size()) throw ParameterError("option --frames needs a value");
        const auto [first, last] = parse_frame_range("--frames", args[i + 1]);
        std::vector<std::string> rest(args.begin(), args.begin() + long(i));
        rest.insert(rest.end(), args.begin() + long(i) + 2, args.end());
        for (size_t j = 0; j < rest.size(); ++j) {
            if (rest[j] == "--frames") throw ParameterError("merge: give --frames once");
            const bool file = rest[j] == "-o" || rest[j] == "--output" || rest[j][0] != '-';
            if (rest[j] == "-o" || rest[j] == "--output") ++j;
            if (file && j < rest.size() && last > first && !has_frame_pattern(rest[j]))
                throw ParameterError("merge --frames: '" + rest[j] + "' has no frame number pattern (%04d)");
        }
        for (int k = first; k <= last; ++k) {
            std::vector<std::string> a = rest;
            for (size_t j = 0; j < a.size(); ++j) {
                if (a[j] == "-o" || a[j] == "--output") ++j;
                else if (!a[j].empty() && a[j][0] == '-') continue;
                if (j < a.size()) a[j] = frame_path("merge --frames", rest[j], k);
            }
            const int rc = merge(a);
            if (rc != 0) return rc;
        }
        return 0;
    }
    ArgReader a{args};
    std::vector<std::string> inputs;
    std::string out;
    bool complete = false;  // --complete: every input must hold all the samples it was asked for
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-h" || o == "--help") return print_usage("merge");
        if (o == "-o" || o == "--output") out = a.value(o);
        else if (o == "--complete") complete = true;
        else if (!o.empty() && o[0] == '-') throw ParameterError("merge: unknown option '" + o + "'\n" + usage("merge"));
        else inputs.push_back(o);
    }
    if (inputs.size() < 2) throw ParameterError("merge: give at least two renders\n" + usage("merge"));
    if (out.empty()) throw ParameterError("merge: no output given (-o OUT.exr)");
    check_output_path(out);
    check_not_an_input(out, inputs);
    const OutputLock lock(out, "gdr merge");

    std::vector<StoredRender> parts;
    for (const std::string& f : inputs) {
        parts.push_back(read_stored_render(f));
        // Named here, with its file: found only in the merged image, a NaN
        // could not be traced to the part that holds it.
        for (const auto& name : parts.back().fb.names())
            require_finite(parts.back().fb.get(name), f + ": layer '" + name + "'");
    }
    if (complete) {
        // A part stopped early (a scheduler's SIGTERM, a time limit) would
        // leave the merged image short of samples without a word.
        std::string short_parts;
        for (const StoredRender& p : parts) {
            const uint64_t reached = (p.ranges.size() == 1 ? p.first_sample : 0) + p.spp;
            if (p.target_spp > reached)
                short_parts += fmt::format("\n  {}: {} of its {} spp", p.file, p.spp,
                                           p.target_spp - (p.ranges.size() == 1 ? p.first_sample : 0));
            else if (p.target_spp == 0 && p.fb.metadata().count("interrupted") &&
                     p.fb.metadata().at("interrupted") == "true")
                short_parts += fmt::format("\n  {}: interrupted after {:.3f} of its {} s", p.file, p.seconds,
                                           p.time_budget);
        }
        if (!short_parts.empty())
            throw InputError("merge --complete: renders short of their target (finish them with gdr render --resume, "
                             "or merge without --complete):" + short_parts);
    }
    const RenderIdentity id0 = identity_of(parts[0]);
    for (size_t i = 1; i < parts.size(); ++i) check_same_render(id0, parts[0].file, identity_of(parts[i]), parts[i].file);
    // Samples of one seed are numbered: two parts holding the same numbers are
    // the same samples, which would be counted twice.
    for (size_t i = 0; i < parts.size(); ++i)
        for (size_t j = i + 1; j < parts.size(); ++j)
            for (const SampleRange& p : parts[i].ranges)
                for (const SampleRange& q : parts[j].ranges)
                    if (p.seed == q.seed && p.first < q.first + q.count && q.first < p.first + p.count)
                        throw InputError(fmt::format("{} and {} hold the same samples (seed {}, samples {}-{} and "
                                                     "{}-{}): merge renders with different seeds or --resume'd "
                                                     "continuations",
                                                     parts[i].file, parts[j].file, p.seed, p.first,
                                                     p.first + p.count - 1, q.first, q.first + q.count - 1));

    FrameBuffer merged = parts[0].fb;
    double seconds = 0.0;
    bool interrupted = false;
    uint64_t held = 0, remaining = 0;  // samples per pixel in all parts, and still to take towards their targets
    std::vector<SampleRange> ranges;
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
        held += parts[i].spp;
        // A part's target counts from its sequence's first sample (sample 0 for a fresh render).
        const uint64_t reached = parts[i].ranges.size() == 1 ? parts[i].first_sample + parts[i].spp : 0;
        if (parts[i].ranges.size() == 1 && parts[i].target_spp > reached) remaining += parts[i].target_spp - reached;
        ranges.insert(ranges.end(), parts[i].ranges.begin(), parts[i].ranges.end());
    }
    // An integrator registered by another program is unknown here; its
    // non-mean layers (if it has any) cannot be recomputed, only averaged.
    std::unique_ptr<Integrator> integrator;
    try {
        integrator = integrator_of(parts[0]);
    } catch (const ParameterError& e) {
        say("warning: {}; layers that are not sample means, if any, are averaged\n", e.what());
    }
    if (integrator) integrator->update_merged(merged);

    // One seed in one unbroken range of sample numbers is a render that --resume can continue.
    ranges = normalized_ranges(ranges);
    const bool one_sequence = ranges.size() == 1;
    auto& meta = merged.metadata();
    meta["seed"] = one_sequence ? std::to_string(ranges[0].seed) : kMixedSeeds;
    meta["first_sample"] = one_sequence ? std::to_string(ranges[0].first) : kMixedSeeds;
    meta["sample_ranges"] = format_sample_ranges(ranges);
    // What the parts were asked for: an interrupted part's missing samples
    // are still to be taken by --resume.
    meta["target_spp"] = std::to_string((one_sequence ? ranges[0].first : 0) + held + remaining);
    meta["time_budget"] = "0";
    meta["render_seconds"] = fmt::format("{:.3f}", seconds);
    meta["interrupted"] = interrupted ? "true" : "false";
    meta["gdr_version"] = version();
    std::string from;
    for (const StoredRender& p : parts) from += (from.empty() ? "" : ", ") + std::filesystem::absolute(p.file).string();
    meta["merged_from"] = from;

    const std::string preview = write_render(out, merged);
    say("merged {} renders, {} spp in all{} -> {}{}\n", parts.size(), meta.at("spp"),
        one_sequence ? "" : " (several seeds: merge more parts in; --resume needs one seed)", out,
        preview.empty() ? "" : " and " + preview);
    return 0;
}

}  // namespace gdr::cli
