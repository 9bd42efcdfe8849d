// gdr submit and gdr status without Slurm: how samples are divided into
// parts, the quoting of the generated scripts (run here by bash with a stub
// gdr, with paths holding spaces and quotes), the #SBATCH lines as sbatch
// reads them, array ranges, the sbatch calls and their dependencies (a stub
// sbatch on PATH), the choice of what --resume resubmits; and the render and
// merge options the jobs rely on: --first-sample, --continue, merge --complete,
// and parts of one seed merging into one render of all their samples.
#include <catch2/catch.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gdr/cli/commands.h"
#include "gdr/cli/submit.h"
#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "cli_test_util.h"

using namespace gdr;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {

const std::string kSmall = GDR_SOURCE_DIR "/tests/scenes/cornell-small.json";

const test::OutDir& out_dir() {
    static const test::OutDir dir("submit");
    return dir;
}
std::string out(const std::string& name) { return out_dir()(name); }
using test::error_of;
using test::stdout_of;

void write_file(const std::string& path, const std::string& text, bool executable = false) {
    fs::create_directories(fs::path(path).parent_path());
    std::ofstream(path, std::ios::binary) << text;
    if (executable) chmod(path.c_str(), 0755);
}

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> v;
    std::string line;
    for (char c : text) {
        if (c == '\n') v.push_back(line), line.clear();
        else line += c;
    }
    if (!line.empty()) v.push_back(line);
    return v;
}

// The small Cornell box as a scene file in `dir` (which may hold spaces), its mesh by absolute path.
std::string scene_in(const std::string& dir) {
    const std::string path = dir + "/box scene.json";
    write_file(path, R"({"camera": {"position": [0, 1, 3.5], "target": [0, 1, 0], "up": [0, 1, 0], "fov": 45,
                         "width": 24, "height": 24},
                         "meshes": [")" GDR_SOURCE_DIR R"(/scenes/cornell-box/CornellBox-Original.obj"]})");
    return path;
}

// A stand-in for gdr that writes its arguments, one per line, to the file ARGS beside it.
std::string stub_gdr(const std::string& dir) {
    const std::string path = dir + "/gdr";
    write_file(path, "#!/bin/bash\nprintf '%s\\n' \"$@\" > \"$(dirname \"$0\")/ARGS\"\n", true);
    return path;
}

// Runs `script` with bash in `dir`, as Slurm would for array task `task` (-1: not an array task); returns the exit status.
int run_script(const std::string& script, const std::string& dir, int task) {
    const std::string env = task >= 0 ? "SLURM_ARRAY_TASK_ID=" + std::to_string(task) + " " : "";
    const std::string cmd = "cd " + cli::shell_quote(dir) + " && env -u SLURM_CPUS_ON_NODE -u SLURM_ARRAY_TASK_ID " +
                            env + "bash " + cli::shell_quote(script) + " 2>/dev/null";
    const int rc = std::system(cmd.c_str());
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

// One argument of an #SBATCH line as sbatch's reader takes it: quotes group, a backslash escapes.
std::vector<std::string> sbatch_words(const std::string& line) {
    std::vector<std::string> words;
    std::string w;
    bool in_word = false, escape = false;
    char quote = 0;
    for (char c : line) {
        if (escape) {
            w += c, escape = false, in_word = true;
        } else if (c == '\\') {
            escape = true;
        } else if (quote) {
            if (c == quote) quote = 0;
            else w += c;
        } else if (c == '"' || c == '\'') {
            quote = c, in_word = true;
        } else if (c == ' ') {
            if (in_word) words.push_back(w), w.clear(), in_word = false;
        } else {
            w += c, in_word = true;
        }
    }
    if (in_word) words.push_back(w);
    return words;
}

// The text of the script named `name` in the output of gdr submit --dry-run.
std::string script_in(const std::string& dry_run, const std::string& name) {
    const size_t at = dry_run.find(name + " <==\n");
    REQUIRE(at != std::string::npos);
    const size_t from = at + name.size() + 5, to = dry_run.find("\n==> ", from);
    return dry_run.substr(from, to == std::string::npos ? std::string::npos : to - from + 1);
}

// Sets PATH for the lifetime of the object.
struct PathScope {
    std::string old;
    explicit PathScope(const std::string& first) : old(std::getenv("PATH") ? std::getenv("PATH") : "") {
        setenv("PATH", (first + ":" + old).c_str(), 1);
    }
    ~PathScope() { setenv("PATH", old.c_str(), 1); }
};

// Largest |a - b| over all values of a layer, relative to the largest |b|.
double max_rel_diff(const Image& a, const Image& b) {
    double d = 0, m = 0;
    for (size_t i = 0; i < a.values().size(); ++i) {
        d = std::max(d, std::abs(double(a.values()[i]) - b.values()[i]));
        m = std::max(m, std::abs(double(b.values()[i])));
    }
    return m > 0 ? d / m : d;
}

}  // namespace

