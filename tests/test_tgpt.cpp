// Temporal gradient-domain path tracing: seed sharing between frames is
// exact, the temporal difference estimates the difference of the converged
// frames along the motion, and frames are independent jobs.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "block_stats.h"
#include "cli_test_util.h"
#include "gdr/io/reconstruct_files.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "gdr/reconstruct/temporal.h"
#include "gdr/scene/animated_scene.h"

using namespace gdr;
using Catch::Matchers::Contains;

namespace {

void write_text(const std::string& path, const std::string& text) {
    std::ofstream f(path);
    f << text;
}

// A square of half-side `half` in the plane z = z0 facing +z, centred on (cx, cy).
std::string quad_obj(float cx, float cy, float z0, float half) {
    std::string s;
    const float xs[4] = {cx - half, cx + half, cx + half, cx - half}, ys[4] = {cy - half, cy - half, cy + half, cy + half};
    for (int i = 0; i < 4; ++i)
        s += "v " + std::to_string(xs[i]) + " " + std::to_string(ys[i]) + " " + std::to_string(z0) + "\n";
    return s + "f 1 2 3\nf 1 3 4\n";
}

// The Cornell box (Original) at `res` pixels with an animation block of
// frames 0..3; `meshes_extra` adds mesh entries, `pose` replaces the camera's
// pose (e.g. by keys).
std::string box_scene(int res, const std::string& meshes_extra,
                      const std::string& pose = R"("position": [0, 1, 3.5], "target": [0, 1, 0])") {
    return R"({"animation": {"first": 0, "last": 3, "fps": 24},
  "camera": {)" + pose + R"(, "fov": 45, "width": )" +
           std::to_string(res) + R"(, "height": )" + std::to_string(res) + R"(},
  "meshes": [{"file": ")" + test::box("Original") + "\"}" + meshes_extra + "]}";
}

// Writes quad.obj into `dir` and returns its box_scene() mesh entry: a quad in
// front of the back wall moving right by 0.2 units a frame.
std::string moving_quad(const test::OutDir& dir) {
    write_text(dir("quad.obj"), quad_obj(0.f, 1.f, 0.f, 0.35f));
    return R"(, {"file": "quad.obj", "keys": [{"frame": 0, "translate": [-0.3, 0, 0]},
        {"frame": 3, "translate": [0.3, 0, 0]}]})";
}

// Frame `frame` of the animation in `path`, rendered by tgpt as `gdr render
// --frames` renders it: the frame's seed, the next frame's seed and the
// replay map. `next_offset` 1 is right; another value is the wrong variant
// that gives the second half some other frame's seed.
FrameBuffer render_frame(const std::string& path, int frame, uint64_t base, long long spp, int next_offset = 1,
                         bool replay = true) {
    SceneFile sf = load_scene_file(path);
    set_frame(sf, frame);
    FrameSampling fs;
    fs.next_seed = frame_seed(base, frame + next_offset);
    if (replay) fs.replay = replay_map(*sf.animation, *sf.scene, frame);
    RenderSettings st;
    st.spp = spp;
    st.seed = frame_seed(base, frame);
    st.frame_sampling = &fs;
    auto integ = integrator_registry().create("tgpt", test::params({{"reconstruct", "none"}}));
    FrameBuffer fb;
    integ->render(*sf.scene, st, fb);
    add_motion_layers(fb, *sf.animation, *sf.scene, frame);
    return fb;
}

// Frame `frame` by gpt: its primal, like dt, leaves out the directly visible emitters.
FrameBuffer render_gpt(const std::string& path, int frame, uint64_t seed, long long spp) {
    SceneFile sf = load_scene_file(path);
    set_frame(sf, frame);
    return test::render(*sf.scene, "gpt", test::params({{"reconstruct", "none"}}), spp, seed);
}

bool same_values(const Image& a, const Image& b) { return a.same_shape(b) && a.values() == b.values(); }

}  // namespace

TEST_CASE("tgpt: a scene that does not move shares every random number between frames", "[tgpt]") {
    test::OutDir dir("tgpt-static");
    write_text(dir("static.json"), box_scene(16, ""));
    std::vector<FrameBuffer> f;
    for (int k = 0; k < 3; ++k) f.push_back(render_frame(dir("static.json"), k, 7, 2));
    for (int k = 0; k + 1 < 3; ++k) {
        // I(k, s=k+1) and I(k+1, s=k+1): the same samples, bit for bit.
        CHECK(same_values(f[k].get(temporal_layers::primal_b), f[k + 1].get(temporal_layers::primal_a)));
        FrameBuffer fk = f[k];
        add_temporal_difference(fk, f[k + 1], "frame k", "frame k+1");
        const Image& dt = fk.get(temporal_layers::dt);
        const Image& valid = fk.get(temporal_layers::valid);
        for (float v : dt.values()) REQUIRE(v == 0.f);
        for (float v : valid.values()) REQUIRE(v == 1.f);
    }
    // The halves of one frame are independent: different numbers, different images.
    CHECK_FALSE(same_values(f[0].get(temporal_layers::primal_a), f[0].get(temporal_layers::primal_b)));
    // Wrong variant: a second half with another frame's seed shares nothing.
    const FrameBuffer wrong = render_frame(dir("static.json"), 0, 7, 2, 2);
    CHECK_FALSE(same_values(wrong.get(temporal_layers::primal_b), f[1].get(temporal_layers::primal_a)));
}

