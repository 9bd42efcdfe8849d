// The gdr tool over a command's whole life: frame ranges checked before any
// frame renders, frame patterns of any width, and errors that name the file.
// (Signals, locks and special files need a real process: tests/lifecycle.sh.)
#include <catch2/catch.hpp>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <filesystem>
#include <limits>
#include <string>

#include "cli_test_util.h"
#include "gdr/io/exr.h"

using namespace gdr;
using namespace gdr::test;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {

const std::string kSmall = GDR_SOURCE_DIR "/tests/scenes/cornell-small.json";
const std::string kAnimation = GDR_SOURCE_DIR "/scenes/cornell-box/animation.json";  // frames 0 to 47

// How many files in `dir` have a name that starts with `prefix`.
int count_files(const OutDir& dir, const std::string& prefix) {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir.path)) n += e.path().filename().string().rfind(prefix, 0) == 0;
    return n;
}

// A small frame with exact gradients and temporal differences, for reconstruct --frames and video.
FrameBuffer small_frame(int k) {
    const int W = 6, H = 5;
    const auto value = [](int x, int y, int k) { return 0.2f + 0.05f * float(x) + 0.03f * float(y) + 0.1f * float(k); };
    FrameBuffer fb(W, H);
    Image p(W, H, 3), dx(W, H, 3), dy(W, H, 3), dt(W, H, 3);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < 3; ++c) {
                p.at(x, y, c) = value(x, y, k);
                if (x + 1 < W) dx.at(x, y, c) = value(x + 1, y, k) - value(x, y, k);
                if (y + 1 < H) dy.at(x, y, c) = value(x, y + 1, k) - value(x, y, k);
                dt.at(x, y, c) = value(x, y, k + 1) - value(x, y, k);
            }
    fb.set("primal", std::move(p));
    fb.set("dx", std::move(dx));
    fb.set("dy", std::move(dy));
    fb.set("dt", std::move(dt));
    return fb;
}

}  // namespace

// Before the fix, gdr::frame_path printed the number into 64 bytes: '%100d'
// gave every frame the same truncated name of spaces, so gdr reconstruct
// --frames and gdr video wrote all frames to one file and exited 0 (checked
// with the previous binary: gdr video -o 'v.%100d.png' wrote one file for
// three frames). The CLI's own patterns (render, merge --frames) printed into
// 128 bytes: 'r.%0200d.exr' gave frames 1 and 2 one name (one file).
TEST_CASE("lifecycle: frame patterns of any width keep every frame in its own file", "[cli][lifecycle]") {
    OutDir dir("lifecycle-pattern");
    for (int k = 0; k <= 2; ++k) write_exr(dir("in." + std::to_string(k) + ".exr"), small_frame(k));
    REQUIRE(error_of({"reconstruct", "--frames", dir("in.%d.exr"), "0:2", "-o", dir("o.%100d.exr")}) == "");
    CHECK(count_files(dir, "o.") == 3);
    CHECK(fs::exists(dir("o." + std::string(99, ' ') + "2.exr")));
    REQUIRE(error_of({"video", dir("o.%100d.exr"), "0:2", "-o", dir("v.%0150d.png")}) == "");
    CHECK(count_files(dir, "v.") == 3);
    CHECK(fs::exists(dir("v." + std::string(149, '0') + "1.png")));
    REQUIRE(error_of({"render", kAnimation, "--resolution", "4x4", "--spp", "1", "--frames", "1:2", "-o",
                      dir("r.%0200d.exr")}) == "");
    CHECK(fs::exists(dir("r." + std::string(199, '0') + "1.exr")));
    CHECK(fs::exists(dir("r." + std::string(199, '0') + "2.exr")));
    // Wider than any path: a named error, not a truncated name.
    CHECK_THAT(error_of({"render", kAnimation, "--spp", "1", "--frames", "1:2", "-o", dir("r.%05000d.exr")}),
               Contains("wider"));
    CHECK_THAT(error_of({"video", dir("o.%100d.exr"), "0:2", "-o", dir("w.%5000d.png")}), Contains("wider"));
}