TEST_CASE("submit: samples divide into consecutive runs of one seed whose sizes differ by at most one", "[submit]") {
    const auto r = cli::divide_samples(7, 10, 4);
    REQUIRE(r.size() == 4);
    const uint64_t firsts[] = {0, 3, 6, 8}, counts[] = {3, 3, 2, 2};
    for (int i = 0; i < 4; ++i) {
        CHECK(r[size_t(i)].seed == 7);
        CHECK(r[size_t(i)].first == firsts[i]);
        CHECK(r[size_t(i)].count == counts[i]);
    }
    CHECK(cli::divide_samples(0, 256, 4)[3].first == 192);
    CHECK_THROWS_AS(cli::divide_samples(0, 3, 4), ParameterError);
    CHECK_THROWS_AS(cli::divide_samples(0, 3, 0), ParameterError);
}

TEST_CASE("submit: array ranges, shell and #SBATCH quoting", "[submit]") {
    CHECK(cli::array_ranges({0, 1, 2, 3}) == "0-3");
    CHECK(cli::array_ranges({3, 1}) == "1,3");
    CHECK(cli::array_ranges({8, 0, 1, 2, 5, 7}) == "0-2,5,7-8");
    CHECK(cli::array_ranges({4}) == "4");
    CHECK(cli::shell_quote("/a/b-c_d.exr") == "/a/b-c_d.exr");
    CHECK(cli::shell_quote("a b") == "'a b'");
    CHECK(cli::shell_quote("it's") == "'it'\\''s'");
    CHECK(cli::shell_quote("") == "''");
    // bash gives back every string as it was.
    for (const std::string s : {"a b", "it's", "$HOME", "`id`", "a\"b", "back\\slash", "*", "~", "two  spaces", "!x", ""}) {
        const std::string file = out("echoed");
        const std::string cmd = "printf '%s' " + cli::shell_quote(s) + " > " + cli::shell_quote(file);
        REQUIRE(std::system(cmd.c_str()) == 0);
        CHECK(test::file_bytes(file) == s);
    }
    CHECK(cli::sbatch_quote("/tmp/x.parts") == "/tmp/x.parts");
    for (const std::string s : {"/tmp/out dir/x.parts", "a\"b", "back\\slash", "#hash", "it's"}) {
        const auto words = sbatch_words("--chdir=" + cli::sbatch_quote(s));
        REQUIRE(words.size() == 1);
        CHECK(words[0] == "--chdir=" + s);
    }
}

