#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <mutex>
#include <optional>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/cli/plugins.h"
#include "frames.h"
#include "output_lock.h"
#include "render_options.h"
#include "say.h"
#include "stop.h"
#include "gdr/core/error.h"
#include "gdr/integrators/adaptive.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"
#include "gdr/io/scene_file.h"
#include "gdr/scene/animated_scene.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/shift/shift.h"

namespace gdr::cli {

namespace {

// Prints progress: a redrawn bar on a terminal, a plain line every 10% otherwise.
class ProgressPrinter {
public:
    ProgressPrinter() : tty_(isatty(fileno(stderr)) != 0) {}
    void operator()(const Progress& p) {
        std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
        if (!lock.owns_lock()) return;
        const double rate = p.seconds > 0 ? double(p.samples) / p.seconds : 0.0;
        const double eta = p.fraction > 0 ? p.seconds * (1.0 - p.fraction) / p.fraction : 0.0;
        if (tty_) {
            if (p.seconds - last_ < 0.1 && p.fraction < 1.0) return;
            last_ = p.seconds;
            const int width = 30, filled = int(p.fraction * width);
            say("\r[{}{}] {:5.1f}%  {:.2f} M samples/s  ETA {:.1f} s   ", std::string(filled, '#'),
                std::string(width - filled, '.'), 100.0 * p.fraction, rate * 1e-6, eta);
        } else {
            const int decile = int(p.fraction * 10.0);
            if (decile <= last_decile_) return;
            last_decile_ = decile;
            say("progress {:3d}%  {:.2f} M samples/s  ETA {:.1f} s\n", decile * 10, rate * 1e-6, eta);
        }
    }
    void finish() {
        if (tty_) say("\n");
    }

private:
    std::mutex mutex_;
    bool tty_;
    double last_ = -1.0;
    int last_decile_ = 0;
};

}  // namespace

// True if the --set assignment names a key of the scene rather than of the integrator.
bool is_scene_key(const std::string& assignment) { return assignment.substr(0, assignment.find('=')) == "fov"; }

void apply_scene_setting(SceneFile& sf, const std::string& assignment) {
    const size_t eq = assignment.find('=');
    const std::string key = assignment.substr(0, eq), value = eq == std::string::npos ? "" : assignment.substr(eq + 1);
    const double fov = ArgReader::parse_real("--set " + key, value);
    if (!(fov > 0.0 && fov < 180.0))
        throw ParameterError("--set " + key + ": the field of view must lie between 0 and 180 degrees, got '" + value + "'");
    set_fov(sf, float(fov));
}

void add_define(SceneFileOptions& options, const std::string& assignment) {
    // A Mitsuba scene's $parameter, as Mitsuba's own tool takes it.
    const size_t eq = assignment.find('=');
    if (eq == 0 || eq == std::string::npos)
        throw ParameterError("option -D expects name=value, got '" + assignment + "'");
    options.defines[assignment.substr(0, eq)] = assignment.substr(eq + 1);
}

std::pair<int, int> parse_resolution(const std::string& v) {
    const size_t x = v.find_first_of("xX");
    if (x == std::string::npos) throw ParameterError("option --resolution expects WIDTHxHEIGHT, got '" + v + "'");
    return {int(ArgReader::parse_int("--resolution", v.substr(0, x), 1, kMaxResolution)),
            int(ArgReader::parse_int("--resolution", v.substr(x + 1), 1, kMaxResolution))};
}

namespace {

// One frame of `gdr render --frame(s)`: its number, and the scene loaded for
// the first frame rendered (the OBJs are read once for all frames).
struct FrameJob {
    int frame = 0;
    SceneFile* scene = nullptr;
    std::pair<int, int> range;  ///< every frame of the command (--frames FIRST:LAST), checked before the first render
    std::string option;         ///< "--frames A:B" or "--frame K", for messages
};

// gdr render of one image: a still, or the frame `job` of an animation.
int render_one(const std::vector<std::string>& args, FrameJob* job) {
    // A closed pipe on stderr (`2>&1 | head -1`) must not kill a render: its
    // messages are optional, its file is not (say() ignores failed writes).
    struct IgnorePipe {
        void (*old)(int) = std::signal(SIGPIPE, SIG_IGN);
        ~IgnorePipe() { std::signal(SIGPIPE, old); }
    } ignore_pipe;
    ArgReader a{args};
    std::string scene_path, out_path, integrator_name, resume_path;
    long long spp = -1, seed = -1, first_sample = -1;
    bool continue_part = false;  // --continue: render OUT, or continue the OUT already there
    int width = 0, height = 0;
    double time_budget = 0.0, exposure = 0.0, adaptive = 0.0, select_gradients = 0.0;
    int threads = 0;
    std::vector<std::string> sets, scene_sets;
    SceneFileOptions scene_options;
    while (a.more()) {
        const std::string opt = a.next();
        if (opt == "-h" || opt == "--help") return print_usage("render");
        if (opt == "-o" || opt == "--output") out_path = a.value(opt);
        else if (opt == "--integrator") integrator_name = a.value(opt);
        else if (opt == "--spp") spp = a.int_value(opt, 1, std::numeric_limits<long long>::max());
        else if (opt == "--time") {
            const std::string v = a.value(opt);
            time_budget = ArgReader::parse_real(opt, v);
            if (!(time_budget > 0.0)) throw ParameterError("option --time must be positive, got '" + v + "'");
        } else if (opt == "--threads") threads = int(a.int_value(opt, 0, kMaxThreads));
        else if (opt == "--seed") seed = a.int_value(opt, 0, std::numeric_limits<long long>::max());
        else if (opt == "--first-sample") first_sample = a.int_value(opt, 0, std::numeric_limits<long long>::max());
        else if (opt == "--continue") continue_part = true;
        else if (opt == "--width") width = int(a.int_value(opt, 1, kMaxResolution));
        else if (opt == "--height") height = int(a.int_value(opt, 1, kMaxResolution));
        else if (opt == "--resolution") std::tie(width, height) = parse_resolution(a.value(opt));
        else if (opt == "--set") {
            const std::string v = a.value(opt);
            // Keys of the scene rather than of the integrator.
            (is_scene_key(v) ? scene_sets : sets).push_back(v);
        } else if (opt == "-D") add_define(scene_options, a.value(opt));
        else if (opt == "--lenient") scene_options.lenient = true;
        else if (opt == "--resume") resume_path = a.value(opt);
        else if (opt == "--exposure") exposure = a.real_value(opt);
        else if (opt == "--adaptive") {
            const std::string v = a.value(opt);
            adaptive = ArgReader::parse_real(opt, v);
            if (!(adaptive > 0.0 && adaptive <= 0.5))
                throw ParameterError("option --adaptive takes the pilot's share of the budget, above 0 and at most 0.5, "
                                     "got '" + v + "'");
        } else if (opt == "--select-gradients") {
            const std::string v = a.value(opt);
            select_gradients = ArgReader::parse_real(opt, v);
            if (!(select_gradients > 0.0 && select_gradients <= 0.5))
                throw ParameterError("option --select-gradients takes the pilots' share of the budget, above 0 and at "
                                     "most 0.5, got '" + v + "'");
        }
        else if (!opt.empty() && opt[0] == '-') throw ParameterError("render: unknown option '" + opt + "'\n" + usage("render"));
        else if (scene_path.empty()) scene_path = opt;
        else throw ParameterError("render: unexpected argument '" + opt + "'");
    }
    if (scene_path.empty()) throw ParameterError("render: no scene file given\n" + usage("render"));
    if (out_path.empty()) throw ParameterError("render: no output given (-o OUT.exr)");
    if (spp > 0 && time_budget > 0.0) throw ParameterError("render: give either --spp or --time, not both");
    if (first_sample >= 0 && !resume_path.empty())
        throw ParameterError("render: --first-sample starts a sequence at a given sample, --resume continues " +
                             resume_path + "'s; give one of them");
    if (continue_part && !resume_path.empty())
        throw ParameterError("render: --continue resumes OUT itself; it takes no --resume");
    if (adaptive > 0.0 && select_gradients > 0.0)
        throw ParameterError("render: --adaptive and --select-gradients are two uses of a pilot; give one of them");
    const std::string pilot_option = select_gradients > 0.0 ? "--select-gradients" : "--adaptive";
    if (select_gradients > 0.0) adaptive = select_gradients;
    if (adaptive > 0.0 && (first_sample >= 0 || continue_part))
        throw ParameterError("render: " + pilot_option + " chooses each render's density from its own pilot, so parts of one "
                             "seed (--first-sample, --continue) would not continue each other's samples; render "
                             "parts with different seeds instead (gdr merge pools them pixel by pixel)");
    if (adaptive > 0.0 && !resume_path.empty())
        throw ParameterError("render: --resume continues " + resume_path +
                             " with its own sample density and gradient mask (if it has them); it takes no " +
                             pilot_option);
    if (continue_part && time_budget > 0.0)
        throw ParameterError("render: --continue renders a part of a fixed sample count (--spp), not --time");
    check_output_path(out_path);
    // Held to the end: a second run to OUT (another --continue of the same
    // part) is refused rather than replacing this one's samples, or this its.
    const OutputLock lock(out_path, "gdr render");
    // --continue: an OUT already there is a part of this render to finish in
    // place (the write goes through a temporary renamed over it, so an
    // interrupted write keeps the old part).
    std::error_code exists_ec;
    const bool in_place = continue_part && std::filesystem::exists(out_path, exists_ec);
    if (in_place) resume_path = out_path;
    check_not_an_input(out_path, {scene_path, in_place ? std::string() : resume_path});
    // What OUT held when read ("" for none), taken before reading it: before
    // replacing it, --continue checks that nothing changed it meanwhile (a
    // run where the lock is not honoured, a copy), whose samples would be lost.
    const std::string read_digest = continue_part ? file_digest(out_path) : "";

    // Resuming continues the previous render's sample sequence, so the merged
    // image equals one longer render. Everything about it is checked before
    // rendering, so that a bad entry cannot cost the new samples.
    StoredRender previous;
    if (!resume_path.empty()) {
        previous = read_stored_render(resume_path);
        if (previous.ranges.size() != 1)
            throw InputError(resume_path + ": merged from renders with different seeds (sample_ranges " +
                             format_sample_ranges(previous.ranges) +
                             "), so it holds no single sample sequence to continue; render more with a new seed and "
                             "merge the parts (gdr merge)");
    }

    const auto t_load = std::chrono::steady_clock::now();
    SceneFile local;
    SceneFile& sf = job && job->scene ? *job->scene : local;
    if (!sf.scene) {
        sf = load_scene_file(scene_path, scene_options);
        for (const std::string& w : sf.warnings) say("warning: {}\n", w);
        for (const std::string& s : scene_sets) apply_scene_setting(sf, s);
        if (width > 0 || height > 0) set_resolution(sf, width, height);
    }
    // An animation renders one frame (its first, unless --frame says which):
    // the frame's own scene, seed and motion layers.
    std::optional<int> frame;
    if (job) {
        if (!sf.animation)
            throw InputError(scene_path + ": --frame and --frames need a scene with an 'animation' block (frames)");
        // The whole range before the first frame renders: a frame past the
        // animation's end must not cost the frames before it their time.
        const AnimationRange& r = sf.animation->range();
        if (job->range.first < r.first || job->range.second > r.last) {
            const int missing = job->range.first < r.first ? job->range.first : std::max(job->range.first, r.last + 1);
            throw ParameterError(fmt::format("render {}: frame {} is outside the animation of {} (frames {} to {}); "
                                             "nothing was rendered",
                                             job->option, missing, scene_path, r.first, r.last));
        }
        frame = job->frame;
    } else if (sf.animation) {
        frame = sf.animation->range().first;
    }
    if (frame) set_frame(sf, *frame);
    const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count();
    check_not_an_input(out_path, sf.inputs);
    // The seed of a frame depends on the frame alone, so that any subset of
    // frames, in any order or process, renders the same files.
    const auto frame_seed_of = [&](uint64_t s) { return frame ? frame_seed(s, *frame) : s; };

    // A resumed render is continued with its own integrator and parameters;
    // --integrator and --set may only repeat them.
    const std::string name = !integrator_name.empty() ? integrator_name
                             : !resume_path.empty()   ? previous.fb.metadata().at("integrator")
                                                      : sf.defaults.integrator;
    std::string origin = resume_path.empty() ? sf.defaults.params.context() : resume_path + " (integrator_params)";
    for (size_t i = 0; i < sets.size(); ++i) origin += (i ? ", --set " : " with --set ") + sets[i];
    Params params(origin);
    if (resume_path.empty())
        for (const auto& [k, v] : sf.defaults.params.values()) params.set(k, v);
    else {
        const Params stored = stored_params(previous);
        for (const auto& [k, v] : stored.values()) params.set(k, v);
    }
    for (const auto& s : sets) params.set_from_text(s);
    require_integrator(name, "gdr render --integrator " + name);
    require_plugins_of(params, "gdr render");
    auto integrator = integrator_registry().create(name, params);

    const auto& cam = sf.scene->camera();
    RenderIdentity identity;
    identity.integrator = name;
    identity.params = integrator->describe();
    identity.width = cam.width(), identity.height = cam.height();
    identity.scene = std::filesystem::absolute(scene_path).string();
    identity.scene_hash = sf.content_hash;
    if (frame) identity.frame = std::to_string(*frame);

    RenderSettings st;
    st.threads = threads;
    const uint64_t base_seed = uint64_t(seed >= 0 ? seed : sf.defaults.seed);
    st.seed = frame_seed_of(base_seed);
    st.first_sample = first_sample >= 0 ? first_sample : 0;
    st.cancel = &stop_flag();
    st.abort = &abort_flag();
    // What the file records as asked for: the number one past the last
    // sample of the sequence (its samples per pixel when it starts at 0).
    uint64_t target_spp = 0;
    double target_time = 0.0;
    if (resume_path.empty()) {
        st.spp = spp > 0 ? spp : sf.defaults.spp;
        if (st.first_sample > std::numeric_limits<long long>::max() - st.spp)
            throw ParameterError(fmt::format("--first-sample {} with {} spp runs past the last sample number",
                                             st.first_sample, st.spp));
        st.time_budget = time_budget;
        if (time_budget > 0.0) target_time = time_budget;
        else target_spp = uint64_t(st.first_sample + st.spp);
    } else {
        check_same_render(identity_of(previous), resume_path, identity, scene_path);
        if (in_place) {
            // The part must be the one asked for: the same seed (given or the
            // scene's) and first sample; otherwise two renders would be mixed.
            if (st.seed != previous.seed || uint64_t(st.first_sample) != previous.first_sample)
                throw InputError(fmt::format("{}: holds samples {}-{} of seed {}, not a part starting at sample {} of "
                                             "seed {}; remove it or render to another file",
                                             out_path, previous.first_sample, previous.first_sample + previous.spp - 1,
                                             previous.seed, st.first_sample, st.seed));
            if (spp < 0) spp = sf.defaults.spp;
        } else if (seed >= 0 && frame_seed_of(uint64_t(seed)) != previous.seed)
            throw InputError(resume_path + ": rendered with seed " + std::to_string(previous.seed) + ", not " +
                             std::to_string(frame_seed_of(uint64_t(seed))) +
                             (frame ? " (frame " + std::to_string(*frame) + " of seed " + std::to_string(seed) + ")" : ""));
        st.seed = previous.seed;
        if (previous.fb.has("sample_density")) st.sample_density = &previous.fb.get("sample_density");
        if (previous.fb.has("gradient_mask")) st.gradient_mask = &previous.fb.get("gradient_mask");
        const auto mixed = previous.fb.metadata().find("sample_density");
        if (mixed != previous.fb.metadata().end() && mixed->second == "mixed")
            throw InputError(resume_path + ": merged from adaptive renders with different sample densities, so no "
                             "one density continues its pixels' sample numbers; render more with a new seed and "
                             "merge the parts (gdr merge)");
        const uint64_t reached = previous.first_sample + previous.spp;  // the next sample number to take
        st.first_sample = (long long)reached;
        // --spp and --time give a new total; without them the stored target is finished.
        const auto nothing_left = [&](const std::string& what) {
            say("{}: already holds {}; nothing to render (give --spp N or --time T for a new total)\n", resume_path, what);
        };
        if (in_place && uint64_t(spp) == previous.spp) {
            // A part that is complete: a re-run task does nothing.
            say("{}: already holds its {} spp (samples {}-{} of seed {}); nothing to render\n", out_path, spp,
                previous.first_sample, reached - 1, previous.seed);
            return 0;
        }
        if (spp > 0) {
            if (uint64_t(spp) <= previous.spp)
                throw ParameterError(fmt::format("--spp {} is the new total, but {} already holds {} spp", spp,
                                                 resume_path, previous.spp));
            st.spp = spp - (long long)previous.spp;
            target_spp = previous.first_sample + uint64_t(spp);
        } else if (time_budget > 0.0) {
            if (time_budget <= previous.seconds)
                throw ParameterError(fmt::format("--time {} is the new total, but {} already took {:.3f} s", time_budget,
                                                 resume_path, previous.seconds));
            st.time_budget = time_budget - previous.seconds;
            target_time = time_budget;
        } else if (previous.target_spp > 0) {
            if (previous.target_spp <= reached) {
                nothing_left(fmt::format("its target of {} spp", previous.target_spp - previous.first_sample));
                return 0;
            }
            st.spp = (long long)(previous.target_spp - reached);
            target_spp = previous.target_spp;
        } else if (previous.time_budget > 0.0) {
            if (previous.time_budget <= previous.seconds) {
                nothing_left(fmt::format("its target of {} s", previous.time_budget));
                return 0;
            }
            st.time_budget = previous.time_budget - previous.seconds;
            target_time = previous.time_budget;
        } else {
            throw ParameterError(resume_path + " records no target sample count or time: give --spp N (the new total) "
                                 "or --time T");
        }
    }

    // Seed sharing (tgpt): the next frame's seed, and which pixel of the
    // previous frame each pixel replays; both follow from the frame alone.
    FrameSampling frame_sampling;
    if (frame && integrator->shares_frame_samples()) {
        uint64_t frame_base = base_seed;
        if (!resume_path.empty()) {
            const auto it = previous.fb.metadata().find("frame_base_seed");
            if (it == previous.fb.metadata().end() || it->second.empty() ||
                it->second.find_first_not_of("0123456789") != std::string::npos || it->second.size() > 19)
                throw InputError(resume_path + ": no valid 'frame_base_seed' entry, which a frame of " + name +
                                 " needs");
            frame_base = uint64_t(std::stoull(it->second));
        }
        const auto t_replay = std::chrono::steady_clock::now();
        frame_sampling.next_seed = frame_seed(frame_base, *frame + 1);
        frame_sampling.replay = replay_map(*sf.animation, *sf.scene, *frame);
        st.frame_sampling = &frame_sampling;
        say("seed sharing with frames {} and {} prepared in {:.3f} s\n", *frame - 1, *frame + 1,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t_replay).count());
    }

