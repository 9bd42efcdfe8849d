// Front end of the spatio-temporal reconstruction (gdr/reconstruct/temporal.h):
// options, frame checks, the streaming window blend and the frame-file driver.

#include "gdr/reconstruct/temporal.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "gdr/core/error.h"

namespace gdr {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string shape_text(const Image& img) {
    return std::to_string(img.width()) + "x" + std::to_string(img.height()) + "x" + std::to_string(img.channels());
}

ImageView view_of(const Image& img) {
    return img.empty() ? ImageView{} : ImageView{img.data(), img.width(), img.height(), img.channels()};
}

/// Hann weight of frame f in the window [first, first + length) (unitless, > 0 inside).
double hann(int f, int first, int length) {
    const double c = first + 0.5 * (length - 1);
    return 0.5 * (1.0 + std::cos(2.0 * kPi * (f - c) / length));
}

}  // namespace

void check_temporal_options(const TemporalOptions& o) {
    auto bad = [](const std::string& what) { throw ParameterError("temporal reconstruction: " + what); };
    if (!(o.alpha > 0) || !std::isfinite(o.alpha)) bad("alpha must be finite and > 0");
    if (!(o.w_s >= 0) || !std::isfinite(o.w_s)) bad("w_s must be finite and >= 0");
    if (!(o.w_t >= 0) || !std::isfinite(o.w_t)) bad("w_t must be finite and >= 0");
    if (o.cg_iterations < 0) bad("cg_iterations must be >= 0");
    if (!(o.tolerance >= 0)) bad("tolerance must be >= 0");
    if (o.irls_iterations < 1) bad("iterations (IRLS) must be >= 1");
    if (o.irls_cg_iterations < 1) bad("irls_cg_iterations must be >= 1");
    if (!(o.irls_tolerance >= 0)) bad("irls_tolerance must be >= 0");
    if (!(o.eps_initial > 0) || !(o.eps_factor > 0) || o.eps_factor > 1) bad("need eps_initial > 0 and 0 < eps_factor <= 1");
    if (o.window < 1) bad("window must be >= 1, got " + std::to_string(o.window));
    if (o.step < 1 || o.step > o.window)
        bad("step must be in 1..window (" + std::to_string(o.window) + "), got " + std::to_string(o.step));
}

TemporalOptions temporal_options(const Params& p) {
    TemporalOptions o;
    o.alpha = p.get_real("alpha", o.alpha);
    o.w_s = p.get_real("w_s", o.w_s);
    o.w_t = p.get_real("w_t", o.w_t);
    o.norm = p.get_choice("norm", "l1", {"l1", "l2"}) == "l1" ? TemporalNorm::l1 : TemporalNorm::l2;
    const std::string solver = p.get_choice("solver", "auto", {"auto", "dct", "cg"});
    o.solver = solver == "auto" ? TemporalSolver::automatic : solver == "dct" ? TemporalSolver::dct : TemporalSolver::cg;
    auto preconditioner = [&](const char* key, const char* def) {
        const std::string v = p.get_choice(key, def, {"dct", "multigrid", "none"});
        return v == "dct" ? TemporalPreconditioner::dct
               : v == "multigrid" ? TemporalPreconditioner::frame_multigrid
                                  : TemporalPreconditioner::none;
    };
    o.l2_preconditioner = preconditioner("preconditioner", "dct");
    o.irls_preconditioner = preconditioner("irls_preconditioner", "multigrid");
    o.eps_initial = p.get_real("eps_initial", o.eps_initial);
    o.eps_factor = p.get_real("eps_factor", o.eps_factor);
    auto integer = [&](const char* key, int def, long long lo, long long hi) {
        const long long v = p.get_int(key, def);
        if (v < lo || v > hi)
            throw ParameterError(p.context() + ": parameter '" + key + "' must be in " + std::to_string(lo) + ".." +
                                 std::to_string(hi) + ", got " + std::to_string(v));
        return int(v);
    };
    o.cg_iterations = integer("cg_iterations", o.cg_iterations, 0, 100000);
    o.tolerance = p.get_real("tolerance", o.tolerance);
    o.irls_iterations = integer("iterations", o.irls_iterations, 1, 1000);
    o.irls_cg_iterations = integer("irls_cg_iterations", o.irls_cg_iterations, 1, 100000);
    o.irls_tolerance = p.get_real("irls_tolerance", o.irls_tolerance);
    o.window = integer("window", o.window, 1, 100000);
    o.step = integer("step", o.step, 1, 100000);
    o.require_dt = p.get_bool("require_dt", o.require_dt);
    p.check_unused("temporal reconstruction");
    try {
        check_temporal_options(o);
    } catch (const ParameterError& e) {
        throw ParameterError(p.context() + ": " + e.what());
    }
    return o;
}