TEST_CASE("submit: --dry-run prints scripts that render and merge the right parts, quoted for paths with spaces",
          "[submit]") {
    const std::string dir = out("my scenes");
    const std::string scene = scene_in(dir);
    const std::string bin = out("bin dir");
    fs::create_directories(bin);
    const std::string gdr = stub_gdr(bin);
    fs::create_directories(out("out dir"));
    const std::string target = out("out dir/it's a box.exr");
    const std::string text = stdout_of([&] {
        REQUIRE(cli::run({"submit", scene, "--parts", "4", "--spp", "16", "--seed", "3", "--set", "max_depth=5",
                          "--sbatch", "--time=01:00:00", "--sbatch", "--comment=a \"quoted\" word", "--gdr", gdr,
                          "--dry-run", "-o", target}) == 0);
    });
    const std::string parts_dir = out("out dir/it's a box.parts");
    // Nothing is written or submitted.
    CHECK_FALSE(fs::exists(parts_dir));
    CHECK_FALSE(fs::exists(target));
    CHECK_THAT(text, Contains("sbatch --parsable " + cli::shell_quote(parts_dir + "/render.sbatch")));
    CHECK_THAT(text, Contains("--dependency=afterok:RENDER_JOB_ID " + cli::shell_quote(parts_dir + "/merge.sbatch")));

    const std::string render = script_in(text, parts_dir + "/render.sbatch");
    const std::string merge = script_in(text, parts_dir + "/merge.sbatch");
    // The directives as sbatch reads them, before the first command.
    std::vector<std::string> directives;
    for (const std::string& l : lines(render)) {
        if (l.rfind("#SBATCH ", 0) == 0) {
            const auto w = sbatch_words(l.substr(8));
            REQUIRE(w.size() == 1);
            directives.push_back(w[0]);
        } else if (!l.empty() && l[0] != '#') {
            break;
        }
    }
    for (const std::string& d : std::vector<std::string>{"--array=0-3", "--chdir=" + parts_dir, "--output=logs/part-%a.log", "--open-mode=append",
                                "--time=01:00:00", "--comment=a \"quoted\" word", "--job-name=gdr-it_s_a_box"})
        CHECK(std::count(directives.begin(), directives.end(), d) == 1);

    // Task 2 renders samples 32..47 of seed 3 into part-2.exr, every path one argument.
    write_file(out("render.sbatch"), render);
    write_file(out("merge.sbatch"), merge);
    const std::string work = out("task dir");
    fs::create_directories(work);
    REQUIRE(run_script(out("render.sbatch"), work, 2) == 0);
    const std::vector<std::string> want = {"render",       scene, "--integrator", "pt",     "--set",      "max_depth=5",
                                           "--seed",       "3",   "--first-sample", "32",  "--spp",      "16",
                                           "--threads",    "0",   "--continue",   "-o",     "part-2.exr"};
    CHECK(lines(test::file_bytes(bin + "/ARGS")) == want);
    // A task outside the render fails, and so does the script run outside Slurm.
    CHECK(run_script(out("render.sbatch"), work, 4) == 2);
    CHECK(run_script(out("render.sbatch"), work, -1) != 0);
    // The merge pools part-0 .. part-3 (in the job's folder) into the output.
    REQUIRE(run_script(out("merge.sbatch"), work, -1) == 0);
    const std::vector<std::string> merge_args = {"merge", "--complete", "part-0.exr", "part-1.exr", "part-2.exr",
                                                 "part-3.exr", "-o", target};
    CHECK(lines(test::file_bytes(bin + "/ARGS")) == merge_args);
    CHECK_THAT(merge, Contains("#SBATCH --kill-on-invalid-dep=yes"));
    CHECK_THAT(merge, Contains("#SBATCH --chdir=\"" + parts_dir + "\""));
}

TEST_CASE("submit: bad submissions are refused before anything is written", "[submit]") {
    const std::string gdr = stub_gdr(out("stub"));
    const std::string o = out("refused.exr");
    CHECK_THAT(error_of({"submit", kSmall, "--spp", "4", "--gdr", gdr, "-o", o}), Contains("--parts"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "1", "--gdr", gdr, "-o", o}), Contains("--parts"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--time", "5", "--gdr", gdr, "-o", o}), Contains("--spp"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--frames", "1:10", "--gdr", gdr, "-o", o}),
               Contains("no animation"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--set", "max_dpth=3", "--gdr", gdr, "-o", o}),
               Contains("max_dpth"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--sbatch", "-p debug", "--gdr", gdr, "-o", o}),
               Contains("long form"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--gdr", out("no-such-gdr"), "-o", o}), Contains("no-such-gdr"));
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--gdr", gdr, "-o", out("x.png")}), Contains(".exr"));
    CHECK_THAT(error_of({"submit", "--resume", o, "--parts", "2"}), Contains("only --dry-run"));
    CHECK_THAT(error_of({"submit", "--resume", o}), Contains("not submitted"));
    CHECK_THAT(error_of({"status", o}), Contains("not submitted"));
    // An existing output is never replaced.
    write_file(out("exists.exr"), "x");
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "2", "--gdr", gdr, "--dry-run", "-o", out("exists.exr")}),
               Contains("exists"));
    CHECK_FALSE(fs::exists(out("refused.parts")));
}

