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

namespace {

// Solid-angle density (1/sr) with which light sampling at `from` picks the
// emitter point of `at`, or, if `infinite`, the environment's direction -at.ng.
double light_pdf_w(const Scene& scene, const Vec3& from, const SurfaceInteraction& at, bool infinite) {
    if (infinite) return scene.environment_pdf(-at.ng);
    const float pa = scene.light_pdf_a(at.prim);
    if (!(pa > 0.f)) return 0.0;
    const Vec3d d = Vec3d(at.p) - Vec3d(from);
    const double dist = glm::length(d);
    return pdf_a_to_w(double(pa), dist, glm::dot(Vec3d(at.ng), d / dist));
}

// Inlined: it sits in evaluate_pair's inner loop, and as a call it kept its
// operands in memory.
[[gnu::always_inline]] inline void add(PairEstimate& e, double w, const Color& cx, const Color& cy) {
    const float wf = float(w);
    e.base += wf * cx;
    e.offset += wf * cy;
    e.gradient += wf * (cy - cx);
}

}  // namespace

// Plain path-tracing MIS weight of technique density a_t against a_other:
// the gradient weight without offset densities (the sample ratio cancels).
inline double pt_mis_weight(MisHeuristic h, double a_t, double a_other) {
    return gradient_mis_weight(GradientMis{h, 0.5}, a_t, a_other, 0.0, 0.0, 1.0);
}

void compute_base_terms(const Scene& scene, const CameraPath& x, MisHeuristic heuristic, BaseTerms& t) {
    t.v.assign(x.size(), BaseTerms::Vertex{});
    Color beta(1.f);
    for (size_t k = 1; k < x.size(); ++k) {
        const Vertex& X = x.v[k];
        const LightConnection& nee = x.nee[k];
        BaseTerms::Vertex& T = t.v[k];
        T.beta = beta;
        T.emitted = emitted(scene, X);
        if (k >= 2) {
            const Vertex& P = x.v[k - 1];
            T.emit = beta * T.emitted;
            T.emit_pdf_bsdf = P.bs.pdf;
            if (!P.bs.is_delta() && x.nee[k - 1].valid && !is_black(T.emitted))
                T.emit_pdf_light = light_pdf_w(scene, P.si.p, X.si, X.infinite);
        }
        if (nee.valid) {
            const LightSample& ls = nee.light;
            T.nee_pdf_light = nee.pdf_w;
            if (T.nee_pdf_light > 0.0) {
                const Vec3& wi = nee.wi;
                T.nee_pdf_bsdf = nee.pdf_bsdf;
                T.inv_nee_pdf_light = 1.0 / T.nee_pdf_light;
                if (nee.visible) {
                    T.nee_unit = nee.f * abs_cos_theta(wi) * ls.radiance * float(T.inv_nee_pdf_light);
                    T.nee = beta * T.nee_unit;
                }
            }
        }
        if (!X.scattered()) break;
        T.inv_bs_pdf = 1.0 / double(X.bs.pdf);
        T.inv_scatter_pdf = T.inv_bs_pdf / double(X.rr_survival);
        T.scatter = scatter_weight(X);
        beta *= T.scatter;
    }
    // Suffix sums, back to front. Where y equals x (same vertices, same
    // densities), gradient_mis_weight(a_t, a_o, a_t, a_o, r) factors into the
    // path-tracing weight of (a_t, a_o) times a function of r alone, and r and
    // beta_y / beta_x stay constant: the whole shared suffix is one product.
    Color next(0.f);  // suffix of vertex k+1 plus its emitter hit, per unit throughput at k+1
    for (size_t k = x.size(); k-- > 1;) {
        const Vertex& X = x.v[k];
        BaseTerms::Vertex& T = t.v[k];
        // Weights only where they multiply something (each costs a division).
        T.suffix = is_black(T.nee_unit) ? Color(0.f)
                                        : float(pt_mis_weight(heuristic, T.nee_pdf_light, T.nee_pdf_bsdf)) * T.nee_unit;
        if (X.scattered() && k + 1 < x.size()) T.suffix += T.scatter * next;
        next = T.suffix;
        if (k >= 2 && !is_black(T.emitted))
            next += float(pt_mis_weight(heuristic, T.emit_pdf_bsdf, T.emit_pdf_light)) * T.emitted;
    }
}