    const auto& ss = sf.scene->stats();
    say("scene {}{}: {} triangles ({} degenerate skipped), {} emitting, {}x{}, {} in {:.2f} s\n", scene_path,
        frame ? fmt::format(" frame {}", *frame) : "", ss.triangles, ss.degenerate_skipped, ss.emitters, cam.width(),
        cam.height(), frame ? "loaded and built" : "loaded", load_s);
    // Per mesh, so that a truncated file shows.
    for (const MeshStats& m : sf.meshes) say("  {}: {} triangles\n", m.file, m.triangles);
    if (!sf.scene->has_lights()) say("warning: the scene has no emitters; the image will be black\n");
    if (!resume_path.empty())
        say("resuming {}: {} spp held, {}\n", resume_path, previous.spp,
            st.time_budget > 0.0 ? fmt::format("{:.3f} s more", st.time_budget) : fmt::format("{} spp more", st.spp));

    // While sampling, a stop signal only stops the sampling: the samples
    // taken so far are then written (or rescued).
    std::optional<PolledStop> polled(std::in_place);
    FrameBuffer fb;
    RenderStats rs;
    {
        ProgressPrinter printer;
        try {
            const ProgressFn show = [&](const Progress& p) { printer(p); };
            if (adaptive > 0.0) {
                AdaptiveRender ad;
                ad.pilot = adaptive;
                if (select_gradients > 0.0) ad.mode = AdaptiveRender::Mode::SelectGradients;
                rs = render_adaptive(*integrator, *sf.scene, st, fb, ad, show);
            } else {
                rs = integrator->render(*sf.scene, st, fb, show);
            }
        } catch (const Interrupted& e) {
            printer.finish();
            say("stopped: {}\n", e.what());
            return stop_status() ? stop_status() : 128 + SIGINT;
        }
        printer.finish();
    }