TEST_CASE("submit: sbatch is called for the array and for the merge after it, --resume resubmits what is not complete",
          "[submit]") {
    // Stand-ins for Slurm's commands: sbatch logs its arguments and prints ids 1, 2, ...; squeue prints QUEUE.
    const std::string fake = out("fake slurm");
    write_file(fake + "/sbatch",
               "#!/bin/bash\nd=$(dirname \"$0\")\nn=$(( $(cat \"$d/N\" 2>/dev/null || echo 0) + 1 ))\necho $n > \"$d/N\"\n"
               "printf '%s\\n' \"$@\" --- >> \"$d/SBATCH\"\necho \"$n;cluster\"\n",
               true);
    write_file(fake + "/squeue", "#!/bin/bash\ncat \"$(dirname \"$0\")/QUEUE\" 2>/dev/null\n", true);
    write_file(fake + "/scancel", "#!/bin/bash\nprintf '%s\\n' \"$@\" >> \"$(dirname \"$0\")/SCANCEL\"\n", true);
    write_file(fake + "/sacct", "#!/bin/bash\necho 'Slurm accounting storage is disabled' >&2\nexit 1\n", true);
    const PathScope path(fake);
    const std::string gdr = stub_gdr(out("stub"));
    fs::create_directories(out("run"));
    const std::string target = out("run/box.exr"), dir = out("run/box.parts");
    const auto sbatch_calls = [&] {
        std::vector<std::vector<std::string>> calls(1);
        for (const std::string& l : lines(test::file_bytes(fake + "/SBATCH"))) {
            if (l == "---") calls.emplace_back();
            else calls.back().push_back(l);
        }
        calls.pop_back();
        fs::remove(fake + "/SBATCH");
        return calls;
    };

    const std::string said = stdout_of([&] {
        REQUIRE(cli::run({"submit", kSmall, "--parts", "4", "--spp", "2", "--seed", "5", "--gdr", gdr, "-o", target}) == 0);
    });
    CHECK_THAT(said, Contains("render job 1: array tasks 0-3") && Contains("merge job 2"));
    auto calls = sbatch_calls();
    REQUIRE(calls.size() == 2);
    CHECK(calls[0] == std::vector<std::string>{"--parsable", dir + "/render.sbatch"});
    CHECK(calls[1] == std::vector<std::string>{"--parsable", "--dependency=afterok:1", dir + "/merge.sbatch"});
    CHECK(test::file_bytes(dir + "/jobs.txt") == "render 1 0-3\nmerge 2\n");
    for (const char* f : {"plan.txt", "render.sbatch", "merge.sbatch"}) CHECK(fs::exists(dir + "/" + f));
    CHECK(fs::is_directory(dir + "/logs"));
    CHECK((fs::status(dir + "/render.sbatch").permissions() & fs::perms::owner_exec) != fs::perms::none);
    // The plan reads back as written.
    const cli::SubmitPlan plan = cli::read_plan(target);
    CHECK(plan.spp == 8);
    CHECK(plan.seed == 5);
    REQUIRE(plan.parts.size() == 4);
    CHECK(plan.parts[3].samples.first == 6);
    CHECK(plan.parts[3].file == dir + "/part-3.exr");
    CHECK(cli::parse_plan(cli::format_plan(plan), dir + "/plan.txt").parts[2].samples.first == 4);
    // Submitting the same output again is refused.
    CHECK_THAT(error_of({"submit", kSmall, "--parts", "4", "--spp", "2", "--gdr", gdr, "-o", target}),
               Contains("submitted already"));

    // Parts 0 and 1 complete, part 2 partial, part 3 missing; task 3 still running.
    const auto part = [&](int i, const char* spp) {
        REQUIRE(cli::run({"render", kSmall, "--integrator", "pt", "--seed", "5", "--first-sample", std::to_string(2 * i),
                          "--spp", spp, "--continue", "-o", dir + "/part-" + std::to_string(i) + ".exr"}) == 0);
    };
    part(0, "2"), part(1, "2"), part(2, "1");
    write_file(fake + "/QUEUE", "1_3|RUNNING|None\n2|PENDING|Dependency\n77|RUNNING|None\n");
    const std::string st = stdout_of([&] { REQUIRE(cli::run({"status", target}) == 0); });
    CHECK_THAT(st, Contains("parts: 2 complete, 1 partial, 1 missing; jobs: 1 running, 0 pending"));
    CHECK_THAT(st, Contains("partial (1 of 2 spp)") && Contains("1_3 RUNNING") && Contains("2 PENDING (Dependency)"));
    CHECK_THAT(st, Contains("merged: no"));
    CHECK_THAT(error_of({"submit", "--resume", target}), Contains("still queued") && Contains("1_3 (RUNNING)"));
    CHECK(sbatch_calls().empty());

    // Once the tasks have ended, a merge that can never run is cancelled and parts 2 and 3 go again.
    write_file(fake + "/QUEUE", "2|PENDING|DependencyNeverSatisfied\n");
    const std::string dry = stdout_of([&] { REQUIRE(cli::run({"submit", "--resume", target, "--dry-run"}) == 0); });
    CHECK_THAT(dry, Contains("scancel 2") && Contains("--array=2-3") && Contains("parts to render again: 2-3"));
    CHECK(sbatch_calls().empty());
    const std::string again = stdout_of([&] { REQUIRE(cli::run({"submit", "--resume", target}) == 0); });
    CHECK_THAT(again, Contains("render job 3: array tasks 2-3") && Contains("merge job 4"));
    CHECK(test::file_bytes(fake + "/SCANCEL") == "2\n");
    calls = sbatch_calls();
    REQUIRE(calls.size() == 2);
    CHECK(calls[0] == std::vector<std::string>{"--parsable", "--array=2-3", dir + "/render.sbatch"});
    CHECK(calls[1] == std::vector<std::string>{"--parsable", "--dependency=afterok:3", dir + "/merge.sbatch"});
    CHECK(test::file_bytes(dir + "/jobs.txt") == "render 1 0-3\nmerge 2\nrender 3 2-3\nmerge 4\n");

    // The parts finish (as the re-run tasks would: part 2 continued, part 3 anew); only the merge is left.
    write_file(fake + "/QUEUE", "");
    part(2, "2"), part(3, "2");
    const std::string merge_only = stdout_of([&] { REQUIRE(cli::run({"submit", "--resume", target}) == 0); });
    CHECK_THAT(merge_only, Contains("merge job 5"));
    calls = sbatch_calls();
    REQUIRE(calls.size() == 1);
    CHECK(calls[0] == std::vector<std::string>{"--parsable", dir + "/merge.sbatch"});
    // The merge job's command, run here, finishes it: status says done, --resume has nothing to do.
    REQUIRE(cli::run({"merge", "--complete", dir + "/part-0.exr", dir + "/part-1.exr", dir + "/part-2.exr",
                      dir + "/part-3.exr", "-o", target}) == 0);
    const std::string done = stdout_of([&] { REQUIRE(cli::run({"status", target}) == 0); });
    CHECK_THAT(done, Contains("parts: 4 complete") && Contains("merged: yes") && Contains("done:"));
    CHECK_THAT(stdout_of([&] { cli::run({"submit", "--resume", target}); }), Contains("merged already"));
    CHECK(sbatch_calls().empty());

    // A part file that holds other samples stops --resume, naming it.
    fs::remove(target);
    REQUIRE(cli::run({"render", kSmall, "--seed", "5", "--spp", "2", "-o", out("other.exr")}) == 0);
    fs::copy_file(out("other.exr"), dir + "/part-3.exr", fs::copy_options::overwrite_existing);
    CHECK_THAT(error_of({"submit", "--resume", target}), Contains("part-3.exr") && Contains("samples 0-1"));
}

