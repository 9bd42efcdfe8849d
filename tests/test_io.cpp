#include <catch2/catch.hpp>

#include <stb/stb_image.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <unistd.h>

#include "gdr/io/exr.h"
#include "gdr/io/png.h"

using namespace gdr;
namespace fs = std::filesystem;

namespace {

/// A fresh per-process scratch directory, removed at exit of the test case.
struct TempDir {
    fs::path dir;
    TempDir() {
        static int n = 0;
        dir = fs::temp_directory_path() / ("gdr_test_io_" + std::to_string(::getpid()) + "_" + std::to_string(n++));
        fs::create_directories(dir);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
    std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

std::string slurp(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), {}};
}

/// IEEE half bits of a float that is exactly representable as a normal half (or zero).
uint16_t to_half_bits(float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    const uint32_t sign = (u >> 16) & 0x8000u;
    if ((u & 0x7fffffffu) == 0) return uint16_t(sign);
    const int e = int((u >> 23) & 0xff) - 127 + 15;
    return uint16_t(sign | (uint32_t(e) << 10) | ((u >> 13) & 0x3ffu));
}

/// Writes an uncompressed scanline EXR by hand, as "other software" would: no
/// OpenEXR involved, arbitrary data window, HALF or FLOAT channels.
/// `channels` must be sorted by name (the EXR rule); value(name, x, y) gives the pixel.
struct RawChannel {
    std::string name;
    bool half;
};
template <class F>
void write_raw_exr(const std::string& path, const std::vector<RawChannel>& channels, int x0, int y0, int x1, int y1,
                   F value) {
    std::string out;
    auto put = [&](const void* p, size_t n) { out.append(static_cast<const char*>(p), n); };
    auto put_i32 = [&](int32_t v) { put(&v, 4); };
    auto put_f32 = [&](float v) { put(&v, 4); };
    auto attr = [&](const std::string& name, const std::string& type, int32_t size) {
        out += name + '\0' + type + '\0';
        put_i32(size);
    };
    out += "\x76\x2f\x31\x01";
    put_i32(2);
    int32_t chsize = 1;
    for (const auto& c : channels) chsize += int32_t(c.name.size()) + 1 + 16;
    attr("channels", "chlist", chsize);
    for (const auto& c : channels) {
        out += c.name + '\0';
        put_i32(c.half ? 1 : 2);
        out += std::string(4, '\0');  // pLinear + reserved
        put_i32(1), put_i32(1);
    }
    out += '\0';
    attr("compression", "compression", 1), out += '\0';
    attr("dataWindow", "box2i", 16), put_i32(x0), put_i32(y0), put_i32(x1), put_i32(y1);
    attr("displayWindow", "box2i", 16), put_i32(0), put_i32(0), put_i32(x1 + 3), put_i32(y1 + 3);
    attr("lineOrder", "lineOrder", 1), out += '\0';
    attr("pixelAspectRatio", "float", 4), put_f32(1.f);
    attr("screenWindowCenter", "v2f", 8), put_f32(0.f), put_f32(0.f);
    attr("screenWindowWidth", "float", 4), put_f32(1.f);
    attr("owner", "string", 5), out += "other";
    out += '\0';
    const int w = x1 - x0 + 1, h = y1 - y0 + 1;
    size_t line_bytes = 0;
    for (const auto& c : channels) line_bytes += size_t(w) * (c.half ? 2 : 4);
    uint64_t offset = out.size() + 8 * size_t(h);
    for (int y = 0; y < h; ++y, offset += 8 + line_bytes) put(&offset, 8);
    for (int y = y0; y <= y1; ++y) {
        put_i32(y);
        put_i32(int32_t(line_bytes));
        for (const auto& c : channels)
            for (int x = x0; x <= x1; ++x) {
                const float v = value(c.name, x, y);
                if (c.half) {
                    const uint16_t hb = to_half_bits(v);
                    put(&hb, 2);
                } else {
                    put_f32(v);
                }
            }
    }
    std::ofstream(path, std::ios::binary) << out;
}

}  // namespace