    const bool interrupted = stop_flag() || abort_flag();
    // Sampling is over: from here a stop signal lets the file be finished
    // (or the rescue file written) and then ends the run. Taken before the
    // polled scope ends, so that no moment is left uncovered.
    const WriteSection writing;
    polled.reset();
    if (frame) {
        // In the driver, not the integrators: every integrator's frames get them.
        const auto t_motion = std::chrono::steady_clock::now();
        add_motion_layers(fb, *sf.animation, *sf.scene, *frame);
        say("motion vectors and object ids of frame {} in {:.3f} s\n", *frame,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t_motion).count());
    }
    auto& meta = fb.metadata();
    if (frame) {
        meta["frame"] = std::to_string(*frame);
        meta["frame_base_seed"] = std::to_string(base_seed);
        meta["fps"] = fmt::format("{}", sf.animation->range().fps);
    }
    RenderRecord record;
    record.integrator = name;
    record.scene = identity.scene;
    record.scene_hash = identity.scene_hash;
    record.seconds = rs.seconds;
    record.time_budget = st.time_budget;
    // An adaptive render's target is the passes after its pilot's share.
    const long long pilot_spp = adaptive > 0.0 && st.time_budget <= 0.0 ? std::stoll(meta.at("adaptive_pilot_spp")) : 0;
    if (st.time_budget <= 0.0) record.target_spp = uint64_t(st.first_sample + st.spp - pilot_spp);
    record.samples = {st.seed, uint64_t(st.first_sample), uint64_t(rs.spp)};
    record.version = version();
    record.interrupted = interrupted;
    write_render_record(fb, record);
    // From here on a failure must not lose the samples: the new part alone is
    // a valid render (gdr merge or --resume take it) and goes to the rescue file.
    FrameBuffer new_part;  // --continue: the new samples alone, for the rescue file
    try {
        if (continue_part) new_part = fb;
        if (!resume_path.empty()) {
            FrameBuffer merged = previous.fb;
            merge_renders(merged, fb);
            integrator->update_merged(merged);
            auto& mm = merged.metadata();
            // The merged image is as complete as its last part.
            mm["interrupted"] = meta["interrupted"];
            mm["render_seconds"] = fmt::format("{:.3f}", previous.seconds + rs.seconds);
            std::vector<SampleRange> ranges = previous.ranges;
            ranges.push_back({st.seed, uint64_t(st.first_sample), uint64_t(rs.spp)});
            mm["sample_ranges"] = format_sample_ranges(normalized_ranges(ranges));
            mm["time_budget"] = fmt::format("{}", target_time);
            if (target_spp > 0) mm["target_spp"] = std::to_string(target_spp);
            else mm.erase("target_spp");
            if (!identity.scene_hash.empty()) mm["scene_hash"] = identity.scene_hash;
            mm["gdr_version"] = version();
            fb = std::move(merged);
        }
    } catch (const Error& e) {
        write_exr_or_rescue(rescue_path(), fb);
        throw RuntimeFailure(std::string(e.what()) + "\nthe new samples were saved to " + rescue_path() +
                             " (gdr merge accepts it)");
    }
    if (continue_part) {
        if (const std::string now = file_digest(out_path); now != read_digest) {
            std::string held = "it is gone";
            if (!now.empty()) {
                try {
                    held = fmt::format("it now holds {} spp", read_stored_render(out_path).spp);
                } catch (const Error&) {
                    held = "it is no longer a render gdr can read";
                }
            }
            write_exr_or_rescue(rescue_path(), new_part);
            throw RuntimeFailure(fmt::format("refusing to replace {}: it changed while this run continued it (it held {} "
                                             "when read; {}), and its samples would be lost; the new samples were saved "
                                             "to {} (gdr merge accepts it)",
                                             out_path, read_digest.empty() ? "nothing" : fmt::format("{} spp", previous.spp),
                                             held, rescue_path()));
        }
    }
    const std::string preview = write_render(out_path, fb, float(exposure));

