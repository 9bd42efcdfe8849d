// gdr video: an animation's EXR frames as a PNG sequence and an MP4 (through ffmpeg when it is installed).
#include <catch2/catch.hpp>

#include <stb/stb_image.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "cli_test_util.h"
#include "gdr/io/exr.h"
#include "gdr/io/png.h"

using namespace gdr;
using namespace gdr::test;
namespace fs = std::filesystem;

namespace {

constexpr int kW = 5, kH = 3;  // odd on purpose: the MP4 pads to even sizes

// Linear value of pixel (x, y), channel c of frame k's "color" layer.
float color_value(int x, int y, int c, int k) { return 0.02f * float(x + 1) + 0.1f * float(y) + 0.05f * float(c) + 0.15f * float(k); }

// Frame k: "color" (3 channels) and, when `with_l1`, a "reconstruction_l1" of constant 0.5, the layer a G-PT
// render's PNG shows; metadata as `gdr render --frames` writes it.
FrameBuffer video_frame(int k, bool with_l1, const std::string& fps = "") {
    FrameBuffer fb(kW, kH);
    Image col(kW, kH, 3), l1(kW, kH, 3);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            for (int c = 0; c < 3; ++c) col.at(x, y, c) = color_value(x, y, c, k), l1.at(x, y, c) = 0.5f;
    fb.set("color", std::move(col));
    if (with_l1) fb.set("reconstruction_l1", std::move(l1));
    fb.metadata()["frame"] = std::to_string(k);
    if (!fps.empty()) fb.metadata()["fps"] = fps;
    return fb;
}

void write_frames(const OutDir& dir, const std::string& stem, int first, int last, bool with_l1,
                  const std::string& fps = "") {
    char name[256];
    for (int k = first; k <= last; ++k) {
        std::snprintf(name, sizeof name, "%s.%04d.exr", stem.c_str(), k);
        write_exr(dir(name), video_frame(k, with_l1, fps));
    }
}

// A PNG's pixels (as stored: 1, 3 or 4 channels), width and height.
struct Png {
    int w = 0, h = 0, n = 0;
    std::vector<unsigned char> px;
};
Png read_png(const std::string& path) {
    Png p;
    unsigned char* d = stbi_load(path.c_str(), &p.w, &p.h, &p.n, 0);
    REQUIRE(d);
    p.px.assign(d, d + size_t(p.w) * p.h * p.n);
    stbi_image_free(d);
    return p;
}

// The 8-bit code of the sRGB curve at linear v (IEC 61966-2-1), written out here so that a change in gdr's curve fails.
int srgb_code(double v) {
    v = std::clamp(v, 0.0, 1.0);
    const double s = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
    return int(s * 255.0 + 0.5);
}

// The files in `dir` whose names start with `prefix`.
std::vector<std::string> files_starting(const OutDir& dir, const std::string& prefix) {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir.path))
        if (e.path().filename().string().rfind(prefix, 0) == 0) out.push_back(e.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
}

// Sets PATH for the lifetime of the object (ffmpeg is looked up on it).
struct PathScope {
    std::string old;
    explicit PathScope(const std::string& path) : old(std::getenv("PATH") ? std::getenv("PATH") : "") {
        setenv("PATH", path.c_str(), 1);
    }
    ~PathScope() { setenv("PATH", old.c_str(), 1); }
};

bool on_path(const std::string& program) {
    return std::system(("command -v " + program + " > /dev/null 2>&1").c_str()) == 0;
}

// What a shell command prints on stdout.
std::string output_of(const std::string& command) {
    std::string out;
    FILE* p = popen(command.c_str(), "r");
    REQUIRE(p);
    char buf[256];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    pclose(p);
    return out;
}

// "frames,width,height,rate" of the video stream of `mp4`, by ffprobe.
std::string probe(const std::string& mp4) {
    std::string s = output_of("ffprobe -v error -select_streams v:0 -count_frames -show_entries "
                              "stream=nb_read_frames,width,height,r_frame_rate,pix_fmt -of "
                              "default=noprint_wrappers=1 '" + mp4 + "'");
    return s;
}

