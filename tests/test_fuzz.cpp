// Bounded fuzzing of the gdr tool: a few hundred mutated scene files, OBJs,
// MTLs and render EXRs (fixed seed), each run through the commands that read
// them. Every run must end in success or a gdr::Error, never a crash or any
// other exception, within its time limit; no written image may hold a NaN
// or Inf; and no input file may change.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"

using namespace gdr;
namespace fs = std::filesystem;

namespace {

std::string read_bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}
void write_bytes(const fs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

// Text that parsers find hard: huge, negative, non-finite and malformed numbers, stray syntax.
const std::vector<std::string> kTokens = {"1e30", "-999", "+999", "nan", "inf", "-0", "0", "1e-45", "99999999999999999999",
                                          "\"", "{", "}", "[", "]", ",", ":", "\n", "f 1 2", "v 1 2", "#", "/", "\\",
                                          "\"width\": 1e9", "\"spp\": 0", "Kd -1 2 nan", "newmtl", "map_Kd x.png"};

// One random change to `s`: flip, delete, duplicate, insert a token, or truncate.
std::string mutate(std::string s, std::mt19937& rng) {
    if (s.empty()) return kTokens[rng() % kTokens.size()];
    const auto pos = [&] { return size_t(rng() % s.size()); };
    switch (rng() % 6) {
        case 0: s[pos()] = char(rng() % 256); break;
        case 1: {
            const size_t a = pos();
            s.erase(a, std::min<size_t>(1 + rng() % 16, s.size() - a));
            break;
        }
        case 2: {
            const size_t a = pos();
            s.insert(pos(), s.substr(a, 1 + rng() % 32));
            break;
        }
        case 3: s.insert(pos(), kTokens[rng() % kTokens.size()]); break;
        case 4: s.resize(pos()); break;
        default: {
            // Zero a run of bytes, as a damaged disk block does.
            const size_t a = pos();
            for (size_t i = a; i < std::min(s.size(), a + 1 + rng() % 64); ++i) s[i] = '\0';
        }
    }
    return s;
}

// Every value of every layer of the EXR at `p` is finite (true if it is no readable EXR).
bool finite_exr(const fs::path& p) {
    FrameBuffer fb;
    try {
        fb = read_exr(p);
    } catch (const Error&) {
        return true;
    }
    for (const auto& name : fb.names())
        for (float v : fb.get(name).values())
            if (!std::isfinite(v)) return false;
    return true;
}

}  // namespace