    say("{} {} spp in {:.2f} s: {:.2f} M samples/s, {:.2f} M rays/s\n", interrupted ? "interrupted after" : "rendered",
        rs.spp, rs.seconds, rs.samples / std::max(1e-9, rs.seconds) * 1e-6, rs.rays / std::max(1e-9, rs.seconds) * 1e-6);
    if (rs.nonfinite) {
        std::string where;
        for (auto [x, y] : rs.nonfinite_pixels) where += fmt::format(" ({}, {})", x, y);
        say("warning: {} NaN/Inf samples were dropped, first at pixels{}\n", rs.nonfinite, where);
    } else {
        say("no NaN/Inf samples\n");
    }
    std::string layers;
    for (const auto& n : fb.names()) layers += " " + n;
    say("wrote {} (layers:{}){}\n", out_path, layers, preview.empty() ? "" : " and " + preview);
    if (abort_flag() && fb.has("dx") && !fb.has("reconstruction_weighted") && !fb.has("reconstruction_l1") &&
        !fb.has("reconstruction_l2"))
        say("the reconstructions were skipped to stop at once: gdr reconstruct {} computes one, and --resume or "
            "gdr merge recompute them\n", out_path);
    // The shell's convention, also for a signal that came during the write.
    return stop_status();
}

}  // namespace