TEST_CASE("exr: multi-layer round trip is bit-exact and keeps order and metadata", "[io]") {
    TempDir tmp;
    const int w = 7, h = 5;
    FrameBuffer fb(w, h);
    // Deliberately not alphabetical, so the channel list order would be wrong.
    Image& zeta = fb.add("zeta", 3);
    Image& color = fb.add("color", 3);
    Image& depth = fb.add("depth", 1);
    Image& albedo = fb.add("albedo", 4);
    Image& mv = fb.add("motion", 2);
    const float specials[] = {-0.f, -1.5f, 1e30f, -3e38f, FLT_MAX, -FLT_MAX, 1e-40f, FLT_MIN, 123456.789f};
    int k = 0;
    for (Image* img : {&zeta, &color, &depth, &albedo, &mv})
        for (float& v : img->values()) v = (k % 5 == 0) ? specials[(k / 5) % 9] : float(k) * 0.37f - 20.f, ++k;
    fb.metadata()["spp"] = "16";
    fb.metadata()["integrator"] = "gpt";
    fb.metadata()["multi"] = "line one\nline two";
    fb.metadata()["empty"] = "";

    const std::string path = tmp / "multi.exr";
    write_exr(path, fb);
    const FrameBuffer back = read_exr(path);
    REQUIRE(back.width() == w);
    REQUIRE(back.height() == h);
    REQUIRE(back.names() == fb.names());
    for (const auto& name : fb.names()) {
        const Image& a = fb.get(name);
        const Image& b = back.get(name);
        INFO(name);
        REQUIRE(a.same_shape(b));
        REQUIRE(std::memcmp(a.data(), b.data(), a.values().size() * sizeof(float)) == 0);
    }
    REQUIRE(back.metadata() == fb.metadata());

    // The "color" layer is stored as bare R, G, B (viewer-visible) and the
    // rest under their prefix: look at the uncompressed channel list bytes.
    const std::string bytes = slurp(path);
    const std::string float_tag("\x02\0\0\0", 4);
    REQUIRE(bytes.find(std::string("\x01\0\0\0G\0", 6) + float_tag) != std::string::npos);
    REQUIRE(bytes.find(std::string("\x01\0\0\0R\0", 6) + float_tag) != std::string::npos);
    REQUIRE(bytes.find("color.R") == std::string::npos);
    REQUIRE(bytes.find(std::string("depth.Y\0", 8)) != std::string::npos);
    REQUIRE(bytes.find(std::string("zeta.B\0", 7)) != std::string::npos);
    REQUIRE(bytes.find(std::string("gdr:spp\0", 8)) != std::string::npos);

    // No temporary file is left next to the output.
    int files = 0;
    for (const auto& e : fs::directory_iterator(tmp.dir)) files += e.is_regular_file() ? 1 : 0;
    REQUIRE(files == 1);
}

TEST_CASE("exr: single images and read_exr_rgb", "[io]") {
    TempDir tmp;
    Image rgb(4, 3, 3);
    for (size_t i = 0; i < rgb.values().size(); ++i) rgb.values()[i] = float(i) - 5.f;
    write_exr_image(tmp / "rgb.exr", rgb);
    const Image back = read_exr_rgb(tmp / "rgb.exr");
    REQUIRE(back.same_shape(rgb));
    REQUIRE(back.values() == rgb.values());
    REQUIRE(read_exr(tmp / "rgb.exr").names() == std::vector<std::string>{"color"});

    Image grey(4, 3, 1);
    grey.at(2, 1) = 7.f;
    write_exr_image(tmp / "grey.exr", grey);
    const Image g3 = read_exr_rgb(tmp / "grey.exr");
    REQUIRE(g3.channels() == 3);
    REQUIRE(g3.rgb(2, 1) == Color(7.f));

    // A gdr multi-layer output: read_exr_rgb picks the viewer-visible "color".
    FrameBuffer fb(4, 3);
    fb.set("dx", rgb);
    Image& c = fb.add("color", 3);
    c.at(1, 1, 2) = 3.f;
    write_exr(tmp / "fb.exr", fb);
    REQUIRE(read_exr_rgb(tmp / "fb.exr").values() == c.values());

    // Several layers and no "color": ambiguous.
    fb.remove("color");
    fb.add("dy", 3);
    write_exr(tmp / "nocolor.exr", fb);
    REQUIRE_THROWS_AS(read_exr_rgb(tmp / "nocolor.exr"), InputError);
}

