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

/// Removes directory `d` and everything in it when the test ends, passed or failed.
struct RemoveOnExit {
    fs::path d;
    ~RemoveOnExit() {
        std::error_code ec;
        fs::remove_all(d, ec);
    }
};

}  // namespace

TEST_CASE("fuzz: mutated scenes, meshes, materials and EXRs: no crash, hang, NaN output or changed input", "[fuzz]") {
    const fs::path dir = fs::temp_directory_path() / ("gdr-test-fuzz-" + std::to_string(getpid()));
    fs::create_directories(dir);
    const RemoveOnExit cleanup{dir};

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

// ---------------------------------------------------------------------------
// Hostile structure, special files and far-away coordinates, through the real
// gdr binary (a crash must fail the test, not end the test process): seeded
// random Mitsuba XML and PLY structure (nesting depth, reference chains,
// element counts, sizes, types, truncation), FIFOs, devices and directories
// in place of every kind of input, and coordinates near and beyond float
// range. Every case must end, within its bound, in exit 0 with a finite
// output or exit 1 with one line "gdr: error: ..." naming one of its input
// files, never in a signal; and no input may change.
#ifdef GDR_TOOL

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <cstring>
#include <functional>
#include <map>
#include <sstream>
#include <thread>

extern char** environ;

namespace {

/// What a bounded run of the gdr binary did.
struct BoundedRun {
    int status = -1;         ///< Exit status, 128 + N if killed by signal N, -1 if it could not start.
    bool timed_out = false;  ///< Killed (SIGKILL) for running past its bound.
    double seconds = 0;      ///< Wall time.
    std::string output;      ///< Standard output and error.
};

/// Runs gdr with `args` (stdin /dev/null, output into `log`), killing it after `limit` seconds.
BoundedRun run_bounded(const std::vector<std::string>& args, const std::string& log, double limit) {
    std::vector<char*> argv{const_cast<char*>(GDR_TOOL)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    BoundedRun r;
    pid_t pid = 0;
    const auto t0 = std::chrono::steady_clock::now();
    const int rc = posix_spawn(&pid, GDR_TOOL, &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) return r;
    int ws = 0;
    for (;;) {
        const pid_t done = waitpid(pid, &ws, WNOHANG);
        if (done == pid) break;
        if (done < 0 && errno != EINTR) return r;
        if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit) {
            kill(pid, SIGKILL);
            while (waitpid(pid, &ws, 0) < 0 && errno == EINTR) {
            }
            r.timed_out = true;
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    r.status = WIFEXITED(ws) ? WEXITSTATUS(ws) : 128 + WTERMSIG(ws);
    r.output = read_bytes(log);
    return r;
}

/// Outcomes of one family of cases, for the summary line.
struct Tally {
    int cases = 0, ran = 0, refused = 0, bad = 0;
};

/// The regular files under `dir` (not its outputs, named out*), with their contents.
std::vector<std::pair<fs::path, std::string>> snapshot(const fs::path& dir) {
    std::vector<std::pair<fs::path, std::string>> v;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.is_regular_file() && e.path().filename().string().rfind("out", 0) != 0 &&
            e.path().extension() != ".log")
            v.emplace_back(e.path(), read_bytes(e.path()));
    return v;
}

/// Runs one case and checks it as the block comment above says; `names` are
/// the file names of which its error message must contain one.
void run_case(Tally& t, const std::string& label, const fs::path& dir, std::vector<std::string> args,
              const std::vector<std::string>& names, double limit = 20.0) {
    ++t.cases;
    const fs::path out = dir / "out.exr";
    std::error_code ec;
    fs::remove(out, ec);
    fs::remove(fs::path(out).replace_extension(".png"), ec);
    const auto before = snapshot(dir);
    const BoundedRun r = run_bounded(args, (dir / "run.log").string(), limit);
    std::string cmd;
    for (const auto& a : args) cmd += (a.size() > 80 ? a.substr(0, 80) + "..." : a) + " ";
    INFO(label << ": gdr " << cmd << "\nexit " << r.status << (r.timed_out ? " (killed: past its bound)" : "")
               << " after " << r.seconds << " s; output:\n" << r.output.substr(0, 2000));
    bool good = !r.timed_out && r.status >= 0 && r.status < 128;
    CHECK(!r.timed_out);
    CHECK(r.status >= 0);
    CHECK(r.status < 128);  // no signal death
    // check-shift's verdict on a shift (exit 1 with FAIL lines, no error) is a result, not a refusal.
    const bool verdict = args[0] == "check-shift" && r.status == 1 && r.output.find("gdr: error:") == std::string::npos &&
                         r.output.find("FAIL: ") != std::string::npos;
    if (good && (r.status == 0 || verdict)) {
        ++t.ran;
        if (fs::exists(out)) {
            const bool finite = finite_exr(out);
            CHECK(finite);
            good = good && finite;
        }
    } else if (good) {
        // One error line, naming one of the case's input files.
        std::istringstream lines(r.output);
        int errors = 0;
        std::string error;
        for (std::string line; std::getline(lines, line);)
            if (line.rfind("gdr: error: ", 0) == 0) ++errors, error = line;
        bool named = false;
        for (const auto& n : names) named = named || error.find(n) != std::string::npos;
        CHECK(r.status == 1);
        CHECK(errors == 1);
        CHECK(named);
        if (std::getenv("GDR_FUZZ_VERBOSE")) std::fprintf(stderr, "%s: %s\n", label.c_str(), error.c_str());
        good = r.status == 1 && errors == 1 && named;
        if (good) ++t.refused;
    }
    for (const auto& [path, content] : before) {
        INFO("input " << path);
        const bool same = read_bytes(path) == content;
        CHECK(same);
        good = good && same;
    }
    if (!good) ++t.bad;
}

/// A Mitsuba scene of an 8x8 camera at `origin`, a lit rectangle and `extra` shapes and BSDFs.
std::string mitsuba_scene(const std::string& origin, const std::string& extra, const std::string& reflectance = "0.5",
                          const std::string& radiance = "1") {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin=")" + origin + R"(" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  <shape type="rectangle"><bsdf type="diffuse"><rgb name="reflectance" value=")" + reflectance + R"("/></bsdf></shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="180"/><translate z="2"/></transform>
    <emitter type="area"><rgb name="radiance" value=")" + radiance + R"("/></emitter>
  </shape>
)" + extra + "</scene>\n";
}

/// A JSON scene of the Cornell box mesh `mesh` seen from `position`.
std::string json_scene(const std::string& position, const std::string& mesh = "box.obj", const std::string& extra = "") {
    return R"({"camera": {"position": )" + position +
           R"(, "target": [0, 1, 0], "up": [0, 1, 0], "fov": 45, "width": 8, "height": 8},
  "meshes": [")" + mesh + R"("],)" + extra + R"(
  "render": {"integrator": "pt", "spp": 1}})";
}