int render(const std::vector<std::string>& args) {
    // --frame K and --frames A:B make one independent render per frame; the
    // other options apply to each, -o and --resume through their %d pattern.
    std::vector<std::string> rest;
    std::optional<std::pair<int, int>> frames;
    std::string frames_opt;
    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& o = args[i];
        if (o == "--frame" || o == "--frames") {
            if (i + 1 >= args.size()) throw ParameterError("option " + o + " needs a value");
            if (frames) throw ParameterError("render: give one of --frame and --frames, once");
            const std::string v = args[++i];
            if (o == "--frame") {
                const int k = int(ArgReader::parse_int(o, v, -(1LL << 30), 1LL << 30));
                frames = std::make_pair(k, k);
            } else {
                frames = parse_frame_range(o, v);
            }
            frames_opt = o + " " + v;
            continue;
        }
        if (o == "-h" || o == "--help") return print_usage("render");
        rest.push_back(o);
        // An option's value is never taken for --frame(s).
        if ((o == "-o" || o == "--output" || o == "--resume" || o == "--set" || o == "-D") && i + 1 < args.size())
            rest.push_back(args[++i]);
    }
    if (!frames) return render_one(args, nullptr);
    const bool several = frames->second > frames->first;
    std::vector<size_t> patterned;  // positions in `rest` of the values of -o and --resume
    for (size_t i = 0; i + 1 < rest.size(); ++i)
        if (rest[i] == "-o" || rest[i] == "--output" || rest[i] == "--resume") {
            patterned.push_back(i + 1);
            if (several && !has_frame_pattern(rest[i + 1]))
                throw ParameterError("render " + frames_opt + ": " + rest[i] + " '" + rest[i + 1] +
                                     "' has no frame number pattern (%04d) for the frames to go to different files");
            (void)frame_path(rest[i], rest[i + 1], frames->first);  // a malformed pattern fails before any render
            ++i;
        }
    SceneFile scene;  // loaded by the first frame, then shared
    for (int k = frames->first; k <= frames->second; ++k) {
        std::vector<std::string> a = rest;
        for (size_t i : patterned) a[i] = frame_path(a[i - 1], rest[i], k);
        FrameJob job{k, &scene, *frames, frames_opt};
        const int rc = render_one(a, &job);
        if (rc != 0) return rc;  // interrupted: the frames after it are not started
    }
    return 0;
}