TEST_CASE("exr: files from other software, HALF channels and an offset data window", "[io]") {
    TempDir tmp;
    const std::string path = tmp / "foreign.exr";
    // Data window (3,5)-(6,6): a 4x2 image not at the origin.
    auto value = [](const std::string& ch, int x, int y) {
        const float base = ch == "B" ? 0.25f : ch == "G" ? -2.f : ch == "R" ? 1.5f : 100.f;
        return base * float(1 + x - 3) + float(y - 5) * 8.f;  // all exactly representable in half
    };
    write_raw_exr(path, {{"B", true}, {"G", true}, {"R", false}, {"normal.X", false}, {"normal.Y", true},
                         {"normal.Z", false}},
                  3, 5, 6, 6, [&](const std::string& ch, int x, int y) {
                      if (ch.rfind("normal.", 0) == 0) return float(ch.back() - 'X') + float(x) * 0.5f - float(y);
                      return value(ch, x, y);
                  });
    const FrameBuffer fb = read_exr(path);
    REQUIRE(fb.width() == 4);
    REQUIRE(fb.height() == 2);
    REQUIRE(fb.has("color"));
    REQUIRE(fb.has("normal"));
    REQUIRE(fb.metadata().at("owner") == "other");
    const Image& c = fb.get("color");
    const Image& n = fb.get("normal");
    REQUIRE(c.channels() == 3);
    REQUIRE(n.channels() == 3);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x) {
            REQUIRE(c.at(x, y, 0) == value("R", x + 3, y + 5));
            REQUIRE(c.at(x, y, 1) == value("G", x + 3, y + 5));
            REQUIRE(c.at(x, y, 2) == value("B", x + 3, y + 5));
            for (int k = 0; k < 3; ++k) REQUIRE(n.at(x, y, k) == float(k) + float(x + 3) * 0.5f - float(y + 5));
        }
    REQUIRE(read_exr_rgb(path).values() == c.values());
}

TEST_CASE("exr: reads the Mitsuba G-PT reference outputs", "[io]") {
    const std::string dir = std::string(GDR_SHARED_DIR) + "/reference-outputs/mitsuba-gpt-cbox-16spp/";
    if (!std::filesystem::exists(dir + "cbox-final.exr")) {
        WARN("skipped: needs the Mitsuba G-PT reference outputs in " << dir
                                                                    << " (GDR_SHARED_DIR: renders of the public Mitsuba G-PT implementation, not part of the repository)");
        return;
    }
    Image fin;
    for (const std::string name : {"throughput", "dx", "dy", "direct", "final"}) {
        INFO(name);
        FrameBuffer fb = read_exr(dir + "cbox-" + name + ".exr");
        REQUIRE(fb.names() == std::vector<std::string>{"color"});
        const Image& img = fb.get("color");
        REQUIRE(img.width() == 512);
        REQUIRE(img.height() == 512);
        REQUIRE(img.channels() == 3);
        REQUIRE_NOTHROW(require_finite(img, name));
        double sum = 0, sum_abs = 0;
        for (float v : img.values()) sum += v, sum_abs += std::abs(v);
        const double mean = sum / double(img.values().size());
        // Gradients are signed and average out; radiance images must be positive.
        if (name == "dx" || name == "dy") REQUIRE(sum_abs > 0);
        else REQUIRE(mean > 0);
        if (name == "final") fin = img;
    }
    // The Cornell box light is warm (radiance 17, 12, 4): R > G > B on average,
    // which catches a B/G/R channel-order mix-up.
    double m[3] = {0, 0, 0};
    for (size_t p = 0; p < fin.pixel_count(); ++p)
        for (int k = 0; k < 3; ++k) m[k] += fin.values()[p * 3 + k];
    REQUIRE(m[0] > m[1]);
    REQUIRE(m[1] > m[2]);
}

