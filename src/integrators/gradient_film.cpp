#include "gdr/integrators/gradient_film.h"

#include <tbb/parallel_for.h>

#include "gdr/core/error.h"

namespace gdr {

namespace {
// Slot names of the one-sided gradients and the offset shares, per neighbour.
const char* const kGradientName[kNeighbours] = {"g+x", "g-x", "g+y", "g-y"};
const char* const kShareName[kNeighbours] = {"s+x", "s-x", "s+y", "s-y"};
}  // namespace

const char* GradientLayout::gradient_name(int d) { return kGradientName[d]; }
const char* GradientLayout::share_name(int d) { return kShareName[d]; }

std::vector<SlotSpec> GradientLayout::slots() const {
    std::vector<SlotSpec> s{{prefix + "self", 3, true}};
    for (int d = 0; d < kNeighbours; ++d) s.push_back({prefix + kGradientName[d], 3, true});
    for (int d = 0; d < kNeighbours; ++d) s.push_back({prefix + kShareName[d], 3, true});
    s.push_back({prefix + "direct", 3, false});
    s.push_back({prefix + "albedo", 3, false});
    s.push_back({prefix + "normal", 3, false});
    s.push_back({prefix + "depth", 1, false});
    return s;
}

GradientLayout GradientLayout::make(const std::string& prefix) {
    GradientLayout l;
    l.prefix = prefix;
    const std::vector<SlotSpec> s = l.slots();
    l.self = slot_offset(s, prefix + "self");
    for (int d = 0; d < kNeighbours; ++d) {
        l.gradient[d] = slot_offset(s, prefix + kGradientName[d]);
        l.share[d] = slot_offset(s, prefix + kShareName[d]);
    }
    l.direct = slot_offset(s, prefix + "direct");
    l.albedo = slot_offset(s, prefix + "albedo");
    l.normal = slot_offset(s, prefix + "normal");
    l.depth = slot_offset(s, prefix + "depth");
    for (const SlotSpec& spec : s) l.floats += spec.channels;
    return l;
}

int slot_offset(const std::vector<SlotSpec>& specs, const std::string& name) {
    int at = 0;
    for (const SlotSpec& s : specs) {
        if (s.name == name) return at;
        at += s.channels;
    }
    throw ParameterError("no sample slot '" + name + "'");
}

GradientEstimates gather_gradients(const Accumulated& acc, const GradientLayout& layout, bool light_splats) {
    const int W = acc.width, H = acc.height;
    const std::string& prefix = layout.prefix;
    GradientEstimates g;
    for (Image* im : {&g.primal, &g.primal_var, &g.dx, &g.dy, &g.dx_var, &g.dy_var}) *im = Image(W, H, 3);
    const int self = acc.slot(prefix + "self");
    int share[kNeighbours], grad[kNeighbours];
    for (int d = 0; d < kNeighbours; ++d)
        share[d] = acc.slot(prefix + kShareName[d]), grad[d] = acc.slot(prefix + kGradientName[d]);
    // A neighbour's terms are means over its own sample count: their
    // per-sample variance is scaled by count(pixel) / count(neighbour), so
    // that every variance layer over the pixel's own count ("spp" layer) is
    // its estimate's variance under adaptive sampling too (1 otherwise).
    const auto ratio = [&](int x, int y, int qx, int qy) {
        return float(double(acc.count(x, y)) / double(acc.count(qx, qy)));
    };
    // Each one-sided gradient: the pixel's own samples, plus the light
    // tracing that landed in it.
    const auto one_sided = [&](int d, int x, int y) {
        const Color m = acc.mean_rgb(grad[d], x, y);
        return light_splats ? m + acc.splat_mean(1 + d, x, y) : m;
    };
    const auto one_sided_var = [&](int d, int x, int y) {
        const Color v = acc.variance_rgb(grad[d], x, y);
        return light_splats ? v + acc.splat_variance(1 + d, x, y) : v;
    };
    tbb::parallel_for(0, H, [&](int y) {
        for (int x = 0; x < W; ++x) {
            Color p = acc.mean_rgb(self, x, y), pv = acc.variance_rgb(self, x, y);
            if (light_splats) p = p + acc.splat_mean(0, x, y), pv = pv + acc.splat_variance(0, x, y);
            // Each neighbour q = (x, y) - step left its offset's share towards (x, y).
            for (int d = 0; d < kNeighbours; ++d) {
                const int qx = x - kNeighbourDx[d], qy = y - kNeighbourDy[d];
                if (qx < 0 || qy < 0 || qx >= W || qy >= H) continue;
                p += acc.mean_rgb(share[d], qx, qy);
                pv += ratio(x, y, qx, qy) * acc.variance_rgb(share[d], qx, qy);
            }
            g.primal.set_rgb(x, y, p);
            g.primal_var.set_rgb(x, y, pv);
            if (x + 1 < W) {
                g.dx.set_rgb(x, y, one_sided(0, x, y) - one_sided(1, x + 1, y));
                g.dx_var.set_rgb(x, y, one_sided_var(0, x, y) + ratio(x, y, x + 1, y) * one_sided_var(1, x + 1, y));
            }
            if (y + 1 < H) {
                g.dy.set_rgb(x, y, one_sided(2, x, y) - one_sided(3, x, y + 1));
                g.dy_var.set_rgb(x, y, one_sided_var(2, x, y) + ratio(x, y, x, y + 1) * one_sided_var(3, x, y + 1));
            }
        }
    });
    return g;
}

void set_gradient_layers(FrameBuffer& out, GradientEstimates&& g, const Accumulated& acc,
                         const GradientLayout& layout) {
    const int W = acc.width, H = acc.height;
    const std::string& prefix = layout.prefix;
    std::vector<Image> im = acc.images({{prefix + "direct"}, {prefix + "albedo"}, {prefix + "normal"}, {prefix + "depth"}});
    Image color(W, H, 3);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) color.set_rgb(x, y, g.primal.rgb(x, y) + im[0].rgb(x, y));
    out.set("color", std::move(color));
    out.set("primal", std::move(g.primal));
    out.set("dx", std::move(g.dx));
    out.set("dy", std::move(g.dy));
    out.set("direct", std::move(im[0]));
    out.set("primal_variance", std::move(g.primal_var));
    out.set("dx_variance", std::move(g.dx_var));
    out.set("dy_variance", std::move(g.dy_var));
    // The masked-gradient fill and the weighted reconstruction read each pixel's own count.
    if (acc.adaptive()) out.set("spp", acc.count_image());
    out.set("albedo", std::move(im[1]));
    out.set("normal", std::move(im[2]));
    out.set("depth", std::move(im[3]));
}

}  // namespace gdr