TEST_CASE("submit: the parts' state comes from the part files and the queue", "[submit]") {
    CHECK(cli::parse_squeue("12_0|RUNNING|None\n12_3|PENDING|Resources\n13|PENDING|Dependency\n").size() == 3);
    const auto q = cli::parse_squeue("12_3|PENDING|Resources\n");
    CHECK(q[0].id == "12_3");
    CHECK(q[0].state == "PENDING");
    CHECK(q[0].reason == "Resources");
    const auto a = cli::parse_sacct("12_0|COMPLETED|0:0\n12_1|CANCELLED by 0|0:15\n12_[2-3]|PENDING|0:0\n");
    REQUIRE(a.size() == 2);
    CHECK(a[1].state == "CANCELLED");
    CHECK(a[1].reason == "exit code 0:15");
    CHECK(a[0].reason.empty());
    CHECK(cli::job_active("RUNNING"));
    CHECK(cli::job_active("PENDING"));
    CHECK_FALSE(cli::job_active("COMPLETED"));
    CHECK_FALSE(cli::job_active("TIMEOUT"));
    const auto r = cli::parse_job_records("render 12 0-2,5\nmerge 13\ngarbage\n");
    REQUIRE(r.size() == 2);
    CHECK(r[0].parts == std::vector<int>{0, 1, 2, 5});
    CHECK(cli::format_job_record(r[0]) == "render 12 0-2,5\n");
    CHECK(r[1].kind == "merge");

    cli::SubmitPlan plan;
    plan.out = out("sel.exr");
    for (int i = 0; i < 3; ++i) plan.parts.push_back({i, {0, uint64_t(2 * i), 2}, out("sel-" + std::to_string(i))});
    using cli::PartFile;
    const std::vector<cli::PartStatus> status = {{PartFile::complete, 2, ""}, {PartFile::partial, 1, ""},
                                                 {PartFile::missing, 0, ""}};
    const std::vector<cli::JobRecord> records = {{"render", "12", {0, 1, 2}}, {"merge", "13", {}}};
    auto choice = cli::choose_resubmission(plan, status, records, {});
    CHECK(choice.parts == std::vector<int>{1, 2});
    CHECK(choice.stale_merges.empty());
    // Another user's job and an ended task do not block; a pending task does.
    choice = cli::choose_resubmission(plan, status, records, {{"99_1", "RUNNING", ""}, {"12_0", "COMPLETED", ""}});
    CHECK(choice.parts == std::vector<int>{1, 2});
    CHECK_THROWS_WITH(cli::choose_resubmission(plan, status, records, {{"12_2", "PENDING", "Resources"}}),
                      Contains("12_2 (PENDING)"));
    CHECK_THROWS_WITH(cli::choose_resubmission(plan, status, records, {{"13", "PENDING", "Dependency"}}),
                      Contains("13 (PENDING)"));
    choice = cli::choose_resubmission(plan, status, records, {{"13", "PENDING", "DependencyNeverSatisfied"}});
    CHECK(choice.stale_merges == std::vector<std::string>{"13"});
    const std::vector<cli::PartStatus> bad = {{PartFile::complete, 2, ""}, {PartFile::unusable, 0, "holds other samples"},
                                              {PartFile::missing, 0, ""}};
    CHECK_THROWS_WITH(cli::choose_resubmission(plan, bad, records, {}), Contains("sel-1") && Contains("other samples"));
}

