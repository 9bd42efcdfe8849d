// Bidirectional path tracing (Veach and Guibas 1994; Lafortune and Willems
// 1993): per sample, one camera subpath through the pixel and one light
// subpath, joined by every (s, t) strategy of the path-space core
// (gdr/path/connection.h) and combined by MIS. Light tracing's t = 1
// strategies land anywhere on the film and are splatted.
#include <charconv>
#include <tuple>

#include "gdr/integrators/bdpt.h"
#include "gdr/path/dims.h"
#include "gdr/integrators/tiled.h"
#include "gdr/path/connection.h"

namespace gdr {

namespace {

// The strategies a debugging render writes as layers of their own (pbrt-v4's
// visualizestrategies): every (s, t) of paths up to this many segments.
constexpr int kStrategyLayerDepth = 4;

class Bdpt final : public TiledIntegrator {
public:
    explicit Bdpt(const Params& p) {
        std::tie(max_depth_, rr_depth_) = depth_params(p, "bdpt");
        heuristic_ = p.get_choice("mis", "power", {"power", "balance"}) == "power" ? MisHeuristic::Power
                                                                                  : MisHeuristic::Balance;
        strategy_ = p.get_string("strategy", "all");
        mode_ = strategy_ == "all" ? Mode::All : strategy_ == "light" ? Mode::Light : Mode::One;
        if (mode_ == Mode::One) {
            // "s,t": that strategy alone, unweighted (a test of its estimator).
            const auto c = parse_connection(strategy_);
            if (!c)
                throw ParameterError("bdpt: strategy must be all, light, or s,t with s >= 0, t >= 1, s + t >= 2 and "
                                     "(s, t) != (1, 1), got '" + strategy_ + "'");
            only_ = *c;
        }
        strategy_layers_ = p.get_bool("strategy_layers", false);
        hide_emitters_ = p.get_bool("hide_emitters", false);
        batch_ = batch_param(p, "bdpt", 16);
        if (strategy_layers_)
            for (int n = 2; n <= kStrategyLayerDepth + 1; ++n)
                for (int t = 1; t <= n; ++t) {
                    const int s = n - t;
                    if (s == 1 && t == 1) continue;
                    const std::string name = "strategy_s" + std::to_string(s) + "_t" + std::to_string(t);
                    if (t == 1) layer_of_[s][t] = {true, 1 + int(splat_names_.size())}, splat_names_.push_back(name);
                    else layer_of_[s][t] = {false, int(slot_names_.size())}, slot_names_.push_back(name);
                }
    }

    std::string describe() const override {
        return "max_depth=" + std::to_string(max_depth_) + "\nrr_depth=" + std::to_string(rr_depth_) +
               "\nmis=" + (heuristic_ == MisHeuristic::Power ? "power" : "balance") + "\nstrategy=" + strategy_ +
               "\nstrategy_layers=" + (strategy_layers_ ? "true" : "false") +
               (hide_emitters_ ? "\nhide_emitters=true" : "") + "\n";
    }

protected:
    std::vector<SlotSpec> slots() const override {
        std::vector<SlotSpec> s = {{"color", 3, true}, {"albedo", 3, false}, {"normal", 3, false}, {"depth", 1, false}};
        for (const std::string& n : slot_names_) s.push_back({n, 3, false});
        return s;
    }
    int splat_layers() const override { return 1 + int(splat_names_.size()); }
    int batch_size() const override { return batch_; }

    void sample_batch(const Scene& scene, SampleJob* jobs, int n, float* out, int stride,
                      uint64_t& rays) const override {
        thread_local Subpath camera, light;
        const WalkOptions cam_opt{max_depth_, rr_depth_};
        const WalkOptions light_opt{max_depth_ > 0 ? max_depth_ - 1 : -1, rr_depth_};
        for (int j = 0; j < n; ++j) {
            SampleJob& job = jobs[j];
            float* o = out + size_t(j) * stride;
            const Vec2 film = Vec2(float(job.x), float(job.y)) + job.sampler.at2(dims::kFilm);
            trace_camera_subpath(scene, film, job.sampler, cam_opt, camera);
            trace_light_subpath(scene, job.sampler, light_opt, light);
            rays += camera.rays + light.rays;
            write_aux(camera, o);
            Color pixel(0.f);
            const int s_max = std::max(light.size(), scene.has_lights() ? 1 : 0);
            for (int t = 1; t <= camera.size(); ++t)
                for (int s = 0; s <= s_max; ++s) {
                    const int verts = s + t;
                    if (verts < 2 || (s == 1 && t == 1)) continue;
                    // Paths of one segment are the directly visible emitters;
                    // (0, 2) is the only strategy left that samples them.
                    if (hide_emitters_ && verts == 2) continue;
                    if (max_depth_ > 0 && verts - 1 > max_depth_) break;
                    if (!wanted(s, t)) continue;
                    const bool weighted = mode_ == Mode::All;
                    const ConnectionResult c = connect(scene, light, camera, {s, t}, job.sampler, {heuristic_, -1}, weighted, rays);
                    if (is_black(c.value)) continue;
                    const Color v = weighted ? c.value * float(c.weight) : c.value;
                    if (c.splat) {
                        if (job.splats) job.splats->add(c.film, v, 0);
                    } else {
                        pixel += v;
                    }
                    if (strategy_layers_ && verts - 1 <= kStrategyLayerDepth) {
                        const Layer& l = layer_of_[s][t];
                        if (l.splat) {
                            if (job.splats) job.splats->add(c.film, v, l.index);
                        } else {
                            float* a = o + 10 + 3 * l.index;
                            a[0] += v.r, a[1] += v.g, a[2] += v.b;
                        }
                    }
                }
            o[0] = pixel.r, o[1] = pixel.g, o[2] = pixel.b;
        }
    }