std::string describe(const TemporalOptions& o) {
    std::ostringstream os;
    os.precision(17);
    auto name = [](TemporalPreconditioner k) {
        return k == TemporalPreconditioner::dct ? "dct" : k == TemporalPreconditioner::frame_multigrid ? "multigrid" : "none";
    };
    const char* solver = o.solver == TemporalSolver::automatic ? "auto" : o.solver == TemporalSolver::dct ? "dct" : "cg";
    os << "alpha=" << o.alpha << "\ncg_iterations=" << o.cg_iterations << "\neps_factor=" << o.eps_factor
       << "\neps_initial=" << o.eps_initial << "\nirls_cg_iterations=" << o.irls_cg_iterations
       << "\nirls_preconditioner=" << name(o.irls_preconditioner) << "\nirls_tolerance=" << o.irls_tolerance
       << "\niterations=" << o.irls_iterations << "\nnorm=" << (o.norm == TemporalNorm::l1 ? "l1" : "l2")
       << "\npreconditioner=" << name(o.l2_preconditioner)
       << "\nrequire_dt=" << (o.require_dt ? "true" : "false") << "\nsolver=" << solver << "\nstep=" << o.step
       << "\ntolerance=" << o.tolerance << "\nw_s=" << o.w_s << "\nw_t=" << o.w_t << "\nwindow=" << o.window << "\n";
    return os.str();
}

TemporalFrameView TemporalFrame::view() const {
    TemporalFrameView v;
    v.primal = view_of(primal), v.dx = view_of(dx), v.dy = view_of(dy), v.dt = view_of(dt);
    v.motion = motion.empty() ? nullptr : motion.data();
    v.valid = valid.empty() ? nullptr : valid.data();
    return v;
}

void check_temporal_frame(const TemporalFrame& fr) {
    const std::string who = "frame '" + fr.name + "'";
    const std::pair<const Image*, const char*> required[] = {
        {&fr.primal, temporal_layers::primal}, {&fr.dx, temporal_layers::dx}, {&fr.dy, temporal_layers::dy}};
    for (const auto& [img, name] : required)
        if (img->empty()) throw InputError(who + ": no layer '" + name + "'");
    const std::pair<const Image*, const char*> same[] = {
        {&fr.dx, temporal_layers::dx}, {&fr.dy, temporal_layers::dy}, {&fr.direct, temporal_layers::direct},
        {&fr.dt, temporal_layers::dt}};
    for (const auto& [img, name] : same)
        if (!img->empty() && !img->same_shape(fr.primal))
            throw InputError(who + ": layer '" + name + "' is " + shape_text(*img) + " but primal is " +
                             shape_text(fr.primal));
    auto sized = [&](const Image& img, const char* name, int channels) {
        if (!img.empty() && (img.width() != fr.primal.width() || img.height() != fr.primal.height() ||
                             img.channels() != channels))
            throw InputError(who + ": layer '" + name + "' is " + shape_text(img) + " but must be " +
                             std::to_string(fr.primal.width()) + "x" + std::to_string(fr.primal.height()) + "x" +
                             std::to_string(channels));
    };
    sized(fr.motion, temporal_layers::motion, 2);
    sized(fr.valid, temporal_layers::valid, 1);
    const std::pair<const Image*, const char*> all[] = {
        {&fr.primal, temporal_layers::primal}, {&fr.dx, temporal_layers::dx},     {&fr.dy, temporal_layers::dy},
        {&fr.direct, temporal_layers::direct}, {&fr.dt, temporal_layers::dt},     {&fr.motion, temporal_layers::motion},
        {&fr.valid, temporal_layers::valid}};
    for (const auto& [img, name] : all)
        if (!img->empty()) require_finite(*img, who + ", layer '" + name + "'");
}

TemporalFrame temporal_frame(const FrameBuffer& fb, const std::string& name) {
    TemporalFrame fr;
    fr.name = name;
    const std::pair<Image*, const char*> layers[] = {
        {&fr.primal, temporal_layers::primal}, {&fr.dx, temporal_layers::dx},     {&fr.dy, temporal_layers::dy},
        {&fr.direct, temporal_layers::direct}, {&fr.dt, temporal_layers::dt},     {&fr.motion, temporal_layers::motion},
        {&fr.valid, temporal_layers::valid}};
    for (const auto& [img, layer] : layers)
        if (fb.has(layer)) *img = fb.get(layer);
    for (const char* layer : {temporal_layers::primal, temporal_layers::dx, temporal_layers::dy})
        if (!fb.has(layer)) {
            std::string list;
            for (const auto& n : fb.names()) list += (list.empty() ? "" : ", ") + n;
            throw InputError("frame '" + name + "': no layer '" + layer + "' (layers: " + (list.empty() ? "none" : list) +
                             ")");
        }
    check_temporal_frame(fr);
    return fr;
}

