// The header of a stored render (gdr/io/render_header.h).
#include "gdr/io/render_header.h"

#include <algorithm>

#include <fmt/core.h>

namespace gdr {

std::string format_sample_ranges(const std::vector<SampleRange>& ranges) {
    std::string s;
    for (const SampleRange& r : ranges) s += fmt::format("{}{}:{}:{}", s.empty() ? "" : ",", r.seed, r.first, r.count);
    return s;
}

std::vector<SampleRange> normalized_ranges(std::vector<SampleRange> ranges) {
    std::sort(ranges.begin(), ranges.end(), [](const SampleRange& a, const SampleRange& b) {
        return a.seed != b.seed ? a.seed < b.seed : a.first < b.first;
    });
    std::vector<SampleRange> out;
    for (const SampleRange& r : ranges) {
        if (!out.empty() && out.back().seed == r.seed && out.back().first + out.back().count == r.first)
            out.back().count += r.count;
        else
            out.push_back(r);
    }
    return out;
}

void write_render_record(FrameBuffer& fb, const RenderRecord& r) {
    auto& meta = fb.metadata();
    meta["integrator"] = r.integrator;
    meta["scene"] = r.scene;
    if (!r.scene_hash.empty()) meta["scene_hash"] = r.scene_hash;
    meta["render_seconds"] = fmt::format("{:.3f}", r.seconds);
    meta["time_budget"] = fmt::format("{}", r.time_budget);
    if (r.target_spp > 0) meta["target_spp"] = std::to_string(r.target_spp);
    meta["sample_ranges"] = format_sample_ranges({r.samples});
    meta["gdr_version"] = r.version;
    meta["interrupted"] = r.interrupted ? "true" : "false";
}

std::string preview_layer(const FrameBuffer& fb) {
    // A gradient-domain render is shown as its variance-weighted (else L1)
    // reconstruction, anything else as its colour. The neural one comes
    // first: a render holds it only when it was asked for (reconstruct=neural).
    for (const char* name : {"reconstruction_neural", "reconstruction_weighted", "reconstruction_l1"})
        if (fb.has(name)) return name;
    // Else the first other reconstruction it holds (reconstruct=NAME of a plugin's method).
    for (const std::string& name : fb.names())
        if (name.rfind("reconstruction_", 0) == 0) return name;
    return fb.has("color") ? "color" : fb.names().front();
}

}  // namespace gdr