TEST_CASE("exr: missing, garbage and truncated files are InputErrors naming the path", "[io]") {
    TempDir tmp;
    const std::string missing = tmp / "does-not-exist.exr";
    REQUIRE_THROWS_WITH(read_exr(missing), Catch::Contains(missing));
    REQUIRE_THROWS_AS(read_exr(missing), InputError);
    REQUIRE_THROWS_AS(read_exr_rgb(missing), InputError);

    const std::string garbage = tmp / "garbage.exr";
    std::ofstream(garbage) << "this is not an OpenEXR file, just some text\n";
    REQUIRE_THROWS_AS(read_exr(garbage), InputError);
    REQUIRE_THROWS_WITH(read_exr(garbage), Catch::Contains(garbage));

    Image img(64, 64, 3);
    for (size_t i = 0; i < img.values().size(); ++i) img.values()[i] = std::sin(float(i));
    const std::string good = tmp / "good.exr", cut = tmp / "cut.exr";
    write_exr_image(good, img);
    const std::string bytes = slurp(good);
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    REQUIRE_THROWS_AS(read_exr(cut), InputError);
    REQUIRE_THROWS_WITH(read_exr(cut), Catch::Contains(cut));
}

TEST_CASE("exr: write errors are RuntimeFailures naming the path", "[io]") {
    TempDir tmp;
    const std::string bad = tmp / "no-such-dir/out.exr";
    REQUIRE_THROWS_AS(write_exr_image(bad, Image(2, 2, 3)), RuntimeFailure);
    REQUIRE_THROWS_WITH(write_exr_image(bad, Image(2, 2, 3)), Catch::Contains(bad));
    REQUIRE_THROWS_AS(write_exr(tmp / "empty.exr", FrameBuffer(4, 4)), ParameterError);
}

TEST_CASE("exr: files written and read with OpenEXR threads are the same as without", "[io]") {
    TempDir tmp;
    FrameBuffer fb(37, 29);
    fb.add("color", 3);
    for (size_t i = 0; i < fb.get("color").values().size(); ++i) fb.get("color").values()[i] = float(i % 97) * 0.37f;
    const auto bytes = [](const std::string& path) {
        std::ifstream in(path, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    set_exr_threads(0);
    write_exr(tmp / "serial.exr", fb);
    set_exr_threads(2);
    write_exr(tmp / "threaded.exr", fb);
    const FrameBuffer back = read_exr(tmp / "threaded.exr");
    set_exr_threads(0);
    CHECK(bytes(tmp / "serial.exr") == bytes(tmp / "threaded.exr"));
    CHECK(back.get("color").values() == fb.get("color").values());
    CHECK_THROWS_AS(set_exr_threads(-1), ParameterError);
}

TEST_CASE("exr, png: writing through a symlink updates its target and keeps the link", "[io]") {
    // The temporary-then-rename write would otherwise replace the link with a
    // file (and, run as root on -o /dev/null, the device with a file).
    TempDir tmp;
    const std::string target = tmp / "target.exr", link = tmp / "link.exr";
    write_exr_image(target, Image(2, 2, 3, 1.f));
    std::filesystem::create_symlink(target, link);
    write_exr_image(link, Image(2, 2, 3, 5.f));
    CHECK(std::filesystem::is_symlink(link));
    CHECK(read_exr_rgb(target).at(1, 1, 0) == 5.f);
    const std::string png_target = tmp / "target.png", png_link = tmp / "link.png";
    write_png_preview(png_target, Image(2, 2, 3, 0.f));
    std::filesystem::create_symlink(png_target, png_link);
    write_png_preview(png_link, Image(2, 2, 3, 1.f));
    CHECK(std::filesystem::is_symlink(png_link));
    int w = 0, h = 0, c = 0;
    unsigned char* px = stbi_load(png_target.c_str(), &w, &h, &c, 3);
    REQUIRE(px);
    CHECK(px[0] == 255);
    stbi_image_free(px);
    // No temporaries are left beside them: two targets, two links.
    int entries = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.dir)) ++entries;
    CHECK(entries == 4);
}