    void finalize(const Accumulated& acc, FrameBuffer& out) const override {
        std::vector<Accumulated::Want> wanted = {{"color"}, {"albedo"}, {"normal"}, {"depth"}, {"color", true}};
        for (const std::string& n : slot_names_) wanted.push_back({n});
        std::vector<Image> im = acc.images(wanted);
        // The pixel's own strategies plus the light tracing that landed in it.
        Image& color = im[0];
        Image& variance = im[4];
        for (int y = 0; y < acc.height; ++y)
            for (int x = 0; x < acc.width; ++x) {
                const Color m = acc.splat_mean(0, x, y), v = acc.splat_variance(0, x, y);
                for (int c = 0; c < 3; ++c) color.at(x, y, c) += m[c], variance.at(x, y, c) += v[c];
            }
        out.set("color", std::move(im[0]));
        out.set("albedo", std::move(im[1]));
        out.set("normal", std::move(im[2]));
        out.set("depth", std::move(im[3]));
        out.set("variance", std::move(im[4]));
        for (size_t i = 0; i < slot_names_.size(); ++i) out.set(slot_names_[i], std::move(im[5 + i]));
        for (size_t i = 0; i < splat_names_.size(); ++i) {
            Image img(acc.width, acc.height, 3);
            for (int y = 0; y < acc.height; ++y)
                for (int x = 0; x < acc.width; ++x) {
                    const Color m = acc.splat_mean(int(i) + 1, x, y);
                    for (int c = 0; c < 3; ++c) img.at(x, y, c) = m[c];
                }
            out.set(splat_names_[i], std::move(img));
        }
    }

private:
    // Albedo and normal at the first non-delta camera vertex, depth of the
    // first hit, as the path tracer writes them.
    static void write_aux(const Subpath& camera, float* o) {
        // An environment vertex (a ray that left the scene) has no surface.
        if (camera.size() < 2 || camera.v[1].infinite) return;
        o[9] = camera.v[1].si.t;
        for (int k = 1; k < camera.size(); ++k) {
            const SurfaceInteraction& si = camera.v[k].si;
            if (camera.v[k].infinite) return;
            if (si.material->pure_delta) continue;
            const Color a = si.material->bsdf->albedo(si.uv);
            o[3] = a.r, o[4] = a.g, o[5] = a.b;
            o[6] = si.frame.n.x, o[7] = si.frame.n.y, o[8] = si.frame.n.z;
            return;
        }
    }

    bool wanted(int s, int t) const {
        switch (mode_) {
            case Mode::All: return true;
            case Mode::Light: return t == 1 || (s == 0 && t == 2);
            case Mode::One: break;
        }
        return s == only_.s && t == only_.t;
    }

    struct Layer {
        bool splat = false;
        int index = 0;  // slot among the strategy slots, or splat layer
    };
    int max_depth_ = -1, rr_depth_ = 5;
    bool hide_emitters_ = false;
    MisHeuristic heuristic_ = MisHeuristic::Power;
    std::string strategy_ = "all";  // the parameter as given (describe())
    // What it selects: every strategy MIS-weighted, light tracing alone, or only_ alone.
    enum class Mode { All, Light, One } mode_ = Mode::All;
    Connection only_;
    bool strategy_layers_ = false;
    int batch_ = 16;
    std::vector<std::string> slot_names_, splat_names_;
    Layer layer_of_[kStrategyLayerDepth + 2][kStrategyLayerDepth + 2];
};

}  // namespace

void register_bdpt(Registry<Integrator>& r) {
    r.add("bdpt",
          "bidirectional path tracing, all (s,t) strategies with MIS (params: max_depth, rr_depth, mis=power|balance, "
          "strategy=all|light|s,t, strategy_layers, batch)",
          [](const Params& p) { return std::make_unique<Bdpt>(p); });
}

}  // namespace gdr