std::string run_out(const std::vector<std::string>& args, int* status = nullptr) {
    return stdout_of([&] {
        const int rc = cli::run(args);
        if (status) *status = rc;
    });
}

}  // namespace

TEST_CASE("cli: video writes a PNG sequence tone-mapped as gdr's PNG previews", "[video][cli]") {
    OutDir dir("video-png");
    write_frames(dir, "f", 1, 3, true);
    // The default layer is the final image (reconstruction_l1 here), as the render's PNG preview shows.
    std::string out = run_out({"video", dir("f.%04d.exr"), "1:3", "-o", dir("l1.%04d.png")});
    CAPTURE(out);
    CHECK(out.find("reconstruction_l1") != std::string::npos);
    CHECK(files_starting(dir, "l1.") == std::vector<std::string>{"l1.0001.png", "l1.0002.png", "l1.0003.png"});
    for (int k = 1; k <= 3; ++k) {
        const Png p = read_png(dir("l1.000" + std::to_string(k) + ".png"));
        REQUIRE((p.w == kW && p.h == kH && p.n == 3));
        for (unsigned char v : p.px) CHECK(int(v) == srgb_code(0.5));  // 188
    }

    // --layer color, a sub-range, --exposure: each pixel's sRGB code, and the same bytes as write_png_preview's.
    out = run_out({"video", dir("f.%04d.exr"), "2:3", "--layer", "color", "--exposure", "1", "-o",
                   dir("c.%04d.png")});
    CHECK(files_starting(dir, "c.") == std::vector<std::string>{"c.0002.png", "c.0003.png"});
    for (int k = 2; k <= 3; ++k) {
        const Png p = read_png(dir("c.000" + std::to_string(k) + ".png"));
        REQUIRE((p.w == kW && p.h == kH && p.n == 3));
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x)
                for (int c = 0; c < 3; ++c) {
                    INFO("frame " << k << " pixel " << x << "," << y << " channel " << c);
                    CHECK(int(p.px[(size_t(y) * kW + x) * 3 + c]) == srgb_code(2.0 * color_value(x, y, c, k)));
                }
        write_png_preview(dir("ref.png"), video_frame(k, false).get("color"), 1.f);
        CHECK(read_png(dir("ref.png")).px == p.px);
    }

    // NaN and infinite values are shown as the PNG writer shows them: NaN and -Inf black, +Inf white.
    FrameBuffer bad = video_frame(0, false);
    bad.get("color").at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    bad.get("color").at(1, 0, 0) = std::numeric_limits<float>::infinity();
    bad.get("color").at(2, 0, 0) = -std::numeric_limits<float>::infinity();
    bad.get("color").at(3, 0, 0) = 7.f;
    write_exr(dir("nan.0000.exr"), bad);
    REQUIRE(error_of({"video", dir("nan.%04d.exr"), "0:0", "-o", dir("nan.%04d.png")}) == "");
    const Png n = read_png(dir("nan.0000.png"));
    CHECK(int(n.px[0]) == 0);
    CHECK(int(n.px[3]) == 255);
    CHECK(int(n.px[6]) == 0);
    CHECK(int(n.px[9]) == 255);
}