// Before the fix, '--frames 46:50' rendered frames 46 and 47 and then failed
// on 48 (checked with the previous binary: r.46.exr and r.47.exr written).
TEST_CASE("lifecycle: a --frames range past the animation is refused before any frame renders", "[cli][lifecycle]") {
    OutDir dir("lifecycle-range");
    const std::string e = error_of({"render", kAnimation, "--resolution", "4x4", "--spp", "1", "--frames", "46:50",
                                    "-o", dir("r.%d.exr")});
    CHECK_THAT(e, Contains("frame 48") && Contains("46:50") && Contains("0 to 47"));
    CHECK(count_files(dir, "r.") == 0);
    CHECK_THAT(error_of({"render", kAnimation, "--resolution", "4x4", "--spp", "1", "--frames", "-2:1", "-o",
                         dir("r.%d.exr")}),
               Contains("frame -2"));
    CHECK_THAT(error_of({"render", kAnimation, "--resolution", "4x4", "--spp", "1", "--frame", "48", "-o",
                         dir("r.exr")}),
               Contains("frame 48"));
    CHECK(count_files(dir, "r.") == 0);
}

// Before the fix the error named the output and the pixel ("m.exr: layer
// 'color' ..."), not the part that held the NaN (checked with the previous
// binary on the same files).
TEST_CASE("lifecycle: merging a part with a non-finite pixel names the part's file and the pixel", "[cli][lifecycle]") {
    OutDir dir("lifecycle-merge");
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "1", "-o", dir("a.exr")}) == 0);
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "2", "-o", dir("b.exr")}) == 0);
    FrameBuffer fb = read_exr(dir("b.exr"));
    fb.get("color").at(3, 4, 1) = std::numeric_limits<float>::quiet_NaN();
    write_exr(dir("bad.exr"), fb);
    const std::string e = error_of({"merge", dir("a.exr"), dir("bad.exr"), "-o", dir("m.exr")});
    CAPTURE(e);
    CHECK_THAT(e, Contains(dir("bad.exr")) && Contains("color") && Contains("(3, 4)"));
    CHECK_FALSE(fs::exists(dir("m.exr")));
}

// Before the fix nothing was locked: the merge below replaced m.exr while
// another run held it (checked with the previous binary, exit 0).
TEST_CASE("lifecycle: an output another run holds is refused at once, naming the holder, and no lock file stays",
          "[cli][lifecycle]") {
    OutDir dir("lifecycle-lock");
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "1", "-o", dir("a.exr")}) == 0);
    REQUIRE(cli::run({"render", kSmall, "--spp", "1", "--seed", "2", "-o", dir("b.exr")}) == 0);
    // Every command removes its lock file as it ends, after success and after an error.
    CHECK(count_files(dir, "a.exr.lock") == 0);
    CHECK(error_of({"merge", dir("a.exr"), dir("a.exr"), "-o", dir("m.exr")}) != "");
    CHECK(count_files(dir, "m.exr.lock") == 0);
    {
        // Another run's lock, as gdr takes it (this process holds it on its own descriptor).
        const int fd = open(dir("m.exr.lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        REQUIRE(fd >= 0);
        REQUIRE(flock(fd, LOCK_EX | LOCK_NB) == 0);
        const std::string holder = "pid 4242 on host node7, gdr merge, since 2026-01-01 00:00:00 UTC\n";
        REQUIRE(write(fd, holder.data(), holder.size()) == ssize_t(holder.size()));
        std::ofstream(dir("m.exr")) << "held";
        const std::string e = error_of({"merge", dir("a.exr"), dir("b.exr"), "-o", dir("m.exr")});
        CHECK_THAT(e, Contains(dir("m.exr")) && Contains("pid 4242 on host node7"));
        CHECK(file_bytes(dir("m.exr")) == "held");
        CHECK_THAT(error_of({"render", kSmall, "--spp", "1", "--continue", "-o", dir("m.exr")}), Contains("pid 4242"));
        close(fd);
    }
    // Released (the holder ended without removing its file): the next run takes it.
    CHECK(error_of({"merge", dir("a.exr"), dir("b.exr"), "-o", dir("m.exr")}) == "");
    CHECK(cli::read_stored_render(dir("m.exr")).spp == 2);
    CHECK(count_files(dir, "m.exr.lock") == 0);
}