/// `n` levels of `open` around `inner`, closed by `close`.
std::string nest(const std::string& open, const std::string& inner, const std::string& close, int n) {
    std::string s;
    s.reserve((open.size() + close.size()) * size_t(n) + inner.size());
    for (int i = 0; i < n; ++i) s += open;
    s += inner;
    for (int i = 0; i < n; ++i) s += close;
    return s;
}

/// A quad (two triangles) as a PLY file, ASCII or binary little-endian.
std::string quad_ply(bool binary) {
    std::string s = std::string("ply\nformat ") + (binary ? "binary_little_endian" : "ascii") +
                    " 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
    const float v[4][3] = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
    const int f[2][3] = {{0, 1, 2}, {0, 2, 3}};
    if (!binary) return s + "-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2\n3 0 2 3\n";
    for (const auto& p : v) s.append(reinterpret_cast<const char*>(p), sizeof p);
    for (const auto& t : f) {
        s += char(3);
        s.append(reinterpret_cast<const char*>(t), sizeof t);
    }
    return s;
}

/// A random structural change of a PLY file: counts, extra elements, property lines and types, format, body bytes.
std::string mutate_ply(std::string s, std::mt19937& rng) {
    static const std::vector<std::string> kCounts = {"0", "1", "3", "5", "1000", "1000000", "1000000000000",
                                                     "18446744073709551615", "18446744073709551616", "-1"};
    static const std::vector<std::string> kTypes = {"char", "uchar", "short", "int", "uint", "float", "double",
                                                    "int64", "list uchar int", "list int float", "list float int"};
    const size_t end = s.find("end_header\n") + 11;
    std::string head = s.substr(0, end), body = s.substr(end);
    const auto replace_line = [&](const std::string& prefix, const std::string& line) {
        const size_t a = head.find(prefix);
        if (a != std::string::npos) head.replace(a, head.find('\n', a) - a, line);
    };
    switch (rng() % 8) {
        case 0: replace_line("element vertex", "element vertex " + kCounts[rng() % kCounts.size()]); break;
        case 1: replace_line("element face", "element face " + kCounts[rng() % kCounts.size()]); break;
        case 2: {
            std::string e = "element junk " + kCounts[rng() % kCounts.size()] + "\n";
            for (int k = int(rng() % 3); k > 0; --k) e += "property " + kTypes[rng() % kTypes.size()] + " j" + std::to_string(k) + "\n";
            head.insert(rng() % 2 ? head.find("end_header") : head.find("element vertex"), e);
            break;
        }
        case 3: replace_line(rng() % 2 ? "property float y" : "property list", "comment dropped"); break;
        case 4: replace_line(rng() % 2 ? "property float z" : "property list", "property " + kTypes[rng() % kTypes.size()] + " z"); break;
        case 5: body.resize(body.empty() ? 0 : rng() % body.size()); break;
        case 6:
            if (!body.empty())
                for (int k = 1 + int(rng() % 4); k > 0; --k) body[rng() % body.size()] = char(rng() % 256);
            break;
        default:
            replace_line("format", rng() % 2 ? "format ascii 1.0" : "format binary_big_endian 1.0");
    }
    return head + body;
}