TEST_CASE("fuzz: mutated scenes, meshes, materials and EXRs: no crash, hang, NaN output or changed input", "[fuzz]") {
    const fs::path dir = fs::temp_directory_path() / ("gdr-test-fuzz-" + std::to_string(getpid()));
    fs::create_directories(dir);
    struct Cleanup {
        fs::path d;
        ~Cleanup() {
            std::error_code ec;
            fs::remove_all(d, ec);
        }
    } cleanup{dir};

    // The originals: the Cornell box at 8x8, and an EXR of each integrator.
    const std::string box = GDR_SOURCE_DIR "/scenes/cornell-box/";
    const std::string scene_text =
        R"({"camera": {"position": [0, 1, 3.5], "target": [0, 1, 0], "up": [0, 1, 0], "fov": 45, "width": 8, "height": 8},
  "meshes": ["box.obj"],
  "materials": {"shortBox": {"kd": [0.5, 0.5, 0.5]}},
  "render": {"integrator": "pt", "spp": 1, "params": {"max_depth": 6}}})";
    const std::string obj_text = read_bytes(box + "CornellBox-Original.obj");
    const std::string mtl_text = read_bytes(box + "CornellBox-Original.mtl");
    write_bytes(dir / "scene.json", scene_text);
    write_bytes(dir / "box.obj", obj_text);
    write_bytes(dir / "CornellBox-Original.mtl", mtl_text);
    REQUIRE(cli::run({"render", (dir / "scene.json").string(), "--spp", "2", "-o", (dir / "pt.exr").string()}) == 0);
    REQUIRE(cli::run({"render", (dir / "scene.json").string(), "--integrator", "gpt", "--spp", "2", "--seed", "1", "-o",
                      (dir / "gpt.exr").string()}) == 0);
    REQUIRE(cli::run({"render", (dir / "scene.json").string(), "--integrator", "gpt", "--spp", "2", "--seed", "2", "-o",
                      (dir / "gpt2.exr").string()}) == 0);
    const std::string exr_text[2] = {read_bytes(dir / "pt.exr"), read_bytes(dir / "gpt.exr")};
    const std::string gpt2 = (dir / "gpt2.exr").string();

    std::mt19937 rng(20261201);
    constexpr int kCases = 320;
    int errors = 0, successes = 0;
    const auto t_start = std::chrono::steady_clock::now();
    for (int i = 0; i < kCases; ++i) {
        // Restore the originals, then damage one file with one change, or two.
        write_bytes(dir / "scene.json", scene_text);
        write_bytes(dir / "box.obj", obj_text);
        write_bytes(dir / "CornellBox-Original.mtl", mtl_text);
        const int which = int(rng() % 10);
        const int exr_kind = int(rng() % 2);
        const fs::path target = which < 4   ? dir / "scene.json"
                                : which < 6 ? dir / "box.obj"
                                : which < 7 ? dir / "CornellBox-Original.mtl"
                                            : dir / "in.exr";
        std::string text = target == dir / "scene.json"                ? scene_text
                           : target == dir / "box.obj"                 ? obj_text
                           : target == dir / "CornellBox-Original.mtl" ? mtl_text
                                                                       : exr_text[exr_kind];
        for (int k = 0, n = 1 + int(rng() % 4 == 0); k < n; ++k) text = mutate(text, rng);
        write_bytes(target, text);

        const std::string o = (dir / ("out" + std::to_string(i) + ".exr")).string();
        std::vector<std::string> args;
        if (target != dir / "in.exr") {
            args = {"render", (dir / "scene.json").string(), "--spp", "1", "--resolution", "8x8", "-o", o};
            if (rng() % 3 == 0) args.insert(args.begin() + 2, {"--integrator", "gpt"});
        } else {
            const std::string in = target.string();
            switch (rng() % 5) {
                case 0: args = {"info", in}; break;
                case 1: args = {"merge", in, exr_kind ? gpt2 : (dir / "pt.exr").string(), "-o", o}; break;
                case 2: args = {"reconstruct", in, "-o", o}; break;
                case 3: args = {"compare", in, exr_kind ? gpt2 : (dir / "pt.exr").string()}; break;
                default: args = {"render", (dir / "scene.json").string(), "--spp", "3", "--resume", in, "-o", o};
            }
        }
        std::string cmd;
        for (const auto& a : args) cmd += a + " ";
        INFO("case " << i << ": " << cmd);

        // Every input, to check that none changed.
        std::vector<std::pair<fs::path, std::string>> inputs;
        for (const auto& e : fs::directory_iterator(dir))
            if (e.is_regular_file() && e.path().filename().string().rfind("out", 0) != 0)
                inputs.emplace_back(e.path(), read_bytes(e.path()));

        const auto t0 = std::chrono::steady_clock::now();
        try {
            std::fflush(stdout);
            cli::run(args);
            ++successes;
        } catch (const Error& e) {
            if (std::getenv("GDR_FUZZ_VERBOSE")) std::fprintf(stderr, "case %d: %s\n", i, e.what());
            ++errors;
        } catch (const std::exception& e) {
            FAIL_CHECK("not a gdr::Error: " << e.what());
        }
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        CHECK(seconds < 10.0);
        for (const auto& [path, content] : inputs) {
            INFO("input " << path);
            CHECK(read_bytes(path) == content);
        }
        if (fs::exists(o)) {
            CHECK(finite_exr(o));
            fs::remove(o);
        }
        std::error_code ec;
        fs::remove(fs::path(o).replace_extension(".png"), ec);
    }
    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    // Both outcomes occur: a fuzzer whose inputs all fail (or all pass)
    // would not be exercising the readers.
    CHECK(errors > kCases / 10);
    CHECK(successes > kCases / 20);
    CHECK(total < 60.0);
    WARN("fuzz: " << kCases << " cases, " << successes << " ran, " << errors << " refused with a gdr::Error, in " << total
                  << " s");
}