TEST_CASE("cli: video names a missing frame or layer and never replaces an input", "[video][cli]") {
    OutDir dir("video-errors");
    write_frames(dir, "f", 1, 3, false);

    // A gap in the sequence is named before anything is written.
    std::string e = error_of({"video", dir("f.%04d.exr"), "1:5", "-o", dir("o.%04d.png")});
    CAPTURE(e);
    CHECK(e.find("f.0004.exr") != std::string::npos);
    CHECK(files_starting(dir, "o.").empty());

    // A missing layer names the file and the layer and lists the layers there are.
    e = error_of({"video", dir("f.%04d.exr"), "1:3", "--layer", "dt", "-o", dir("o.%04d.png")});
    CHECK(e.find("f.0001.exr") != std::string::npos);
    CHECK(e.find("'dt'") != std::string::npos);
    CHECK(e.find("layers: color") != std::string::npos);
    // ... also when only a later frame lacks the layer the first frame chose.
    write_frames(dir, "g", 1, 3, true);
    write_exr(dir("g.0002.exr"), video_frame(2, false));
    // (The frames before it are written by then: a PNG sequence is not one file.)
    e = error_of({"video", dir("g.%04d.exr"), "1:3", "-o", dir("go.%04d.png")});
    CHECK(e.find("g.0002.exr") != std::string::npos);
    CHECK(e.find("'reconstruction_l1'") != std::string::npos);

    // An output never replaces an input: EXRs named .png, by the same name and through a symlink.
    write_frames(dir, "h", 1, 2, false);
    for (int k = 1; k <= 2; ++k) {
        fs::rename(dir("h.000" + std::to_string(k) + ".exr"), dir("h.000" + std::to_string(k) + ".png"));
        fs::create_symlink(dir("h.000" + std::to_string(k) + ".png"), dir("link.000" + std::to_string(k) + ".png"));
    }
    const std::string before = file_bytes(dir("h.0001.png"));
    for (const std::string target : {"h.%04d.png", "link.%04d.png"}) {
        e = error_of({"video", dir("h.%04d.png"), "1:2", "-o", dir(target)});
        CAPTURE(target);
        CHECK(e.find("refusing to write") != std::string::npos);
        CHECK(e.find("h.0001.png") != std::string::npos);
        e = error_of({"video", dir("h.%04d.png"), "1:2", "-o", dir("v.mp4"), "--png", dir(target)});
        CHECK(e.find("refusing to write") != std::string::npos);
    }
    CHECK(file_bytes(dir("h.0001.png")) == before);
    CHECK(read_exr(dir("h.0001.png")).has("color"));
    // The inputs, as EXRs named .png, make a sequence once the output is elsewhere.
    CHECK(error_of({"video", dir("h.%04d.png"), "1:2", "-o", dir("hh.%04d.png")}) == "");

    // Options that cannot mean anything are refused, naming what is wrong.
    CHECK(error_of({"video", dir("f.%04d.exr"), "1:3", "-o", dir("v.avi")}).find("v.avi") != std::string::npos);
    CHECK(error_of({"video", dir("f.exr"), "1:3", "-o", dir("o.%04d.png")}).find("f.exr") != std::string::npos);
    CHECK(error_of({"video", dir("f.%04d.exr"), "1:3", "-o", dir("o.%04d.png"), "--png", dir("p.%04d.png")}) != "");
    CHECK(error_of({"video", dir("f.%04d.exr"), "3:1", "-o", dir("o.%04d.png")}).find("before") != std::string::npos);
    CHECK(error_of({"video", dir("f.%04d.exr"), "1:3", "--fps", "0", "-o", dir("v.mp4")}).find("--fps") !=
          std::string::npos);
    CHECK(files_starting(dir, "o.").empty());
}

TEST_CASE("cli: video without ffmpeg writes the PNG sequence and says how to get the MP4", "[video][cli]") {
    OutDir dir("video-no-ffmpeg");
    write_frames(dir, "f", 0, 3, false);
    fs::create_directories(dir.path / "empty-bin");
    std::string out;
    int status = -1;
    {
        const PathScope path(dir("empty-bin"));
        out = run_out({"video", dir("f.%04d.exr"), "0:3", "-o", dir("v.mp4")}, &status);
    }
    CAPTURE(out);
    CHECK(status == 0);
    CHECK(out.find("ffmpeg not found") != std::string::npos);
    CHECK(out.find(dir("v.%04d.png")) != std::string::npos);  // says where the PNGs went
    CHECK(!fs::exists(dir("v.mp4")));
    CHECK(files_starting(dir, "v.") ==
          std::vector<std::string>{"v.0000.png", "v.0001.png", "v.0002.png", "v.0003.png"});
    const Png p = read_png(dir("v.0002.png"));
    CHECK((p.w == kW && p.h == kH));
    CHECK(int(p.px[0]) == srgb_code(color_value(0, 0, 0, 2)));
}