/// A far-away number: 10^k with k drawn from near and beyond the coordinate and float ranges.
std::string far_number(std::mt19937& rng) {
    static const int kExp[] = {0, 3, 10, 14, 15, 16, 18, 19, 20, 30, 38, 39, 300};
    return (rng() % 4 == 0 ? "-1e" : "1e") + std::to_string(kExp[rng() % std::size(kExp)]);
}

}  // namespace

TEST_CASE("fuzz: hostile structure, special files and far-away coordinates through the gdr binary",
          "[fuzz][cli]") {
    const fs::path dir = fs::temp_directory_path() / ("gdr-test-fuzz-hostile-" + std::to_string(getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const RemoveOnExit cleanup{dir};
    const auto at = [&](const std::string& name) { return (dir / name).string(); };
    const std::string box = GDR_SOURCE_DIR "/scenes/cornell-box/";
    const std::string obj_text = read_bytes(box + "CornellBox-Original.obj");
    const std::string mtl_text = read_bytes(box + "CornellBox-Original.mtl");
    const std::string out = at("out.exr");
    const auto render = [&](const std::string& scene, std::vector<std::string> more = {}) {
        std::vector<std::string> a = {"render", scene, "--spp", "1", "--threads", "1", "-o", out};
        a.insert(a.begin() + 2, more.begin(), more.end());
        return a;
    };
    // Writes `files`, runs the case, then removes them, so that each case sees only its own inputs.
    const auto with_files = [&](const std::map<std::string, std::string>& files, const std::function<void()>& f) {
        for (const auto& [name, text] : files) write_bytes(dir / name, text);
        f();
        for (const auto& [name, text] : files) fs::remove(dir / name);
    };
    std::map<std::string, Tally> tally;
    const auto t_start = std::chrono::steady_clock::now();

    SECTION("fixed regression cases") {
        Tally& t = tally["regression"];
        // Each of these crashed, hung or ran away before its fix (checked
        // against the unfixed binary): the status in each comment.
        // SIGSEGV: 16,000 nested twosided BSDFs overflowed the importer's recursion.
        with_files({{"deep.xml", mitsuba_scene("0, 0, 5", "<shape type=\"rectangle\">" +
                                                               nest("<bsdf type=\"twosided\">", "<bsdf type=\"diffuse\"/>",
                                                                    "</bsdf>", 16000) + "</shape>\n")}},
                   [&] {
                       run_case(t, "16000 nested twosided", dir, render(at("deep.xml")), {"deep.xml"});
                       run_case(t, "16000 nested twosided, check-shift", dir,
                                {"check-shift", at("deep.xml"), "--paths", "10"}, {"deep.xml"});
                   });
        // SIGSEGV: 32,000 nested elements of any name (the id index recursed over them).
        with_files({{"deep.xml", mitsuba_scene("0, 0, 5", "<shape type=\"rectangle\">" + nest("<a>", "", "</a>", 32000) +
                                                               "</shape>\n")}},
                   [&] { run_case(t, "32000 nested elements", dir, render(at("deep.xml")), {"deep.xml"}); });
        // SIGSEGV: a chain of 20,000 twosided BSDFs, each referring to the next, recursed as deep.
        {
            std::string chain;
            for (int i = 0; i < 20000; ++i)
                chain += "<bsdf type=\"twosided\" id=\"b" + std::to_string(i) + "\"><ref id=\"b" + std::to_string(i + 1) +
                         "\"/></bsdf>\n";
            chain += "<bsdf type=\"diffuse\" id=\"b20000\"/>\n<shape type=\"rectangle\"><ref id=\"b0\"/></shape>\n";
            with_files({{"chain.xml", mitsuba_scene("0, 0, 5", chain)}},
                       [&] { run_case(t, "20000 chained refs", dir, render(at("chain.xml")), {"chain.xml"}); });
        }
        // SIGABRT in Embree (ray.valid()): a camera at 1e19, for every integrator and check-shift.
        with_files({{"box.obj", obj_text}, {"CornellBox-Original.mtl", mtl_text}, {"far.json", json_scene("[0, 1, 1e19]")}},
                   [&] {
                       for (const char* integrator : {"pt", "bdpt", "gpt", "gbdpt"})
                           run_case(t, std::string("camera at 1e19, ") + integrator, dir,
                                    render(at("far.json"), {"--integrator", integrator}), {"far.json"});
                       run_case(t, "camera at 1e19, check-shift", dir, {"check-shift", at("far.json"), "--paths", "10"},
                                {"far.json"});
                   });
        // Exit 1 blaming the up vector: a camera at 1e20 (its distance to the target overflowed).
        with_files({{"box.obj", obj_text}, {"CornellBox-Original.mtl", mtl_text}, {"far.json", json_scene("[0, 1, 1e20]")}},
                   [&] {
                       run_case(t, "camera at 1e20", dir, render(at("far.json")), {"far.json"});
                       CHECK_THAT(read_bytes(dir / "run.log"), Catch::Contains("position") && !Catch::Contains("up is"));
                   });
        // Exit 0, rendered with samples dropped: a reflectance of 1e39 (Inf in float).
        with_files({{"bright.xml", mitsuba_scene("0, 0, 5", "", "1e39")}}, [&] {
            run_case(t, "reflectance 1e39", dir, render(at("bright.xml")), {"bright.xml"});
            CHECK_THAT(read_bytes(dir / "run.log"), Catch::Contains("float range"));
        });
        // Endless loop: a PLY element of 10^12 items without properties.
        with_files({{"huge.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                 "element junk 1000000000000\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"},
                    {"huge.xml", mitsuba_scene("0, 0, 5", "<shape type=\"ply\"><string name=\"filename\" "
                                                          "value=\"huge.ply\"/></shape>\n")}},
                   [&] { run_case(t, "PLY element of 10^12 items", dir, render(at("huge.xml")), {"huge.ply"}, 10.0); });
        // 15 s and 470 MB of allocation, then a message about missing layers: an
        // EXR of 1.5 kB whose header declares a data window of 2^20 x 8 pixels.
        {
            write_bytes(dir / "bright.xml", mitsuba_scene("0, 0, 5", ""));
            REQUIRE(run_bounded({"render", at("bright.xml"), "--spp", "1", "-o", at("small.exr")}, at("run.log"), 30).status == 0);
            std::string exr = read_bytes(dir / "small.exr");
            fs::remove(dir / "small.exr");
            fs::remove(dir / "small.png");
            fs::remove(dir / "bright.xml");
            const std::string key = std::string("dataWindow") + '\0' + "box2i" + '\0';
            const size_t p = exr.find(key);
            REQUIRE(p != std::string::npos);
            const int32_t window[4] = {0, 0, (1 << 20) - 1, 7};  // xmin, ymin, xmax, ymax
            std::memcpy(exr.data() + p + key.size() + 4, window, sizeof window);
            with_files({{"forged.exr", exr}}, [&] {
                run_case(t, "forged EXR data window, reconstruct", dir, {"reconstruct", at("forged.exr"), "-o", out},
                         {"forged.exr"}, 10.0);
                CHECK_THAT(read_bytes(dir / "run.log"), Catch::Contains("header declares"));
                run_case(t, "forged EXR data window, compare", dir, {"compare", at("forged.exr"), at("forged.exr")},
                         {"forged.exr"}, 10.0);
            });
        }
        // Time and memory quadratic in the depth (30,000 levels: 6 s and 900 MB;
        // 10^6 levels ran until killed): deeply nested JSON arrays.
        with_files({{"deep.json", "{\"x\": " + nest("[", "", "]", 1000000) + ", \"camera\": {}}"}},
                   [&] { run_case(t, "10^6 nested JSON arrays", dir, render(at("deep.json")), {"deep.json"}, 10.0); });
        // Read until memory ran out, then std::bad_alloc naming no file: mtllib /dev/zero.
        with_files({{"zero.obj", "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
                    {"zero.json", json_scene("[0, 1, 3]", "zero.obj")}},
                   [&] { run_case(t, "mtllib /dev/zero", dir, render(at("zero.json")), {"/dev/zero"}, 10.0); });
    }

    SECTION("special files in place of every input") {
        Tally& t = tally["special-files"];
        // Opened for reading, a FIFO without a writer blocks for ever: every
        // reader must refuse it by its type first (and open without blocking).
        const std::string fifo = at("fifo");
        REQUIRE(mkfifo(fifo.c_str(), 0600) == 0);
        fs::create_directory(dir / "a-directory");
        const std::vector<std::pair<std::string, std::string>> specials = {
            {fifo, "fifo"}, {"/dev/zero", "/dev/zero"}, {"/dev/null", "/dev/null"}, {at("a-directory"), "a-directory"}};
        with_files({{"box.obj", obj_text}, {"CornellBox-Original.mtl", mtl_text}}, [&] {
            for (const auto& [special, name] : specials) {
                // The scene file itself, JSON and XML by name.
                run_case(t, "scene " + name, dir, render(special), {name});
                // A mesh of a JSON scene (OBJ) and of a Mitsuba scene (OBJ, PLY).
                write_bytes(dir / "s.json", json_scene("[0, 1, 3.5]", special));
                run_case(t, "JSON mesh " + name, dir, render(at("s.json")), {name});
                for (const char* type : {"obj", "ply"}) {
                    write_bytes(dir / "s.xml", mitsuba_scene("0, 0, 5", std::string("<shape type=\"") + type +
                                                                            "\"><string name=\"filename\" value=\"" +
                                                                            special + "\"/></shape>\n"));
                    run_case(t, std::string("XML ") + type + " " + name, dir, render(at("s.xml")), {name});
                }
                // A material library, a texture and an environment map.
                write_bytes(dir / "m.obj", "mtllib " + special + "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
                write_bytes(dir / "s.json", json_scene("[0, 1, 3.5]", "m.obj"));
                run_case(t, "mtllib " + name, dir, render(at("s.json")), {name, "m.obj"});
                write_bytes(dir / "t.mtl", "newmtl t\nKd 1 1 1\nmap_Kd " + special + "\n");
                write_bytes(dir / "m.obj", "mtllib t.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                           "f 1/1 2/2 3/3\n");
                run_case(t, "texture " + name, dir, render(at("s.json")), {name});
                write_bytes(dir / "s.json", json_scene("[0, 1, 3.5]", "box.obj",
                                                       R"( "environment": {"type": "envmap", "file": ")" + special + "\"},"));
                run_case(t, "environment map " + name, dir, render(at("s.json")), {name});
                write_bytes(dir / "s.xml", mitsuba_scene("0, 0, 5", "<shape type=\"rectangle\"><bsdf type=\"diffuse\">"
                                                                    "<texture type=\"bitmap\" name=\"reflectance\"><string "
                                                                    "name=\"filename\" value=\"" + special +
                                                                    "\"/></texture></bsdf></shape>\n"));
                run_case(t, "XML bitmap " + name, dir, render(at("s.xml")), {name});
            }
            for (const char* f : {"s.json", "s.xml", "m.obj", "t.mtl"}) fs::remove(dir / f);
        });
        fs::remove(fifo);
    }

    SECTION("far-away coordinates") {
        Tally& t = tally["far-coordinates"];
        std::mt19937 rng(39001);
        with_files({{"box.obj", obj_text}, {"CornellBox-Original.mtl", mtl_text}}, [&] {
            for (int i = 0; i < 48; ++i) {
                const std::string x = far_number(rng), y = far_number(rng);
                if (i % 2 == 0) {
                    // A JSON camera far along its axis or off to the side, or a JSON mesh moved and scaled far away.
                    std::string scene = json_scene(i % 8 == 0 ? "[0, 1, " + x + "]" : "[" + x + ", " + y + ", 3.5]");
                    if (i % 4 == 2) {
                        scene = json_scene("[0, 1, 3.5]", "box.obj");
                        const std::string mesh = "[\"box.obj\"]";
                        scene.replace(scene.find(mesh), mesh.size(),
                                      R"([{"file": "box.obj", "transform": {"scale": )" + y + R"(, "translate": [0, 0, )" +
                                          x + "]}}]");
                    }
                    write_bytes(dir / "f.json", scene);
                    static const char* kIntegrators[] = {"pt", "gpt", "bdpt", "gbdpt"};
                    run_case(t, "JSON camera / mesh " + x + " " + y, dir,
                             render(at("f.json"), {"--integrator", kIntegrators[rng() % 4]}), {"f.json"});
                } else {
                    // A Mitsuba camera, or a mesh scaled and moved far away.
                    write_bytes(dir / "f.xml",
                                mitsuba_scene(i % 4 == 1 ? "0, 0, " + x : "0, 0, 5",
                                              "<shape type=\"obj\"><string name=\"filename\" value=\"box.obj\"/>"
                                              "<transform name=\"to_world\"><scale value=\"" + y + "\"/><translate z=\"" +
                                                  x + "\"/></transform></shape>\n"));
                    run_case(t, "XML camera / shape " + x + " " + y, dir,
                             rng() % 3 ? render(at("f.xml"))
                                       : std::vector<std::string>{"check-shift", at("f.xml"), "--paths", "10"},
                             {"f.xml", "box.obj"});
                }
            }
            fs::remove(dir / "f.json");
            fs::remove(dir / "f.xml");
        });
    }

    SECTION("random Mitsuba XML structure") {
        Tally& t = tally["xml-structure"];
        std::mt19937 rng(39002);
        static const int kDepths[] = {1, 2, 3, 50, 99, 100, 101, 150, 1000, 40000};
        static const std::vector<std::string> kValues = {"0.5", "1e-50", "1e-40", "1e10", "3e38", "1e38", "1e39",
                                                         "1e300", "-1", "0"};
        for (int i = 0; i < 120; ++i) {
            std::string extra, reflectance = "0.5", radiance = "1";
            for (int k = 0, n = 1 + int(rng() % 3); k < n; ++k) {
                const int d = kDepths[rng() % std::size(kDepths)];
                switch (rng() % 5) {
                    case 0:
                        extra += "<shape type=\"rectangle\">" + nest("<bsdf type=\"twosided\">", "<bsdf type=\"diffuse\"/>", "</bsdf>", d) + "</shape>\n";
                        break;
                    case 1: extra += "<shape type=\"rectangle\">" + nest("<b>", "", "</b>", d) + "</shape>\n"; break;
                    case 2: {
                        std::string p = "c";  // (built in steps: GCC 12 warns falsely of "c" + to_string)
                        p += std::to_string(k);
                        p += '_';
                        for (int j = 0; j < d; ++j)
                            extra += "<bsdf type=\"" + std::string(rng() % 2 ? "twosided" : "mask") + "\" id=\"" + p +
                                     std::to_string(j) + "\"><ref id=\"" + p + std::to_string(j + 1) + "\"/></bsdf>\n";
                        extra += "<bsdf type=\"diffuse\" id=\"" + p + std::to_string(d) + "\"/>\n<shape type=\"cube\"><ref id=\"" + p + "0\"/></shape>\n";
                        break;
                    }
                    case 3:
                        for (int j = 0, m = std::min(d, 300); j < m; ++j) extra += "<shape type=\"cube\"/>\n";
                        break;
                    default:
                        (rng() % 2 ? reflectance : radiance) = kValues[rng() % kValues.size()];
                }
            }
            write_bytes(dir / "x.xml", mitsuba_scene("0, 0, 5", extra, reflectance, radiance));
            run_case(t, "XML structure " + std::to_string(i), dir, render(at("x.xml")), {"x.xml"});
        }
        fs::remove(dir / "x.xml");
    }

    SECTION("random PLY structure") {
        Tally& t = tally["ply-structure"];
        std::mt19937 rng(39003);
        write_bytes(dir / "p.xml", mitsuba_scene("0, 0, 5", "<shape type=\"ply\"><string name=\"filename\" "
                                                            "value=\"p.ply\"/></shape>\n"));
        for (int i = 0; i < 120; ++i) {
            std::string ply = quad_ply(rng() % 2);
            for (int k = 0, n = 1 + int(rng() % 3 == 0); k < n; ++k) ply = mutate_ply(ply, rng);
            write_bytes(dir / "p.ply", ply);
            run_case(t, "PLY structure " + std::to_string(i), dir, render(at("p.xml")), {"p.ply"}, 10.0);
        }
        fs::remove(dir / "p.xml");
        fs::remove(dir / "p.ply");
    }

    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    for (const auto& [family, t] : tally) {
        WARN("fuzz " << family << ": " << t.cases << " cases, " << t.ran << " ran, " << t.refused
                     << " refused with one error line naming the file, " << t.bad << " failed, in " << total << " s");
        CHECK(t.bad == 0);
    }
}

#endif  // GDR_TOOL