int info(const std::vector<std::string>& args) {
    if (args.size() == 1 && (args[0] == "-h" || args[0] == "--help")) return print_usage("info");
    if (args.size() != 1) throw ParameterError("info: expected one EXR file\n" + usage("info"));
    const FrameBuffer fb = read_exr(args[0]);
    // A file that claims to be a render must hold what every render holds:
    // a damaged header otherwise reads as an image of zeros with no settings.
    if (looks_like_render(fb)) {
        check_render_settings(fb, args[0]);
        (void)read_stored_render(args[0]);
    }
    size_t name_w = 0, key_w = 0;
    for (const auto& n : fb.names()) name_w = std::max(name_w, n.size());
    for (const auto& [k, v] : fb.metadata()) key_w = std::max(key_w, k.size());
    fmt::print("{}: {}x{}\nlayers:\n", args[0], fb.width(), fb.height());
    for (const auto& n : fb.names()) {
        const Image& img = fb.get(n);
        double mean = 0.0;
        for (float v : img.values()) mean += v;
        mean /= double(std::max<size_t>(1, img.values().size()));
        fmt::print("  {:<{}}  {} channel{:<1}  mean {:.6g}\n", n, name_w, img.channels(), img.channels() > 1 ? "s" : "",
                   mean);
    }
    if (!fb.metadata().empty()) {
        fmt::print("settings:\n");
        for (const auto& [k, v] : fb.metadata()) {
            // Multi-line values (integrator parameters) continue under their first line.
            std::string vv;
            for (char c : v) vv += c == '\n' ? "\n  " + std::string(key_w + 3, ' ') : std::string(1, c);
            while (!vv.empty() && vv.back() == ' ') vv.pop_back();
            while (!vv.empty() && vv.back() == '\n') vv.pop_back();
            fmt::print("  {:<{}} = {}\n", k, key_w, vv);
        }
    }
    return 0;
}