TEST_CASE("render --continue: a complete part is left alone, a partial one is finished in place, another is refused",
          "[submit][cli]") {
    const std::string part = out("cont.exr");
    const std::vector<std::string> args = {"render", kSmall, "--seed", "4", "--first-sample", "6", "--spp", "3",
                                           "--continue", "-o", part};
    REQUIRE(cli::run(args) == 0);
    const FrameBuffer first = read_exr(part);
    CHECK(first.metadata().at("sample_ranges") == "4:6:3");
    CHECK(first.metadata().at("target_spp") == "9");  // the number one past its last sample
    const std::string bytes = test::file_bytes(part);
    REQUIRE(cli::run(args) == 0);  // a re-run: nothing to do, nothing written
    CHECK(test::file_bytes(part) == bytes);
    // A part asked for more samples continues from where it is: equal to one render of them.
    std::vector<std::string> more = args;
    more[7] = "7";
    REQUIRE(cli::run(more) == 0);
    REQUIRE(cli::run({"render", kSmall, "--seed", "4", "--first-sample", "6", "--spp", "7", "-o", out("whole.exr")}) == 0);
    const FrameBuffer cont = read_exr(part), whole = read_exr(out("whole.exr"));
    CHECK(cont.metadata().at("sample_ranges") == "4:6:7");
    CHECK(cont.metadata().at("target_spp") == "13");
    for (const char* layer : {"color", "albedo", "normal", "depth", "variance"})
        CHECK(max_rel_diff(cont.get(layer), whole.get(layer)) < 1e-6);
    // A file of another seed or first sample is not this part.
    CHECK_THAT(error_of({"render", kSmall, "--seed", "5", "--first-sample", "6", "--spp", "7", "--continue", "-o", part}),
               Contains("seed 4"));
    CHECK_THAT(error_of({"render", kSmall, "--seed", "4", "--spp", "7", "--continue", "-o", part}),
               Contains("starting at sample 0"));
    CHECK_THAT(error_of({"render", kSmall, "--continue", "--time", "1", "-o", out("t.exr")}), Contains("--spp"));
    CHECK_THAT(error_of({"render", kSmall, "--first-sample", "2", "--resume", part, "-o", out("r.exr")}),
               Contains("--first-sample"));
    // A resumed part reaches its own target: a part of samples 6..8 stopped after 1 sample resumes to 9.
    REQUIRE(cli::run({"render", kSmall, "--seed", "4", "--first-sample", "6", "--spp", "1", "-o", out("short.exr")}) == 0);
    FrameBuffer stopped = read_exr(out("short.exr"));
    stopped.metadata()["target_spp"] = "9";
    stopped.metadata()["interrupted"] = "true";
    write_exr(out("stopped.exr"), stopped);
    CHECK_THAT(error_of({"merge", "--complete", out("stopped.exr"), out("whole.exr"), "-o", out("m.exr")}),
               Contains("stopped.exr: 1 of its 3 spp"));
    REQUIRE(cli::run({"render", kSmall, "--resume", out("stopped.exr"), "-o", out("resumed.exr")}) == 0);
    const FrameBuffer resumed = read_exr(out("resumed.exr"));
    CHECK(resumed.metadata().at("sample_ranges") == "4:6:3");
    CHECK(resumed.metadata().at("target_spp") == "9");
    CHECK(max_rel_diff(resumed.get("color"), first.get("color")) < 1e-6);
}

