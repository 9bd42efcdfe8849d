#include "gdr/eval/equal_time.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>

#include <chrono>

#include "gdr/core/error.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/io/scene_file.h"

namespace gdr::eval {

std::unique_ptr<Scene> load_scene_at_width(const std::string& path, int width) {
    if (width < 1) throw ParameterError("load_scene_at_width: width must be >= 1");
    SceneFile sf = load_scene_file(path);
    CameraDesc d = sf.scene->camera().desc();
    const double aspect = double(d.height) / double(d.width);
    d.height = std::max(1, int(std::lround(width * aspect)));
    d.width = width;
    // The loaded scene itself, with its environment and delta lights (a copy
    // of its mesh and materials alone rendered an envmap-lit room black).
    sf.scene->set_camera(Camera(d));
    return std::move(sf.scene);
}

uint64_t hash_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot read for hashing");
    uint64_t h = 1469598103934665603ull;
    for (std::istreambuf_iterator<char> it(in), end; it != end; ++it) {
        h ^= uint64_t(static_cast<unsigned char>(*it));
        h *= 1099511628211ull;
    }
    return h;
}

ReachTime time_to_reach(std::vector<CurvePoint> c, double target) {
    std::sort(c.begin(), c.end(), [](const CurvePoint& a, const CurvePoint& b) { return a.seconds < b.seconds; });
    c.erase(std::remove_if(c.begin(), c.end(), [](const CurvePoint& p) { return !(p.seconds > 0 && p.error > 0); }),
            c.end());
    ReachTime r;
    r.seconds = std::numeric_limits<double>::quiet_NaN();
    if (c.empty() || !(target > 0)) return r;
    const double lt = std::log(target);
    // Power law through points a and b, solved for the time of error `target`.
    auto along = [&](const CurvePoint& a, const CurvePoint& b) {
        const double la = std::log(a.error), lb = std::log(b.error);
        const double ta = std::log(a.seconds), tb = std::log(b.seconds);
        if (lb == la) return std::numeric_limits<double>::quiet_NaN();
        return std::exp(ta + (lt - la) * (tb - ta) / (lb - la));
    };
    if (c.front().error <= target) {
        r.how = Reach::ExtrapolatedBelow;
        r.seconds = c.front().seconds;
        if (c.size() >= 2 && c[1].error < c[0].error) r.seconds = std::min(r.seconds, along(c[0], c[1]));
        return r;
    }
    for (size_t i = 1; i < c.size(); ++i)
        if (c[i].error <= target) {
            r.how = Reach::Interpolated;
            r.seconds = along(c[i - 1], c[i]);
            return r;
        }
    if (c.size() >= 2 && c.back().error < c[c.size() - 2].error) {
        r.how = Reach::ExtrapolatedAbove;
        r.seconds = along(c[c.size() - 2], c.back());
    }
    return r;
}

const char* to_string(Reach r) {
    switch (r) {
        case Reach::Interpolated: return "interp";
        case Reach::ExtrapolatedBelow: return "extrap<";
        case Reach::ExtrapolatedAbove: return "extrap>";
        case Reach::NotReached: return "never";
    }
    return "?";
}

double solve_seconds(Integrator& gpt, const Scene& scene, int threads, const std::string& method, const Params& params) {
    RenderSettings st;
    st.threads = threads;
    st.spp = 1;
    FrameBuffer fb;
    gpt.render(scene, st, fb);
    const auto t0 = std::chrono::steady_clock::now();
    (void)reconstruct(method, params, gradient_buffers(fb));
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string default_reference_cache() {
    if (const char* e = std::getenv("GDR_REFERENCE_CACHE"); e && *e) return e;
    if (const char* h = std::getenv("HOME"); h && *h) return std::string(h) + "/.cache/gdr-references";
    return "/tmp/gdr-references";
}

}  // namespace gdr::eval