TEST_CASE("png: sRGB preview with exposure and clamping is readable", "[io]") {
    TempDir tmp;
    Image img(3, 2, 3);
    img.set_rgb(0, 0, Color(0.5f, 0.f, 1.f));
    img.set_rgb(1, 0, Color(2.f, -1.f, 0.0031308f));
    img.set_rgb(2, 0, Color(0.25f, 0.22f, 1e-4f));
    img.at(0, 1, 0) = std::numeric_limits<float>::quiet_NaN();
    const std::string path = tmp / "preview.png";
    write_png_preview(path, img);

    int w = 0, h = 0, n = 0;
    unsigned char* px = stbi_load(path.c_str(), &w, &h, &n, 0);
    REQUIRE(px != nullptr);
    REQUIRE(w == 3);
    REQUIRE(h == 2);
    REQUIRE(n == 3);
    auto at = [&](int x, int y, int k) { return int(px[(y * w + x) * n + k]); };
    REQUIRE(at(0, 0, 0) == 188);  // sRGB(0.5) = 0.7354
    REQUIRE(at(0, 0, 1) == 0);
    REQUIRE(at(0, 0, 2) == 255);
    REQUIRE(at(1, 0, 0) == 255);  // clamped
    REQUIRE(at(1, 0, 1) == 0);    // clamped
    REQUIRE(at(1, 0, 2) == 10);   // 0.04045 * 255 = 10.3
    REQUIRE(at(2, 0, 1) == 129);  // sRGB(0.22) = 0.5064
    REQUIRE(at(0, 1, 0) == 0);    // NaN written as black
    stbi_image_free(px);

    // One stop up maps 0.25 to what 0.5 gives.
    write_png_preview(path, img, 1.f);
    px = stbi_load(path.c_str(), &w, &h, &n, 0);
    REQUIRE(px != nullptr);
    REQUIRE(at(2, 0, 0) == 188);
    stbi_image_free(px);

    // Grey stays grey, RGBA keeps a linear alpha.
    Image grey(2, 2, 1, 0.5f), rgba(2, 2, 4, 0.5f);
    write_png_preview(tmp / "grey.png", grey);
    write_png_preview(tmp / "rgba.png", rgba);
    px = stbi_load((tmp / "grey.png").c_str(), &w, &h, &n, 0);
    REQUIRE(px != nullptr);
    REQUIRE(n == 1);
    REQUIRE(at(1, 1, 0) == 188);
    stbi_image_free(px);
    px = stbi_load((tmp / "rgba.png").c_str(), &w, &h, &n, 0);
    REQUIRE(px != nullptr);
    REQUIRE(n == 4);
    REQUIRE(at(1, 1, 0) == 188);
    REQUIRE(at(1, 1, 3) == 128);
    stbi_image_free(px);

    const std::string bad = tmp / "no-such-dir/p.png";
    REQUIRE_THROWS_AS(write_png_preview(bad, img), RuntimeFailure);
    REQUIRE_THROWS_WITH(write_png_preview(bad, img), Catch::Contains(bad));
}

TEST_CASE("png: sRGB transfer functions round trip and match the standard", "[io]") {
    for (int i = 0; i <= 1000; ++i) {
        const float v = float(i) / 1000.f;
        REQUIRE(srgb_to_linear(linear_to_srgb(v)) == Approx(v).margin(1e-6));
        REQUIRE(linear_to_srgb(srgb_to_linear(v)) == Approx(v).margin(1e-6));
    }
    // Every 8-bit code survives decode -> encode -> quantise.
    for (int b = 0; b < 256; ++b) REQUIRE(int(linear_to_srgb(srgb_to_linear(b / 255.f)) * 255.f + 0.5f) == b);
    REQUIRE(linear_to_srgb(0.f) == 0.f);
    REQUIRE(linear_to_srgb(1.f) == Approx(1.f));
    REQUIRE(linear_to_srgb(0.18f) == Approx(0.4613561f).epsilon(1e-5));
    REQUIRE(srgb_to_linear(0.5f) == Approx(0.2140411f).epsilon(1e-5));
    // Continuity at the linear/power knee.
    REQUIRE(linear_to_srgb(0.0031308f) == Approx(linear_to_srgb(0.00313081f)).epsilon(1e-4));
}