int list_plugins() {
    // The plugins' names too: loading them costs libtorch's start-up time
    // (the neural plugin), which a listing may spend.
    const PluginLoad& plugins = load_plugins();
    // Each integrator's parameters with their defaults, as its describe() states them.
    const auto defaults = [](const std::string& name) {
        try {
            std::string d = integrator_registry().create(name, Params("defaults"))->describe(), out;
            for (char c : d) out += c == '\n' ? ' ' : c;
            while (!out.empty() && out.back() == ' ') out.pop_back();
            return out;
        } catch (const Error&) {
            return std::string();
        }
    };
    fmt::print("integrators (gdr render --integrator NAME, parameters with --set key=value):\n");
    for (const auto& n : integrator_registry().names()) {
        fmt::print("  {:<18} {}\n", n, integrator_registry().description(n));
        const std::string d = defaults(n);
        if (!d.empty()) fmt::print("  {:<18} defaults: {}\n", "", d);
    }
    fmt::print("scene settings (gdr render --set key=value): fov (degrees, along the camera's fov axis)\n");
    fmt::print("shift mappings (gpt, gbdpt shift=NAME; their parameters shift.KEY=VALUE):\n");
    for (const auto& n : shift_registry().names()) fmt::print("  {:<18} {}\n", n, shift_registry().description(n));
    fmt::print("reconstructors (gdr reconstruct --method NAME; gpt, gbdpt, tgpt reconstruct=NAME[,NAME...], their "
               "parameters reconstruct.KEY=VALUE):\n");
    for (const auto& n : reconstructor_registry().names())
        fmt::print("  {:<18} {}\n", n, reconstructor_registry().description(n));
    if (!reconstructor_registry().has("neural")) {
        std::string why = "not built, or not found (no " + std::string(kNeuralPluginFile) +
                          " where gdr looks: GDR_PLUGIN_PATH); it needs libtorch, which scripts/install-deps.sh "
                          "installs (libtorch-dev)";
        for (const auto& [file, reason] : plugins.skipped)
            if (std::filesystem::path(file).filename() == kNeuralPluginFile)
                why = "its plugin " + file + " could not be loaded: " + reason;
        fmt::print("  {:<18} {}\n", "neural", why);
    }
    for (const std::string& file : plugins.loaded) fmt::print("plugin loaded: {}\n", file);
    for (const auto& [file, reason] : plugins.skipped) fmt::print("plugin skipped: {}: {}\n", file, reason);
    return 0;
}

}  // namespace gdr::cli