TEST_CASE("tgpt: the replay map follows an analytic translation and closes its round trips", "[tgpt]") {
    test::OutDir dir("tgpt-replay");
    // A quad in front of the back wall moving right by 0.2 units a frame,
    // about 2 pixels at 32 pixels across the box.
    const std::string moving = moving_quad(dir);
    write_text(dir("moving.json"), box_scene(32, moving));
    SceneFile sf = load_scene_file(dir("moving.json"));
    set_frame(sf, 2);
    const Image r = replay_map(*sf.animation, *sf.scene, 2);
    int replayed = 0, own = 0;
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x) {
            const PixelMotion m = pixel_motion(*sf.animation, *sf.scene, 2, x, y);
            if (r.at(x, y, 0) < 0.f) {
                ++own;
                continue;
            }
            ++replayed;
            // The previous frame's pixel is this one moved back by the rounded motion.
            REQUIRE(r.at(x, y, 0) == float(x + int(std::lround(m.bwd.x))));
            REQUIRE(r.at(x, y, 1) == float(y + int(std::lround(m.bwd.y))));
        }
    // Most pixels (the static box) replay their own pixel; the quad's
    // disoccluded strip has no correspondence.
    CHECK(replayed > 32 * 32 * 8 / 10);
    CHECK(own > 0);

    // What seed sharing and the replay are for: dt of frames that share their
    // random numbers along the motion is far less noisy than of frames that
    // do not. Wrong variants: frame 1's second half with another frame's seed
    // (nothing shared), and frame 2's first half without the replay (its own
    // pixels' numbers: the same on the static box, not on the moving quad).
    enum Variant { kShared, kNoSharing, kNoReplay };
    const auto dt_power = [&](Variant v, bool quad_only) {
        double sum = 0.0;
        for (uint64_t base = 0; base < 8; ++base) {
            const FrameBuffer a = render_frame(dir("moving.json"), 1, base, 2, v == kNoSharing ? 2 : 1);
            const FrameBuffer b = render_frame(dir("moving.json"), 2, base, 2, 1, v != kNoReplay);
            // dt by hand, on the rows the shared variant keeps.
            const Image &pb = a.get(temporal_layers::primal_b), &pa = b.get(temporal_layers::primal_a);
            const Image &m = a.get(temporal_layers::motion), &object = a.get("object_id");
            for (int y = 0; y < 32; ++y)
                for (int x = 0; x < 32; ++x) {
                    const int qx = x + int(std::lround(m.at(x, y, 0))), qy = y + int(std::lround(m.at(x, y, 1)));
                    if (qx < 0 || qy < 0 || qx >= 32 || qy >= 32 || r.at(qx, qy, 0) != float(x) ||
                        r.at(qx, qy, 1) != float(y) || (quad_only && object.at(x, y, 0) != 1.f))
                        continue;
                    const double d = test::grey(pa, qx, qy) - test::grey(pb, x, y);
                    sum += d * d;
                }
        }
        return sum;
    };
    const double shared = dt_power(kShared, false), independent = dt_power(kNoSharing, false);
    const double shared_quad = dt_power(kShared, true), no_replay_quad = dt_power(kNoReplay, true);
    INFO("sum of dt^2: shared " << shared << ", not shared " << independent << "; on the quad: shared "
                                << shared_quad << ", without replay " << no_replay_quad);
    CHECK(shared < 0.25 * independent);
    CHECK(shared_quad < 0.75 * no_replay_quad);
}