TEST_CASE("cli: video encodes an MP4 with ffmpeg and keeps a good one when an encode fails", "[video][cli]") {
    OutDir dir("video-mp4");
    write_frames(dir, "f", 0, 4, false, "30");

    // A failing ffmpeg (a stand-in on PATH) is named with its message, and leaves no file behind.
    fs::create_directories(dir.path / "bad-bin");
    {
        std::ofstream s(dir("bad-bin/ffmpeg"));
        // It writes a partial file where it was told to (its last argument), as a real failing encode can.
        s << "#!/bin/sh\nfor a; do out=$a; done\ncat > /dev/null\ncase $out in */*) echo partial > \"$out\" ;; esac\n"
             "echo 'first line' >&2\necho 'stand-in encoder failure' >&2\nexit 3\n";
    }
    fs::permissions(dir("bad-bin/ffmpeg"), fs::perms::owner_all);
    std::string e;
    {
        const PathScope path(dir("bad-bin") + ":/usr/bin:/bin");
        e = error_of({"video", dir("f.%04d.exr"), "0:4", "-o", dir("v.mp4")});
    }
    CAPTURE(e);
    CHECK(e.find("ffmpeg") != std::string::npos);
    CHECK(e.find("stand-in encoder failure") != std::string::npos);
    CHECK(e.find("exit status 3") != std::string::npos);
    CHECK(files_starting(dir, "v.").empty());
    CHECK(files_starting(dir, ".v.").empty());

    if (!on_path("ffmpeg")) {
        WARN("ffmpeg is not installed: the MP4 encoding is not tested (the test without ffmpeg still runs)");
        return;
    }
    std::string out = run_out({"video", dir("f.%04d.exr"), "0:4", "-o", dir("v.mp4"), "--png", dir("p.%04d.png")});
    CAPTURE(out);
    REQUIRE(fs::exists(dir("v.mp4")));
    CHECK(fs::file_size(dir("v.mp4")) > 0);
    CHECK(files_starting(dir, ".v.").empty());  // no temporary left
    CHECK(files_starting(dir, "p.").size() == 5);
    CHECK(out.find("30 fps") != std::string::npos);  // the frames' "fps"
    if (on_path("ffprobe")) {
        const std::string info = probe(dir("v.mp4"));
        CAPTURE(info);
        CHECK(info.find("width=6\n") != std::string::npos);  // 5x3 padded to even
        CHECK(info.find("height=4\n") != std::string::npos);
        CHECK(info.find("nb_read_frames=5\n") != std::string::npos);
        CHECK(info.find("r_frame_rate=30/1\n") != std::string::npos);
        CHECK(info.find("pix_fmt=yuv420p\n") != std::string::npos);
    } else {
        WARN("ffprobe is not installed: the MP4's frame count and size are not checked");
    }

    // A sequence that breaks mid-way (frame 3 is no EXR) stops ffmpeg and leaves the good MP4 as it was.
    const std::string good = file_bytes(dir("v.mp4"));
    write_frames(dir, "g", 0, 4, false);
    { std::ofstream(dir("g.0003.exr")) << "not an EXR"; }
    e = error_of({"video", dir("g.%04d.exr"), "0:4", "--fps", "12", "-o", dir("v.mp4")});
    CHECK(e.find("g.0003.exr") != std::string::npos);
    CHECK(file_bytes(dir("v.mp4")) == good);
    CHECK(files_starting(dir, ".v.").empty());

    // --fps overrides, and a reconstructed frame's rate is found through its input.
    write_exr(dir("src.exr"), video_frame(0, false, "25"));
    for (int k = 0; k <= 1; ++k) {
        FrameBuffer fb = video_frame(k, false);
        fb.metadata()["reconstruction_input"] = dir("src.exr");
        write_exr(dir("r.000" + std::to_string(k) + ".exr"), fb);
    }
    out = run_out({"video", dir("r.%04d.exr"), "0:1", "-o", dir("r.mp4")});
    CHECK(out.find("25 fps") != std::string::npos);
    out = run_out({"video", dir("r.%04d.exr"), "0:1", "--fps", "12", "-o", dir("r.mp4")});
    CHECK(out.find("12 fps from --fps") != std::string::npos);
    if (on_path("ffprobe")) {
        const std::string info = probe(dir("r.mp4"));
        CAPTURE(info);
        CHECK(info.find("nb_read_frames=2\n") != std::string::npos);
        CHECK(info.find("r_frame_rate=12/1\n") != std::string::npos);
    }
}