bool has_temporal_halves(const FrameBuffer& frame, const FrameBuffer& next) {
    return frame.has(temporal_layers::primal_b) && next.has(temporal_layers::primal_a) &&
           next.has(temporal_layers::replay);
}

void add_temporal_difference(FrameBuffer& frame, const FrameBuffer& next, const std::string& name,
                             const std::string& next_name) {
    const auto layer = [](const FrameBuffer& fb, const std::string& who, const char* l, int channels,
                          const Image* like) -> const Image& {
        if (!fb.has(l)) throw InputError("frame '" + who + "': no layer '" + l + "' (a tgpt frame has it)");
        const Image& im = fb.get(l);
        if (im.channels() != channels || (like && (im.width() != like->width() || im.height() != like->height())))
            throw InputError("frame '" + who + "': layer '" + l + "' is " + shape_text(im) + ", not " +
                             std::to_string(like ? like->width() : im.width()) + "x" +
                             std::to_string(like ? like->height() : im.height()) + " with " +
                             std::to_string(channels) + " channels");
        return im;
    };
    const Image& b = layer(frame, name, temporal_layers::primal_b, 3, nullptr);
    const Image& a = layer(next, next_name, temporal_layers::primal_a, 3, &b);
    const Image& replay = layer(next, next_name, temporal_layers::replay, 2, &b);
    const Image* motion = frame.has(temporal_layers::motion) ? &layer(frame, name, temporal_layers::motion, 2, &b)
                                                             : nullptr;
    const int W = b.width(), H = b.height();
    Image dt(W, H, 3), valid(W, H, 1);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            // The same rounding as the solver's temporal rows (half away from zero).
            const int qx = x + (motion ? int(std::lround(motion->at(x, y, 0))) : 0);
            const int qy = y + (motion ? int(std::lround(motion->at(x, y, 1))) : 0);
            if (qx < 0 || qy < 0 || qx >= W || qy >= H) continue;
            if (replay.at(qx, qy, 0) != float(x) || replay.at(qx, qy, 1) != float(y)) continue;
            dt.set_rgb(x, y, a.rgb(qx, qy) - b.rgb(x, y));
            valid.at(x, y, 0) = 1.f;
        }
    frame.set(temporal_layers::dt, std::move(dt));
    frame.set(temporal_layers::valid, std::move(valid));
}

TemporalReconstructor::TemporalReconstructor(const TemporalOptions& options) : opt_(options) {
    check_temporal_options(opt_);
}

void TemporalReconstructor::push(TemporalFrame frame) {
    if (finished_) throw ParameterError("TemporalReconstructor: push() after finish()");
    check_temporal_frame(frame);
    if (pushed_ > 0) {
        const TemporalFrame& prev = inputs_.back();
        if (!frame.primal.same_shape(prev.primal))
            throw InputError("frame '" + frame.name + "': primal is " + shape_text(frame.primal) +
                             " but the previous frame '" + prev.name + "' is " + shape_text(prev.primal));
        if (opt_.require_dt && prev.dt.empty() && opt_.w_t > 0)
            throw InputError("frame '" + prev.name + "': no layer '" + temporal_layers::dt + "', but frame '" +
                             frame.name + "' follows it (require_dt=false treats this as a cut)");
    }
    inputs_.push_back(std::move(frame));
    ++pushed_;
    if (pushed_ - next_window_ == opt_.window) {
        solve_window(next_window_, opt_.window);
        next_window_ += opt_.step;
        // No later window covers frames before next_window_.
        finalise_until(next_window_);
    }
}

void TemporalReconstructor::finish() {
    if (finished_) return;
    finished_ = true;
    if (covered_ < pushed_) solve_window(next_window_, pushed_ - next_window_);
    finalise_until(pushed_);
}