TEST_CASE("tgpt: dt estimates the difference of converged frames along the motion", "[tgpt][statistical]") {
    test::OutDir dir("tgpt-dt");
    const std::string moving = moving_quad(dir);
    write_text(dir("object.json"), box_scene(24, moving));
    // The camera pans right and turns: motion everywhere.
    write_text(dir("camera.json"), box_scene(24, "", R"("keys": [{"frame": 0, "position": [-0.3, 1, 3.5], "target": [0, 1, 0]},
        {"frame": 3, "position": [0.3, 1, 3.4], "target": [0.1, 1, 0]}])"));
    for (const char* name : {"object.json", "camera.json"}) {
        INFO(name);
        const int k = 1, runs = 48, block = 4, W = 24, H = 24;
        // dt_k over runs with independent base seeds, per block over valid pixels.
        std::vector<FrameBuffer> dts;
        for (int r = 0; r < runs; ++r) {
            FrameBuffer a = render_frame(dir(name), k, 100 + r, 4);
            const FrameBuffer b = render_frame(dir(name), k + 1, 100 + r, 4);
            add_temporal_difference(a, b, "k", "k+1");
            dts.push_back(std::move(a));
        }
        // The pixels compared: valid rows (those of run 0: the mask depends on
        // the geometry alone).
        const Image& valid = dts[0].get(temporal_layers::valid);
        const Image& motion = dts[0].get(temporal_layers::motion);
        std::vector<int> target(size_t(W) * H, -1);  // per pixel: where it is in frame k+1 (x + W y), -1: not compared
        int used = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                if (valid.at(x, y, 0) != 1.f) continue;
                const int qx = x + int(std::lround(motion.at(x, y, 0))), qy = y + int(std::lround(motion.at(x, y, 1)));
                target[size_t(y) * W + x] = qy * W + qx, ++used;
            }
        CHECK(used > W * H / 2);
        std::vector<FrameBuffer> pk, pk1;
        for (int r = 0; r < runs; ++r) {
            pk.push_back(render_gpt(dir(name), k, 5000 + r, 8));
            pk1.push_back(render_gpt(dir(name), k + 1, 9000 + r, 8));
        }
        // The reference: independent frames differenced along the
        // same rounded motion (or, `follow` false, the wrong variant, not).
        const auto reference = [&](bool follow) {
            return test::block_stats(runs, W, H, block, [&](int r, auto&& add) {
                const Image &c0 = pk[r].get("primal"), &c1 = pk1[r].get("primal");
                for (int y = 0; y < H; ++y)
                    for (int x = 0; x < W; ++x) {
                        const int t = target[size_t(y) * W + x];
                        if (t < 0) continue;
                        const int qx = follow ? t % W : x, qy = follow ? t / W : y;
                        add(x, y, test::grey(c1, qx, qy) - test::grey(c0, x, y));
                    }
            });
        };
        const test::BlockStats est = test::block_stats(runs, W, H, block, [&](int r, auto&& add) {
            const Image& dt = dts[r].get(temporal_layers::dt);
            for (int y = 0; y < H; ++y)
                for (int x = 0; x < W; ++x)
                    if (target[size_t(y) * W + x] >= 0) add(x, y, test::grey(dt, x, y));
        });
        const double z = test::max_z(est, reference(true));
        CHECK(z < 4.5);
        // Wrong variant: the converged frames differenced without following
        // the motion; 36 blocks, so a true z near 5 would be a 1-in-10^4 event.
        CHECK(test::max_z(est, reference(false)) > 6.0);
    }
}

TEST_CASE("tgpt: frames rendered in any order or in separate runs are the same files", "[tgpt][cli]") {
    test::OutDir dir("tgpt-jobs");
    write_text(dir("anim.json"), box_scene(16, moving_quad(dir)));
    const auto render = [&](const std::string& range, const std::string& out) {
        test::stdout_of([&] {
            cli::run({"render", dir("anim.json"), "--integrator", "tgpt", "--spp", "2", "--frames", range, "-o",
                      dir(out) + "/f.%04d.exr"});
        });
    };
    std::filesystem::create_directories(dir("all"));
    std::filesystem::create_directories(dir("split"));
    render("0:3", "all");
    // Two "machines": separate runs, later frames first, each with a fresh integrator.
    render("2:3", "split");
    render("0:1", "split");
    for (int k = 0; k <= 3; ++k) {
        const FrameBuffer a = read_exr(frame_path(dir("all") + "/f.%04d.exr", k));
        const FrameBuffer b = read_exr(frame_path(dir("split") + "/f.%04d.exr", k));
        REQUIRE(a.names() == b.names());
        for (const std::string& n : a.names()) {
            INFO("frame " << k << " layer " << n);
            CHECK(same_values(a.get(n), b.get(n)));
        }
    }
    // The sequence reconstructs with its temporal differences formed from the halves.
    const FrameSequenceReport rep = reconstruct_frame_sequence(dir("all") + "/f.%04d.exr", 0, 3,
                                                               dir("final.%04d.exr"), TemporalOptions{});
    CHECK(rep.frames == 4);
    REQUIRE(!rep.windows.empty());
    CHECK(rep.windows[0].second.temporal_rows > 3 * 16 * 16 * 8 / 10);
    // A frame that is not tgpt's cannot give its neighbour a dt: named.
    std::filesystem::copy(dir("all"), dir("mixed"));
    std::filesystem::remove(dir("mixed") + "/f.0002.exr");
    test::stdout_of([&] {
        cli::run({"render", dir("anim.json"), "--integrator", "gpt", "--spp", "1", "--frame", "2", "-o",
                  dir("mixed") + "/f.0002.exr"});
    });
    CHECK_THAT(test::error_of({"reconstruct", "--frames", dir("mixed") + "/f.%04d.exr", "0:3", "-o",
                               dir("again.%04d.exr")}),
               Contains("f.0001.exr") && Contains("'dt'"));
}
