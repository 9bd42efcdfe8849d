// Reconstructor front end: input checks, the registry, and loaders for the
// buffer layouts gdr reads (see gdr/reconstruct/reconstructor.h).

#include "gdr/reconstruct/reconstructor.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>

#include "gdr/reconstruct/poisson.h"

namespace gdr {
namespace {

std::string shape_text(const Image& img) {
    return std::to_string(img.width()) + "x" + std::to_string(img.height()) + "x" + std::to_string(img.channels());
}

/// Like require_finite, but scans in parallel first: the exact (first-pixel)
/// message is only worth a serial pass when something is wrong. The scan
/// tests exponent bits (all ones = NaN or Inf) with an integer OR, which the
/// compiler vectorises; an early-exit loop or a float sum would not be.
void check_finite(const Image& img, const std::string& layer) {
    const float* v = img.data();
    const size_t count = img.values().size();
    const bool bad = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, count, 1 << 16), false,
        [&](const tbb::blocked_range<size_t>& r, bool found) {
            std::uint32_t any = 0;
            for (size_t i = r.begin(); i < r.end(); ++i)
                any |= (std::bit_cast<std::uint32_t>(v[i]) & 0x7f800000u) == 0x7f800000u;
            return found || any != 0;
        },
        [](bool a, bool b) { return a || b; });
    if (bad) require_finite(img, layer);
}

}  // namespace

const Image* GradientBuffers::layer(const std::string& name) const {
    if (name == "primal") return primal;
    if (name == "dx") return dx;
    if (name == "dy") return dy;
    if (name == "direct") return direct;
    return layers && layers->has(name) ? &layers->get(name) : nullptr;
}

GradientBuffers GradientFrame::buffers() const {
    return GradientBuffers{&primal, &dx, &dy, direct.empty() ? nullptr : &direct};
}

void check_gradient_buffers(const GradientBuffers& in) {
    if (!in.primal || !in.dx || !in.dy)
        throw ParameterError(std::string("reconstruction needs primal, dx and dy; missing: ") +
                             (!in.primal ? "primal " : "") + (!in.dx ? "dx " : "") + (!in.dy ? "dy" : ""));
    if (in.primal->empty()) throw ParameterError("reconstruction: the primal image is empty");
    const std::pair<const Image*, const char*> layers[] = {
        {in.primal, "primal"},           {in.dx, "dx"},
        {in.dy, "dy"},                   {in.direct, "direct"},
        {in.primal_variance, "primal_variance"}, {in.dx_variance, "dx_variance"},
        {in.dy_variance, "dy_variance"}};
    for (const auto& [img, name] : layers) {
        if (!img) continue;
        if (!img->same_shape(*in.primal))
            throw ParameterError(std::string("reconstruction: layer '") + name + "' is " + shape_text(*img) +
                                 " but primal is " + shape_text(*in.primal));
    }
    if (in.spp && (in.spp->width() != in.primal->width() || in.spp->height() != in.primal->height() ||
                   in.spp->channels() != 1))
        throw ParameterError("reconstruction: layer 'spp' is " + shape_text(*in.spp) + " but must be " +
                             std::to_string(in.primal->width()) + "x" + std::to_string(in.primal->height()) + "x1");
    for (const auto& [img, name] : layers)
        if (img) check_finite(*img, name);
    if (in.spp) check_finite(*in.spp, "spp");
}

Image Reconstructor::reconstruct(const GradientBuffers& in) const {
    check_gradient_buffers(in);
    for (const std::string& name : required_layers()) {
        const Image* img = in.layer(name);
        if (!img) {
            std::string list = "primal, dx, dy";
            if (in.direct) list += ", direct";
            if (in.layers)
                for (const auto& n : in.layers->names())
                    if (n != "primal" && n != "dx" && n != "dy" && n != "direct") list += ", " + n;
            throw InputError("reconstruction needs the layer '" + name + "', which the input lacks (layers: " + list +
                             ")");
        }
        if (img->width() != in.primal->width() || img->height() != in.primal->height())
            throw ParameterError("reconstruction: layer '" + name + "' is " + shape_text(*img) + " but primal is " +
                                 shape_text(*in.primal));
        check_finite(*img, name);
    }
    Image out = solve(in);
    if (!out.same_shape(*in.primal))
        throw RuntimeFailure("reconstructor returned a " + shape_text(out) + " image for " + shape_text(*in.primal) +
                             " input");
    // The one check every method passes through: a NaN or Inf from any
    // solver (or from adding `direct`) must never reach an image file. With
    // `direct`, it is tested in the same pass as the sum.
    const ImageView result{out.data(), out.width(), out.height(), out.channels()};
    if (in.direct) {
        const float* d = in.direct->data();
        float* o = out.data();
        const bool bad = tbb::parallel_reduce(
            tbb::blocked_range<size_t>(0, out.values().size(), 1 << 16), false,
            [&](const tbb::blocked_range<size_t>& r, bool found) {
                std::uint32_t any = 0;
                for (size_t i = r.begin(); i < r.end(); ++i) {
                    o[i] += d[i];
                    any |= (std::bit_cast<std::uint32_t>(o[i]) & 0x7f800000u) == 0x7f800000u;
                }
                return found || any != 0;
            },
            [](bool a, bool b) { return a || b; });
        if (bad) check_finite_result(result, "reconstruction");
    } else {
        check_finite_result(result, "reconstruction");
    }
    return out;
}

void register_builtin_reconstructors(Registry<Reconstructor>& r) {
    register_poisson_reconstructors(r);
    register_weighted_reconstructors(r);
}

Registry<Reconstructor>& reconstructor_registry() {
    return process_registry<Reconstructor>("reconstructor", register_builtin_reconstructors);
}

Image reconstruct(const std::string& method, const Params& params, const GradientBuffers& in) {
    return reconstructor_registry().create(method, params)->reconstruct(in);
}

GradientBuffers gradient_buffers(const FrameBuffer& fb) {
    for (const char* name : {"primal", "dx", "dy"})
        if (!fb.has(name)) {
            std::string list;
            for (const auto& n : fb.names()) list += (list.empty() ? "" : ", ") + n;
            throw InputError(std::string("frame buffer has no layer '") + name + "' (layers: " +
                             (list.empty() ? "none" : list) + ")");
        }
    auto optional = [&](const char* name) { return fb.has(name) ? &fb.get(name) : nullptr; };
    GradientBuffers gb{&fb.get("primal"), &fb.get("dx"), &fb.get("dy"), optional("direct")};
    gb.primal_variance = optional("primal_variance"), gb.dx_variance = optional("dx_variance");
    gb.dy_variance = optional("dy_variance"), gb.spp = optional("spp");
    gb.layers = &fb;
    return gb;
}

}  // namespace gdr