void TemporalReconstructor::solve_window(int first, int count) {
    std::vector<TemporalFrameView> views;
    for (int f = first; f < first + count; ++f) views.push_back(inputs_[size_t(f - input_base_)].view());
    const TemporalFrame& head = inputs_[size_t(first - input_base_)];
    const size_t len = head.primal.values().size();
    std::vector<std::vector<float>> solved(count, std::vector<float>(len));
    std::vector<float*> out;
    for (auto& s : solved) out.push_back(s.data());
    TemporalReport rep;
    try {
        rep = solve_temporal_window(views, opt_, out);
    } catch (const RuntimeFailure& e) {
        throw RuntimeFailure("frames '" + head.name + "' to '" + inputs_[size_t(first + count - 1 - input_base_)].name +
                             "': " + e.what());
    }
    reports_.emplace_back(first, rep);
    for (int f = first; f < first + count; ++f) {
        while (blend_base_ + int(blends_.size()) <= f) {
            Blend b;
            const TemporalFrame& src = inputs_[size_t(blend_base_ + int(blends_.size()) - input_base_)];
            b.sum.assign(len, 0.f);
            b.width = src.primal.width(), b.height = src.primal.height(), b.channels = src.primal.channels();
            b.direct = src.direct;
            blends_.push_back(std::move(b));
        }
        Blend& b = blends_[size_t(f - blend_base_)];
        const double wgt = hann(f, first, count);
        const std::vector<float>& s = solved[f - first];
        for (size_t i = 0; i < len; ++i) b.sum[i] += float(wgt) * s[i];
        b.weight += wgt;
    }
    covered_ = std::max(covered_, first + count);
    // Inputs before the next window's start are no longer needed.
    const int keep_from = std::min(first + opt_.step, pushed_);
    while (input_base_ < keep_from && !inputs_.empty()) inputs_.pop_front(), ++input_base_;
}

void TemporalReconstructor::finalise_until(int end) {
    while (blend_base_ < end && !blends_.empty()) {
        Blend& b = blends_.front();
        Image img;
        const float inv = float(1.0 / b.weight);
        if (!b.direct.empty()) {
            img = b.direct;
            float* o = img.data();
            for (size_t i = 0; i < b.sum.size(); ++i) o[i] += b.sum[i] * inv;
        } else {
            img = Image(b.width, b.height, b.channels);
            float* o = img.data();
            for (size_t i = 0; i < b.sum.size(); ++i) o[i] = b.sum[i] * inv;
        }
        check_finite_result(ImageView{img.data(), img.width(), img.height(), img.channels()},
                            "temporal reconstruction, frame " + std::to_string(blend_base_));
        ready_.push_back(std::move(img));
        blends_.pop_front();
        ++blend_base_;
    }
}

bool TemporalReconstructor::ready() const { return !ready_.empty(); }

Image TemporalReconstructor::pop() {
    if (ready_.empty()) throw ParameterError("TemporalReconstructor: pop() with no finished frame");
    Image img = std::move(ready_.front());
    ready_.pop_front();
    ++popped_;
    return img;
}

int TemporalReconstructor::frames_pushed() const { return pushed_; }
int TemporalReconstructor::frames_popped() const { return popped_; }
int TemporalReconstructor::held_frames() const { return int(inputs_.size()); }
int TemporalReconstructor::pending_blends() const { return int(blends_.size()); }
const std::vector<std::pair<int, TemporalReport>>& TemporalReconstructor::reports() const { return reports_; }

std::string frame_path(const std::string& pattern, int frame) {
    size_t conv = std::string::npos, conv_end = 0;
    for (size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] != '%') continue;
        if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
            ++i;
            continue;
        }
        size_t j = i + 1;
        while (j < pattern.size() && (pattern[j] == '0' || pattern[j] == '-' || pattern[j] == '+' || pattern[j] == ' '))
            ++j;
        while (j < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[j]))) ++j;
        if (j >= pattern.size() || pattern[j] != 'd' || conv != std::string::npos)
            throw ParameterError("frame pattern '" + pattern +
                                 "' must hold exactly one integer conversion such as %d or %04d (and %% for '%')");
        conv = i, conv_end = j + 1;
        i = j;
    }
    if (conv == std::string::npos)
        throw ParameterError("frame pattern '" + pattern + "' holds no frame number conversion (%d, %04d)");
    const std::string spec = pattern.substr(conv, conv_end - conv);
    // Sized to the number, so that no width is cut short (a cut number would
    // give every frame one name); a width no path could hold is refused.
    const int need = std::snprintf(nullptr, 0, spec.c_str(), frame);
    if (need < 0 || need > 4096)
        throw ParameterError("frame pattern '" + pattern + "': its frame number would be wider than 4096 characters");
    std::string buf(size_t(need) + 1, '\0');
    std::snprintf(buf.data(), buf.size(), spec.c_str(), frame);
    buf.resize(size_t(need));
    std::string out;
    for (size_t i = 0; i < pattern.size(); ++i) {
        if (i == conv) {
            out += buf;
            i = conv_end - 1;
        } else if (pattern[i] == '%') {
            out += '%';
            ++i;  // "%%"
        } else {
            out += pattern[i];
        }
    }
    return out;
}

}  // namespace gdr