TEST_CASE("submit: parts of one seed with consecutive samples merge into one render of all of them, to float rounding",
          "[submit][cli]") {
    // 4 parts of 4 spp against one render of 16 spp, for pt and gpt. The
    // mean layers agree to a few float roundings (docs/cluster.md states what
    // was measured on the 512x512 box); gpt's variance layers are sums of
    // per-sample variances of several estimators, which a merge pools as
    // one, so they agree only in expectation and are not compared.
    for (const char* integrator : {"pt", "gpt"}) {
        const std::string tag = integrator;
        std::vector<std::string> merge = {"merge", "--complete"};
        for (int i = 0; i < 4; ++i) {
            const std::string p = out(tag + "-part" + std::to_string(i) + ".exr");
            REQUIRE(cli::run({"render", kSmall, "--integrator", integrator, "--seed", "2", "--first-sample",
                              std::to_string(4 * i), "--spp", "4", "-o", p}) == 0);
            merge.push_back(p);
        }
        merge.insert(merge.end(), {"-o", out(tag + "-merged.exr")});
        REQUIRE(cli::run(merge) == 0);
        REQUIRE(cli::run({"render", kSmall, "--integrator", integrator, "--seed", "2", "--spp", "16", "-o",
                          out(tag + "-whole.exr")}) == 0);
        const FrameBuffer m = read_exr(out(tag + "-merged.exr")), w = read_exr(out(tag + "-whole.exr"));
        CHECK(m.metadata().at("sample_ranges") == "2:0:16");
        CHECK(m.metadata().at("seed") == "2");
        for (const std::string& layer : w.names()) {
            if (layer.find("variance") != std::string::npos && tag == "gpt") continue;
            INFO(tag << " layer " << layer);
            // The weighted reconstruction reads those variance layers as
            // weights, so it inherits their pooling: 9e-5 was measured here.
            const double tol = layer == "variance"                  ? 1e-5
                               : layer == "reconstruction_l1"       ? 1e-4
                               : layer == "reconstruction_weighted" ? 1e-3
                                                                    : 2e-6;
            CHECK(max_rel_diff(m.get(layer), w.get(layer)) < tol);
        }
        CHECK(m.get("spp").values() == w.get("spp").values());
    }
}