namespace {

// evaluate_pair() with `closed_form` fixed at compile time: the rendering
// loop's form carries none of the vertex-by-vertex walk's tests.
template <bool closed_form>
PairEstimate evaluate_pair_as(const Scene& scene, const CameraPath& x, const BaseTerms& t, const OffsetPath* y,
                              const GradientMis& mis) {
    PairEstimate e;
    Color beta_y(1.f);
    double r = 1.0, r_prev = 1.0;  // offset prefix density / base prefix density (through k-1, k-2)
    const size_t m = y ? y->size() : 0;
    bool y_alive = m > 0;
    for (size_t k = 1; k < x.size(); ++k) {
        const Vertex& X = x.v[k];
        const BaseTerms::Vertex& T = t.v[k];
        const bool has_y = y_alive && k < m;
        // In the shared suffix the offset is the base with its own throughput and prefix density.
        const bool merged = has_y && y->merged(k);
        // In closed form the walk stops at the first merged vertex, so there
        // every merged vertex is the first one; it stops one vertex sooner
        // where the offset reconnected onto x_k with x_k's BSDF values, past
        // x_k's emitter term (that one sees the offset's own previous vertex).
        const bool closed_from_here = closed_form && (merged || (has_y && k == y->base_values_from));
        if (closed_form && !has_y) {
            // No offset from here on (none, failed or ended): every later term has
            // the plain path-tracing weight and no offset share, so the base's
            // suffix sums give the rest at once.
            Color c = T.suffix;
            if (k >= 2 && !is_black(T.emitted))
                c += float(pt_mis_weight(mis.heuristic, T.emit_pdf_bsdf, T.emit_pdf_light)) * T.emitted;
            const Color cx = T.beta * c;
            if (!is_black(cx)) add(e, 1.0, cx, Color(0.f));
            break;
        }

        // Emitter reached by BSDF sampling at x_{k-1}.
        if (k >= 2) {
            Color cy(0.f);
            double b_b = 0.0, b_l = 0.0;
            if (merged) {
                cy = beta_y * T.emitted;
                if (closed_form || k == y->merged_from) {
                    const ShiftStep& S = y->v[k - 1].step;  // left the shared vertex with its own incoming direction
                    b_b = double(S.pdf) * S.jacobian;
                    b_l = T.emit_pdf_light * S.jacobian;
                } else {
                    b_b = T.emit_pdf_bsdf, b_l = T.emit_pdf_light;
                }
            } else if (has_y) {
                const OffsetRecord& Y = y->v[k];
                const ShiftStep& S = y->v[k - 1].step;
                cy = beta_y * Y.y.emitted;
                // The offset's densities weigh the base even where the offset itself contributes nothing.
                b_b = double(S.pdf) * S.jacobian;
                const OffsetVertex& Yp = y->v[k - 1].y;
                if (!S.delta && (Y.y.infinite || Y.y.si.is_emitter()) && scene.has_lights() && !Yp.si.material->pure_delta)
                    b_l = light_pdf_w(scene, Yp.si.p, Y.y.si, Y.y.infinite) * S.jacobian;
            }
            if (!is_black(T.emit) || !is_black(cy))
                add(e, gradient_mis_weight(mis, T.emit_pdf_bsdf, T.emit_pdf_light, b_b, b_l, r_prev), T.emit, cy);
        }

        if (closed_from_here) {
            // Everything from here on (this light sample, later vertices) in closed
            // form: w = w_pt * g(r), g(r) = (a q)^b / ((a q)^b + ((1-a) r q)^b),
            // which is the gradient weight of one technique of density 1 against
            // an offset of density 1 (and no other technique).
            const double g = gradient_mis_weight(mis, 1.0, 0.0, 1.0, 0.0, r);
            if (g > 0.0) {
                const Color cx = T.beta * T.suffix, cy = beta_y * T.suffix;
                add(e, g, cx, cy);
            }
            break;
        }

        // Light sample at x_k, shared with the offset.
        if (T.nee_pdf_light > 0.0) {
            Color cy(0.f);
            double b_l = 0.0, b_b = 0.0;
            if (!closed_form && merged) {
                cy = beta_y * T.nee_unit;
                b_l = T.nee_pdf_light, b_b = T.nee_pdf_bsdf;
            } else if (has_y && y->v[k].nee) {
                const OffsetRecord& R = y->v[k];
                b_l = R.nee_pdf_light_w * R.nee_jacobian;
                b_b = double(R.nee_pdf_bsdf) * R.nee_jacobian;
                cy = beta_y * R.nee_f * R.nee_cos * R.nee_radiance * float(R.nee_jacobian * T.inv_nee_pdf_light);
            }
            if (!is_black(T.nee) || !is_black(cy))
                add(e, gradient_mis_weight(mis, T.nee_pdf_light, T.nee_pdf_bsdf, b_l, b_b, r), T.nee, cy);
        }

        if (!X.scattered()) break;
        r_prev = r;
        if (!closed_form && merged) {
            beta_y *= scatter_weight(X);
        } else if (has_y) {
            const ShiftStep& S = y->v[k].step;
            if (S.kind == ShiftStep::Kind::Fail || k + 1 >= m) {
                y_alive = false;
            } else {
                // Products with the base's reciprocals: four offsets share them.
                beta_y *= S.f * float(abs_cos_theta(S.wi) * S.jacobian * T.inv_scatter_pdf);
                r *= double(S.pdf) * S.jacobian * T.inv_bs_pdf;
            }
        }
    }
    return e;
}

}  // namespace

PairEstimate evaluate_pair(const Scene& scene, const CameraPath& x, const BaseTerms& t, const OffsetPath* y,
                           const GradientMis& mis, bool closed_form) {
    return closed_form ? evaluate_pair_as<true>(scene, x, t, y, mis) : evaluate_pair_as<false>(scene, x, t, y, mis);
}



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
