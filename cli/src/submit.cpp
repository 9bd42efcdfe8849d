// gdr submit and gdr status: a render as a Slurm array job whose task i
// renders part i (a run of consecutive samples of one seed) into its own
// file, and a dependent job that merges the parts. The parts folder beside
// the output holds the scripts, the part files, the logs, the plan (which
// --resume and status read) and the ids of the jobs submitted.
#include "gdr/cli/submit.h"
#include "gdr/cli/plugins.h"

#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <fmt/core.h>

#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/scene_file.h"
#include "process.h"
#include "render_options.h"
#include "stop.h"

namespace gdr::cli {

namespace fs = std::filesystem;

namespace {

constexpr int kPlanFormat = 1;

// Most parts: Slurm's own array limit (MaxArraySize) is far lower by default.
constexpr long long kMaxParts = 1 << 20;

// Parts per line of the merge command.
constexpr int kPartsPerLine = 8;

// Characters that mean nothing to bash or to sbatch's #SBATCH reader.
bool plain_char(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           std::strchr("_@%+=:,./-", c) != nullptr;
}

bool plain(const std::string& s) { return !s.empty() && std::all_of(s.begin(), s.end(), plain_char); }

// Refuses text that a script line cannot hold.
void check_one_line(const std::string& what, const std::string& s) {
    if (s.find('\n') != std::string::npos || s.find('\r') != std::string::npos)
        throw ParameterError(what + " holds a line break, which a job script cannot carry: '" + s + "'");
}

std::string absolute(const std::string& p) { return fs::absolute(fs::path(p)).lexically_normal().string(); }

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot be read");
    return {std::istreambuf_iterator<char>(in), {}};
}

void write_text(const std::string& path, const std::string& text, bool executable = false) {
    {
        std::ofstream os(path, std::ios::binary | std::ios::trunc);
        os << text;
        os.close();
        if (!os) throw RuntimeFailure("cannot write '" + path + "'");
    }
    if (executable) chmod(path.c_str(), 0755);
}

void append_text(const std::string& path, const std::string& text) {
    std::ofstream os(path, std::ios::binary | std::ios::app);
    os << text;
    os.close();
    if (!os) throw RuntimeFailure("cannot write '" + path + "'");
}

std::string trim(std::string s) {
    while (!s.empty() && std::isspace((unsigned char)s.back())) s.pop_back();
    size_t i = 0;
    while (i < s.size() && std::isspace((unsigned char)s[i])) ++i;
    return s.substr(i);
}

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        out.push_back(line);
    }
    return out;
}

// The first line of a program's error output, for a message.
std::string first_line(const std::string& text) {
    const std::string t = trim(text);
    return t.substr(0, t.find('\n'));
}

uint64_t parse_count(const std::string& v, const std::string& what, const std::string& file) {
    char* end = nullptr;
    errno = 0;
    const unsigned long long x = std::strtoull(v.c_str(), &end, 10);
    if (v.empty() || *end || v[0] == '-' || errno == ERANGE)
        throw InputError(file + ": " + what + " is not a number: '" + v + "'");
    return x;
}

// "first-last" of a sample range.
std::string samples_text(const SampleRange& r) { return fmt::format("{}-{}", r.first, r.first + r.count - 1); }

// The Slurm job name of a render to `out`: "gdr-" and its name, in characters every shell and log shows plainly.
std::string job_name_of(const std::string& out) {
    std::string stem = fs::path(out).stem().string(), name = "gdr-";
    for (char c : stem) name += (std::isalnum((unsigned char)c) || c == '-' || c == '_' || c == '.') ? c : '_';
    return name;
}

// One #SBATCH line for the option "--name=value" or "--flag".
std::string sbatch_line(const std::string& option) {
    const size_t eq = option.find('=');
    if (eq == std::string::npos) return "#SBATCH " + sbatch_quote(option) + "\n";
    return "#SBATCH " + option.substr(0, eq + 1) + sbatch_quote(option.substr(eq + 1)) + "\n";
}

// Words joined into one bash command, continued on new lines when long.
std::string command_lines(const std::vector<std::string>& words) {
    std::string out, line;
    for (const std::string& w : words) {
        if (!line.empty() && line.size() + 1 + w.size() > 100) {
            out += line + " \\\n";
            line = "    ";
        } else if (!line.empty()) {
            line += " ";
        }
        line += w;
    }
    return out + line + "\n";
}

std::string user_name() {
    if (const passwd* pw = getpwuid(getuid())) return pw->pw_name;
    const char* u = std::getenv("USER");
    return u ? u : "";
}

// The job id printed by `sbatch --parsable` ("123" or "123;cluster").
std::string parsable_job_id(const std::string& out) {
    const std::string id = trim(first_line(out).substr(0, first_line(out).find(';')));
    if (id.empty() || !std::all_of(id.begin(), id.end(), [](char c) { return std::isdigit((unsigned char)c); }))
        throw RuntimeFailure("sbatch printed no job id: '" + trim(out) + "'");
    return id;
}

// Runs sbatch with `args` and returns the job id it printed.
std::string sbatch(const std::vector<std::string>& args) {
    std::vector<std::string> argv = {"sbatch", "--parsable"};
    argv.insert(argv.end(), args.begin(), args.end());
    const ProgramResult r = run_program(argv);
    if (!r.started) throw RuntimeFailure("cannot run sbatch: " + r.err);
    if (r.status != 0) throw RuntimeFailure("sbatch failed (exit status " + std::to_string(r.status) + "): " + trim(r.err));
    return parsable_job_id(r.out);
}

// A command as a user would type it, for messages and --dry-run.
std::string shown(const std::vector<std::string>& argv) {
    std::string s;
    for (const std::string& a : argv) {
        if (!s.empty()) s += ' ';
        s += shell_quote(a);
    }
    return s;
}

// The job id of an array task or job ("123" of "123_4").
std::string base_id(const std::string& id) { return id.substr(0, id.find('_')); }

// What the scheduler says of a plan's jobs.
struct QueueView {
    bool squeue = false;             // squeue answered
    std::string squeue_note;         // why not
    std::vector<JobState> queued;    // the plan's jobs squeue lists
    bool sacct = false;              // sacct answered
    std::string sacct_note;          // why not
    std::vector<JobState> accounted; // the plan's jobs sacct knows
};

QueueView look_up_jobs(const std::vector<JobRecord>& records, bool with_sacct) {
    QueueView v;
    std::set<std::string> ids;
    for (const JobRecord& r : records) ids.insert(r.id);
    if (find_program("squeue").empty()) {
        v.squeue_note = "squeue not found";
    } else {
        // The user's jobs, filtered here: `squeue -j ID` of one job that has
        // left the controller's memory is an error rather than an empty list.
        const ProgramResult r = run_program({"squeue", "-h", "-r", "-u", user_name(), "-o", "%i|%T|%r"});
        if (r.status != 0) {
            v.squeue_note = "squeue failed: " + first_line(r.err);
        } else {
            v.squeue = true;
            for (const JobState& j : parse_squeue(r.out))
                if (ids.count(base_id(j.id))) v.queued.push_back(j);
        }
    }
    if (!with_sacct || ids.empty()) return v;
    if (find_program("sacct").empty()) {
        v.sacct_note = "sacct not found";
        return v;
    }
    std::string list;
    for (const std::string& id : ids) {
        if (!list.empty()) list += ',';
        list += id;
    }
    const ProgramResult r = run_program({"sacct", "-n", "-X", "-P", "-o", "JobID,State,ExitCode", "-j", list});
    if (r.status != 0) {
        v.sacct_note = "sacct: " + first_line(r.err.empty() ? r.out : r.err);
    } else {
        v.sacct = true;
        v.accounted = parse_sacct(r.out);
    }
    return v;
}

// The state of job or task `id`: squeue's while it is queued, else sacct's; nullptr if neither knows it.
const JobState* state_of(const QueueView& v, const std::string& id) {
    for (const JobState& j : v.queued)
        if (j.id == id) return &j;
    for (const JobState& j : v.accounted)
        if (j.id == id) return &j;
    return nullptr;
}

// The state squeue gives job or task `id`, nullptr if it is not queued.
const JobState* in_queue(const QueueView& v, const std::string& id) {
    for (const JobState& j : v.queued)
        if (j.id == id && job_active(j.state)) return &j;
    return nullptr;
}

// The latest render array job that rendered part `index`, "" if none.
std::string task_of(const std::vector<JobRecord>& records, int index) {
    for (auto it = records.rbegin(); it != records.rend(); ++it)
        if (it->kind == "render" && std::count(it->parts.begin(), it->parts.end(), index))
            return it->id + "_" + std::to_string(index);
    return "";
}

// The latest merge job, "" if none.
std::string merge_job_of(const std::vector<JobRecord>& records) {
    for (auto it = records.rbegin(); it != records.rend(); ++it)
        if (it->kind == "merge") return it->id;
    return "";
}

// Whether `out` is the merge of every sample of `plan`; "" if so, else what it is.
std::string merged_problem(const SubmitPlan& plan) {
    std::error_code ec;
    if (!fs::exists(plan.out, ec)) return "not merged yet";
    try {
        const ExrHeader h = read_exr_header(plan.out);
        const auto it = h.metadata.find("sample_ranges");
        const std::string want = format_sample_ranges({{plan.seed, 0, plan.spp}});
        if (it == h.metadata.end() || it->second != want)
            return plan.out + " holds samples " + (it == h.metadata.end() ? "unknown" : it->second) +
                   ", not the plan's " + want;
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

std::vector<JobRecord> read_job_records(const SubmitPlan& plan) {
    std::error_code ec;
    if (!fs::exists(plan.jobs_path(), ec)) return {};
    return parse_job_records(read_text(plan.jobs_path()));
}

std::string job_text(const JobState* j) {
    if (!j) return "";
    return j->reason.empty() || j->reason == "None" ? j->state : j->state + " (" + j->reason + ")";
}

std::string usage_error(const std::string& what) { return "submit: " + what + "\n" + usage("submit"); }

// Submits the render array of `parts` (all of them: no --array override) and
// the merge after it; records both and prints their ids.
void queue_jobs(const SubmitPlan& plan, const std::vector<int>& parts, bool all_parts) {
    std::string render_id;
    if (!parts.empty()) {
        std::vector<std::string> args;
        if (!all_parts) args.push_back("--array=" + array_ranges(parts));
        args.push_back(plan.render_script_path());
        render_id = sbatch(args);
        append_text(plan.jobs_path(), format_job_record({"render", render_id, parts}));
        fmt::print("render job {}: array tasks {} (logs in {}/logs)\n", render_id, array_ranges(parts), plan.dir);
    }
    std::vector<std::string> args;
    if (!render_id.empty()) args.push_back("--dependency=afterok:" + render_id);
    args.push_back(plan.merge_script_path());
    std::string merge_id;
    try {
        merge_id = sbatch(args);
    } catch (const Error& e) {
        throw RuntimeFailure(std::string(e.what()) + "\nthe parts are queued (job " + render_id +
                             "), the merge is not: once they have finished, gdr submit --resume " +
                             shell_quote(plan.out) + " submits it");
    }
    append_text(plan.jobs_path(), format_job_record({"merge", merge_id, {}}));
    fmt::print("merge job {}: {}writes {}\n", merge_id, render_id.empty() ? "" : "runs once every part has succeeded, ",
               plan.out);
    fmt::print("gdr status {} shows the progress\n", shell_quote(plan.out));
}

// The commands queue_jobs() would run, for --dry-run.
std::string queue_commands(const SubmitPlan& plan, const std::vector<int>& parts, bool all_parts) {
    std::string s;
    if (!parts.empty()) {
        std::vector<std::string> argv = {"sbatch", "--parsable"};
        if (!all_parts) argv.push_back("--array=" + array_ranges(parts));
        argv.push_back(plan.render_script_path());
        s += "#   " + shown(argv) + "\n";
    }
    std::vector<std::string> argv = {"sbatch", "--parsable"};
    if (!parts.empty()) argv.push_back("--dependency=afterok:RENDER_JOB_ID");
    argv.push_back(plan.merge_script_path());
    return s + "#   " + shown(argv) + "\n";
}

int resume_submission(const std::string& out, bool dry_run) {
    const SubmitPlan plan = read_plan(out);
    const std::string problem = merged_problem(plan);
    if (problem.empty()) {
        fmt::print("{} is merged already ({} spp of seed {}); nothing to submit\n", plan.out, plan.spp, plan.seed);
        return 0;
    }
    std::error_code ec;
    if (fs::exists(plan.out, ec))
        throw InputError("refusing to resubmit: " + problem + "; gdr submit never replaces it (remove it to merge again)");
    const std::vector<JobRecord> records = read_job_records(plan);
    QueueView queue;
    if (!records.empty()) {
        queue = look_up_jobs(records, false);
        if (!queue.squeue)
            throw RuntimeFailure(queue.squeue_note + ": cannot tell whether jobs of " + plan.out +
                                 " are still queued, so nothing is resubmitted");
    }
    std::vector<PartStatus> status;
    for (const Part& p : plan.parts) status.push_back(part_status(plan, p));
    const Resubmission again = choose_resubmission(plan, status, records, queue.queued);
    if (dry_run) {
        fmt::print("# gdr submit --resume --dry-run: nothing was submitted. Without --dry-run it would run\n");
        for (const std::string& id : again.stale_merges) fmt::print("#   {}\n", shown({"scancel", id}));
        fmt::print("{}", queue_commands(plan, again.parts, false));
        fmt::print("# parts to render again: {}\n", again.parts.empty() ? "none" : array_ranges(again.parts));
        return 0;
    }
    if (find_program("sbatch").empty()) throw RuntimeFailure("sbatch not found: gdr submit needs Slurm's sbatch on PATH");
    // The cancellations and the new jobs' records complete before a stop signal ends the process.
    const WriteSection section;
    for (const std::string& id : again.stale_merges) {
        const ProgramResult r = run_program({"scancel", id});
        if (r.status != 0) throw RuntimeFailure("scancel " + id + " failed: " + first_line(r.err));
        fmt::print("cancelled merge job {}: a part it waited for had failed, so it could never run\n", id);
    }
    fmt::print("{}: resubmitting {}\n", plan.out,
               again.parts.empty() ? std::string("the merge (every part is complete)")
                                   : "parts " + array_ranges(again.parts) + " and the merge");
    queue_jobs(plan, again.parts, false);
    return 0;
}

}  // namespace

std::vector<SampleRange> divide_samples(uint64_t seed, uint64_t total, int parts) {
    if (parts < 1 || uint64_t(parts) > total)
        throw ParameterError(fmt::format("cannot divide {} samples per pixel into {} parts: each part needs at least one",
                                         total, parts));
    std::vector<SampleRange> out;
    const uint64_t base = total / uint64_t(parts), extra = total % uint64_t(parts);
    uint64_t first = 0;
    for (int i = 0; i < parts; ++i) {
        const uint64_t count = base + (uint64_t(i) < extra ? 1 : 0);
        out.push_back({seed, first, count});
        first += count;
    }
    return out;
}

std::string parts_dir_of(const std::string& out) {
    const fs::path p = fs::path(absolute(out));
    return (p.parent_path() / (p.stem().string() + ".parts")).string();
}

std::string shell_quote(const std::string& s) {
    if (plain(s)) return s;
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

std::string sbatch_quote(const std::string& s) {
    if (plain(s)) return s;
    std::string q = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') q += '\\';
        q += c;
    }
    return q + "\"";
}

std::string array_ranges(std::vector<int> tasks) {
    std::sort(tasks.begin(), tasks.end());
    tasks.erase(std::unique(tasks.begin(), tasks.end()), tasks.end());
    std::string s;
    for (size_t i = 0; i < tasks.size();) {
        size_t j = i;
        while (j + 1 < tasks.size() && tasks[j + 1] == tasks[j] + 1) ++j;
        if (!s.empty()) s += ',';
        s += std::to_string(tasks[i]);
        if (j > i) s += "-" + std::to_string(tasks[j]);
        i = j + 1;
    }
    return s;
}

std::string render_script(const SubmitPlan& plan) {
    std::vector<int> all;
    for (const Part& p : plan.parts) all.push_back(p.index);
    const std::string tasks = array_ranges(all);
    std::string s = "#!/bin/bash\n";
    s += fmt::format("# Written by gdr submit (gdr {}). Array task i renders part i of\n#   {}\n", version(), plan.out);
    s += fmt::format("# into part-i.exr here: the samples first .. first+spp-1 of seed {} in every pixel.\n", plan.seed);
    s += fmt::format("# The {} parts hold the {} samples per pixel of one render; merge.sbatch merges them.\n",
                     plan.parts.size(), plan.spp);
    s += "# A task whose part is complete does nothing; one whose part is partial (stopped by\n";
    s += "# SIGTERM: scancel, a time limit) continues it. To resubmit what is not complete:\n";
    s += "#   gdr submit --resume " + shell_quote(plan.out) + "\n";
    s += "#SBATCH --job-name=" + sbatch_quote(plan.job_name) + "\n";
    s += "#SBATCH --array=" + tasks + "\n";
    s += "#SBATCH --chdir=" + sbatch_quote(plan.dir) + "\n";
    s += "#SBATCH --output=logs/part-%a.log\n";
    s += "#SBATCH --open-mode=append\n";
    for (const std::string& o : plan.sbatch) s += sbatch_line(o);
    s += "set -eu\n";
    s += "part=${SLURM_ARRAY_TASK_ID:?this is a Slurm array job script: submit it with sbatch}\n";
    s += "case $part in\n";
    for (const Part& p : plan.parts)
        s += fmt::format("    {}) first={} spp={} ;;\n", p.index, p.samples.first, p.samples.count);
    s += fmt::format("    *) echo \"gdr: no part $part in this render (parts {})\" >&2; exit 2 ;;\n", tasks);
    s += "esac\n";
    // Options stay on one line with their values.
    std::vector<std::string> words = {"exec " + shell_quote(plan.gdr) + " render", shell_quote(plan.scene)};
    for (size_t i = 0; i < plan.render_args.size(); ++i) {
        std::string w = shell_quote(plan.render_args[i]);
        if (i + 1 < plan.render_args.size() && plan.render_args[i].rfind("--", 0) == 0)
            w += " " + shell_quote(plan.render_args[++i]);
        words.push_back(w);
    }
    const bool threads_given = std::count(plan.render_args.begin(), plan.render_args.end(), "--threads") > 0;
    words.push_back("--seed " + std::to_string(plan.seed));
    words.push_back("--first-sample \"$first\"");
    words.push_back("--spp \"$spp\"");
    // The CPUs Slurm gave the task, not every core of the node.
    if (!threads_given) words.push_back("--threads \"${SLURM_CPUS_ON_NODE:-0}\"");
    words.push_back("--continue");
    words.push_back("-o \"part-$part.exr\"");
    return s + command_lines(words);
}

std::string merge_script(const SubmitPlan& plan) {
    std::string s = "#!/bin/bash\n";
    s += fmt::format("# Written by gdr submit (gdr {}). Merges the {} parts in this folder into\n#   {}\n", version(),
                     plan.parts.size(), plan.out);
    s += "# (their samples pooled, the reconstructions recomputed). Submitted with\n";
    s += "# --dependency=afterok:<render array job>, so it runs once every part has succeeded;\n";
    s += "# --complete refuses a part short of its samples.\n";
    s += "#SBATCH --job-name=" + sbatch_quote(plan.job_name + "-merge") + "\n";
    s += "#SBATCH --chdir=" + sbatch_quote(plan.dir) + "\n";
    s += "#SBATCH --output=logs/merge.log\n";
    s += "#SBATCH --open-mode=append\n";
    s += "#SBATCH --kill-on-invalid-dep=yes\n";
    for (const std::string& o : plan.sbatch) s += sbatch_line(o);
    s += "set -eu\n";
    s += "exec " + shell_quote(plan.gdr) + " merge --complete";
    for (size_t i = 0; i < plan.parts.size(); ++i) {
        s += i % kPartsPerLine == 0 ? " \\\n    " : " ";
        s += shell_quote(fs::path(plan.parts[i].file).filename().string());
    }
    return s + " \\\n    -o " + shell_quote(plan.out) + "\n";
}

std::string format_plan(const SubmitPlan& plan) {
    std::string s = fmt::format("# gdr submit's plan (gdr {}), read by gdr submit --resume and gdr status\n", version());
    s += fmt::format("format {}\n", kPlanFormat);
    s += "out " + plan.out + "\n";
    s += "scene " + plan.scene + "\n";
    s += "gdr " + plan.gdr + "\n";
    s += "integrator " + plan.integrator + "\n";
    s += "job_name " + plan.job_name + "\n";
    s += fmt::format("seed {}\nspp {}\n", plan.seed, plan.spp);
    for (const std::string& a : plan.render_args) s += "render_arg " + a + "\n";
    for (const std::string& o : plan.sbatch) s += "sbatch " + o + "\n";
    for (const Part& p : plan.parts) s += fmt::format("part {} {} {}\n", p.index, p.samples.first, p.samples.count);
    return s;
}

SubmitPlan parse_plan(const std::string& text, const std::string& file) {
    SubmitPlan plan;
    plan.dir = fs::path(absolute(file)).parent_path().string();
    bool format_seen = false;
    for (const std::string& line : lines_of(text)) {
        if (line.empty() || line[0] == '#') continue;
        const size_t sp = line.find(' ');
        const std::string key = line.substr(0, sp), value = sp == std::string::npos ? "" : line.substr(sp + 1);
        if (key == "format") {
            if (value != std::to_string(kPlanFormat))
                throw InputError(file + ": plan format " + value + ", but this gdr reads format " +
                                 std::to_string(kPlanFormat));
            format_seen = true;
        } else if (key == "out") plan.out = value;
        else if (key == "scene") plan.scene = value;
        else if (key == "gdr") plan.gdr = value;
        else if (key == "integrator") plan.integrator = value;
        else if (key == "job_name") plan.job_name = value;
        else if (key == "seed") plan.seed = parse_count(value, "seed", file);
        else if (key == "spp") plan.spp = parse_count(value, "spp", file);
        else if (key == "render_arg") plan.render_args.push_back(value);
        else if (key == "sbatch") plan.sbatch.push_back(value);
        else if (key == "part") {
            std::istringstream in(value);
            std::string index, first, count, rest;
            in >> index >> first >> count;
            if (count.empty() || (in >> rest)) throw InputError(file + ": malformed part line '" + line + "'");
            Part p;
            p.index = int(parse_count(index, "a part index", file));
            p.samples = {0, parse_count(first, "a first sample", file), parse_count(count, "a sample count", file)};
            plan.parts.push_back(p);
        } else {
            throw InputError(file + ": unknown plan entry '" + key + "'");
        }
    }
    if (!format_seen || plan.out.empty() || plan.parts.empty() || plan.spp == 0)
        throw InputError(file + ": not a complete gdr submit plan (format, out, spp and parts are needed)");
    uint64_t next = 0;
    for (size_t i = 0; i < plan.parts.size(); ++i) {
        Part& p = plan.parts[i];
        if (p.index != int(i) || p.samples.first != next || p.samples.count == 0)
            throw InputError(file + ": part " + std::to_string(p.index) +
                             " does not continue the parts before it (parts must be 0, 1, ... with consecutive samples)");
        p.samples.seed = plan.seed;
        p.file = plan.dir + "/part-" + std::to_string(p.index) + ".exr";
        next += p.samples.count;
    }
    if (next != plan.spp)
        throw InputError(fmt::format("{}: the parts hold {} samples per pixel, but the plan says {}", file, next, plan.spp));
    return plan;
}

SubmitPlan read_plan(const std::string& out) {
    const std::string dir = parts_dir_of(out);
    const std::string file = dir + "/plan.txt";
    std::error_code ec;
    if (!fs::exists(file, ec))
        throw InputError(out + " was not submitted with gdr submit: no plan " + file);
    SubmitPlan plan = parse_plan(read_text(file), file);
    if (fs::weakly_canonical(plan.out, ec) != fs::weakly_canonical(absolute(out), ec))
        throw InputError(file + " is the plan of " + plan.out + ", not of " + out);
    return plan;
}

std::string format_job_record(const JobRecord& job) {
    return job.kind + " " + job.id + (job.parts.empty() ? "" : " " + array_ranges(job.parts)) + "\n";
}

std::vector<JobRecord> parse_job_records(const std::string& text) {
    std::vector<JobRecord> out;
    for (const std::string& line : lines_of(text)) {
        std::istringstream in(line);
        JobRecord r;
        std::string ranges;
        in >> r.kind >> r.id >> ranges;
        if ((r.kind != "render" && r.kind != "merge") || r.id.empty()) continue;
        // "0-3,5": every index of each run.
        for (size_t at = 0; at < ranges.size();) {
            const size_t end = std::min(ranges.find(',', at), ranges.size());
            const std::string run = ranges.substr(at, end - at);
            const size_t dash = run.find('-');
            const int a = std::atoi(run.substr(0, dash).c_str());
            const int b = dash == std::string::npos ? a : std::atoi(run.substr(dash + 1).c_str());
            for (int i = a; i <= b && b - a < kMaxParts; ++i) r.parts.push_back(i);
            at = end + 1;
        }
        out.push_back(r);
    }
    return out;
}

std::vector<JobState> parse_squeue(const std::string& text) {
    std::vector<JobState> out;
    for (const std::string& line : lines_of(text)) {
        const size_t a = line.find('|'), b = a == std::string::npos ? a : line.find('|', a + 1);
        if (a == std::string::npos) continue;
        JobState j;
        j.id = trim(line.substr(0, a));
        j.state = trim(line.substr(a + 1, b == std::string::npos ? std::string::npos : b - a - 1));
        if (b != std::string::npos) j.reason = trim(line.substr(b + 1));
        if (!j.id.empty()) out.push_back(j);
    }
    return out;
}

std::vector<JobState> parse_sacct(const std::string& text) {
    std::vector<JobState> out;
    for (JobState j : parse_squeue(text)) {
        if (j.id.find('[') != std::string::npos) continue;  // tasks not started yet: squeue lists them
        j.state = j.state.substr(0, j.state.find(' '));     // "CANCELLED by 0"
        if (j.reason == "0:0") j.reason.clear();
        else if (!j.reason.empty()) j.reason = "exit code " + j.reason;
        out.push_back(j);
    }
    return out;
}

bool job_active(const std::string& state) {
    static const std::set<std::string> ended = {"COMPLETED", "FAILED",      "CANCELLED",     "TIMEOUT",
                                                "NODE_FAIL", "PREEMPTED",   "OUT_OF_MEMORY", "BOOT_FAIL",
                                                "DEADLINE",  "SPECIAL_EXIT", "REVOKED"};
    return !state.empty() && !ended.count(state);
}

PartStatus part_status(const SubmitPlan& plan, const Part& part) {
    PartStatus s;
    std::error_code ec;
    if (!fs::exists(part.file, ec)) return s;
    s.file = PartFile::unusable;
    ExrHeader h;
    try {
        h = read_exr_header(part.file);
    } catch (const Error& e) {
        s.note = e.what();
        return s;
    }
    const auto get = [&](const std::string& key) {
        const auto it = h.metadata.find(key);
        return it == h.metadata.end() ? std::string() : it->second;
    };
    if (!plan.integrator.empty() && get("integrator") != plan.integrator) {
        s.note = "rendered with integrator '" + get("integrator") + "', not '" + plan.integrator + "'";
        return s;
    }
    // One run "seed:first:count" of the part's seed from its first sample.
    const std::string ranges = get("sample_ranges");
    const size_t c1 = ranges.find(':'), c2 = c1 == std::string::npos ? c1 : ranges.find(':', c1 + 1);
    if (ranges.empty() || ranges.find(',') != std::string::npos || c2 == std::string::npos) {
        s.note = "holds samples '" + ranges + "', not one run of the part's";
        return s;
    }
    try {
        const uint64_t seed = parse_count(ranges.substr(0, c1), "seed", part.file);
        const uint64_t first = parse_count(ranges.substr(c1 + 1, c2 - c1 - 1), "first sample", part.file);
        const uint64_t count = parse_count(ranges.substr(c2 + 1), "sample count", part.file);
        if (seed != part.samples.seed || first != part.samples.first || count > part.samples.count) {
            s.note = fmt::format("holds samples {}-{} of seed {}, not part of {} of seed {}", first, first + count - 1,
                                 seed, samples_text(part.samples), part.samples.seed);
            return s;
        }
        s.spp = count;
        s.file = count == part.samples.count ? PartFile::complete : PartFile::partial;
    } catch (const Error& e) {
        s.note = e.what();
    }
    return s;
}

Resubmission choose_resubmission(const SubmitPlan& plan, const std::vector<PartStatus>& status,
                                 const std::vector<JobRecord>& records, const std::vector<JobState>& queued) {
    for (size_t i = 0; i < plan.parts.size() && i < status.size(); ++i)
        if (status[i].file == PartFile::unusable)
            throw InputError(plan.parts[i].file + ": " + status[i].note +
                             "; remove it to render the part again");
    Resubmission r;
    std::string busy;
    for (const JobState& j : queued) {
        const auto rec = std::find_if(records.begin(), records.end(), [&](const JobRecord& x) { return x.id == base_id(j.id); });
        if (rec == records.end() || !job_active(j.state)) continue;
        // A merge whose parts failed waits for ever (unless Slurm cancels it): it goes.
        if (rec->kind == "merge" && j.reason.find("DependencyNeverSatisfied") != std::string::npos) {
            r.stale_merges.push_back(j.id);
            continue;
        }
        if (!busy.empty()) busy += ", ";
        busy += j.id + " (" + j.state + ")";
    }
    if (!busy.empty())
        throw InputError("jobs of " + plan.out + " are still queued: " + busy +
                         "; resubmitting now would render their parts twice. Wait for them (gdr status " +
                         shell_quote(plan.out) + ") or cancel them (scancel) first");
    for (size_t i = 0; i < plan.parts.size(); ++i)
        if (i >= status.size() || status[i].file != PartFile::complete) r.parts.push_back(plan.parts[i].index);
    return r;
}

int submit(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::string scene_path, out_path, integrator_name, resume_out, gdr_path;
    long long parts = 0, spp = -1, seed = -1, threads = -1, cpus = 0;
    int width = 0, height = 0;
    bool dry_run = false;
    std::vector<std::string> sets, sbatch_options, resolution_args;
    std::string partition;
    size_t given = 0;  // options other than --resume and --dry-run
    while (a.more()) {
        const std::string opt = a.next();
        if (opt == "-h" || opt == "--help") return print_usage("submit");
        if (opt != "--resume" && opt != "--dry-run") ++given;
        if (opt == "-o" || opt == "--output") out_path = a.value(opt);
        else if (opt == "--parts") parts = a.int_value(opt, 2, kMaxParts);
        else if (opt == "--spp") spp = a.int_value(opt, 1, std::numeric_limits<long long>::max() / kMaxParts);
        else if (opt == "--seed") seed = a.int_value(opt, 0, std::numeric_limits<long long>::max());
        else if (opt == "--integrator") integrator_name = a.value(opt);
        else if (opt == "--set") sets.push_back(a.value(opt));
        else if (opt == "--width" || opt == "--height") {
            const long long v = a.int_value(opt, 1, kMaxResolution);
            (opt == "--width" ? width : height) = int(v);
            resolution_args.insert(resolution_args.end(), {opt, std::to_string(v)});
        } else if (opt == "--resolution") {
            const std::string v = a.value(opt);
            std::tie(width, height) = parse_resolution(v);
            resolution_args.insert(resolution_args.end(), {opt, v});
        } else if (opt == "--threads") threads = a.int_value(opt, 0, kMaxThreads);
        else if (opt == "--time")
            throw ParameterError("submit: --time has no fixed sample count to divide into parts; give --spp N (the "
                                 "parts take consecutive samples of one seed)");
        else if (opt == "--frames")
            throw ParameterError("submit: --frames: gdr renders still images only (it has no animation yet), so "
                                 "there are no frames to render as array tasks; --parts N divides one image's samples");
        else if (opt == "--partition") partition = a.value(opt);
        else if (opt == "--cpus-per-task") cpus = a.int_value(opt, 1, kMaxThreads);
        else if (opt == "--sbatch") {
            const std::string v = a.value(opt);
            if (v.rfind("--", 0) != 0 || v.size() < 3)
                throw ParameterError("--sbatch '" + v + "': give an sbatch option in its long form, --name=value or --flag");
            check_one_line("--sbatch", v);
            sbatch_options.push_back(v);
        } else if (opt == "--gdr") gdr_path = a.value(opt);
        else if (opt == "--resume") resume_out = a.value(opt);
        else if (opt == "--dry-run") dry_run = true;
        else if (!opt.empty() && opt[0] == '-') throw ParameterError(usage_error("unknown option '" + opt + "'"));
        else if (scene_path.empty()) scene_path = opt;
        else throw ParameterError("submit: unexpected argument '" + opt + "'");
    }
    if (!resume_out.empty()) {
        if (given > 0 || !scene_path.empty())
            throw ParameterError("submit: --resume OUT.exr resubmits with the settings of the first submission; it "
                                 "takes only --dry-run");
        return resume_submission(resume_out, dry_run);
    }
    if (scene_path.empty()) throw ParameterError(usage_error("no scene file given"));
    if (out_path.empty()) throw ParameterError("submit: no output given (-o OUT.exr)");
    if (parts == 0) throw ParameterError("submit: give the number of parts (--parts N)");

    // Everything a part could trip over is checked here, once, rather than in
    // every task: the output, the scene, the integrator and its parameters.
    check_output_path(out_path);
    const std::string out = absolute(out_path), dir = parts_dir_of(out);
    std::error_code ec;
    if (fs::exists(out, ec))
        throw InputError("refusing to submit: " + out + " exists, and gdr submit never replaces a render (remove it or "
                         "choose another -o)");
    if (fs::exists(dir + "/plan.txt", ec))
        throw InputError(out + " was submitted already (" + dir + "): gdr status " + shell_quote(out) +
                         " shows its parts, gdr submit --resume " + shell_quote(out) + " resubmits what is missing");
    if (fs::exists(dir, ec))
        throw InputError("refusing to submit: the parts folder " + dir + " exists and is not a gdr submission; remove it");
    SceneFile sf = load_scene_file(scene_path);
    // Its parts would take a frame's seed, not the plan's, and read as unusable.
    if (sf.animation)
        throw InputError(scene_path + ": is an animation; gdr submit divides one still image into parts. Render its "
                         "frames with gdr render --frames FIRST:LAST (every frame an independent job, e.g. one per task)");
    std::vector<std::string> integrator_sets;
    for (const std::string& s : sets) {
        check_one_line("--set", s);
        if (is_scene_key(s)) apply_scene_setting(sf, s);
        else integrator_sets.push_back(s);
    }
    if (width > 0 || height > 0) set_resolution(sf, width, height);
    std::vector<std::string> inputs = sf.inputs;
    inputs.push_back(scene_path);
    check_not_an_input(out, inputs);
    const std::string name = integrator_name.empty() ? sf.defaults.integrator : integrator_name;
    Params params(integrator_sets.empty() ? sf.defaults.params.context() : "--set");
    for (const auto& [k, v] : sf.defaults.params.values()) params.set(k, v);
    for (const std::string& s : integrator_sets) params.set_from_text(s);
    require_integrator(name, "gdr submit --integrator " + name);
    require_plugins_of(params, "gdr submit");
    (void)integrator_registry().create(name, params);

    SubmitPlan plan;
    plan.out = out;
    plan.dir = dir;
    plan.scene = absolute(scene_path);
    if (gdr_path.empty()) gdr_path = fs::read_symlink("/proc/self/exe", ec).string();
    plan.gdr = absolute(gdr_path);
    if (access(plan.gdr.c_str(), X_OK) != 0)
        throw ParameterError("--gdr '" + plan.gdr + "': not an executable file (the jobs run it)");
    plan.integrator = name;
    plan.job_name = job_name_of(out);
    plan.seed = uint64_t(seed >= 0 ? seed : sf.defaults.seed);
    // --spp (or the scene's spp) is each part's: N parts of --spp S hold N * S samples.
    const uint64_t part_spp = uint64_t(spp > 0 ? spp : sf.defaults.spp);
    if (part_spp > uint64_t(std::numeric_limits<long long>::max()) / uint64_t(parts))
        throw ParameterError(fmt::format("submit: {} parts of {} spp run past the last sample number", parts, part_spp));
    plan.spp = part_spp * uint64_t(parts);
    plan.render_args = {"--integrator", name};
    for (const std::string& s : sets) plan.render_args.insert(plan.render_args.end(), {"--set", s});
    plan.render_args.insert(plan.render_args.end(), resolution_args.begin(), resolution_args.end());
    if (threads >= 0) plan.render_args.insert(plan.render_args.end(), {"--threads", std::to_string(threads)});
    else if (cpus > 0) plan.render_args.insert(plan.render_args.end(), {"--threads", std::to_string(cpus)});
    if (!partition.empty()) plan.sbatch.push_back("--partition=" + partition);
    if (cpus > 0) plan.sbatch.push_back("--cpus-per-task=" + std::to_string(cpus));
    plan.sbatch.insert(plan.sbatch.end(), sbatch_options.begin(), sbatch_options.end());
    for (const std::string& p : {plan.out, plan.scene, plan.gdr, plan.dir}) check_one_line("the path", p);
    const std::vector<SampleRange> ranges = divide_samples(plan.seed, plan.spp, int(parts));
    for (size_t i = 0; i < ranges.size(); ++i)
        plan.parts.push_back({int(i), ranges[i], dir + "/part-" + std::to_string(i) + ".exr"});
    std::vector<int> all;
    for (const Part& p : plan.parts) all.push_back(p.index);

    const std::string render = render_script(plan), merge = merge_script(plan);
    if (dry_run) {
        fmt::print("# gdr submit --dry-run: nothing was written or submitted. Without --dry-run, gdr submit\n");
        fmt::print("# writes these scripts and its plan into {}, then runs\n", plan.dir);
        fmt::print("{}", queue_commands(plan, all, true));
        fmt::print("\n==> {} <==\n{}\n==> {} <==\n{}", plan.render_script_path(), render, plan.merge_script_path(), merge);
        return 0;
    }
    if (find_program("sbatch").empty())
        throw RuntimeFailure("sbatch not found: gdr submit needs Slurm's sbatch on PATH (--dry-run prints the scripts)");
    // A stop signal waits for the folder, its scripts and the queued jobs'
    // records to be complete: a half-made folder could be neither resumed nor
    // submitted again.
    const WriteSection section;
    fs::create_directories(dir + "/logs", ec);
    if (ec) throw RuntimeFailure("cannot create " + dir + "/logs: " + ec.message());
    try {
        write_text(plan.plan_path(), format_plan(plan));
        write_text(plan.render_script_path(), render, true);
        write_text(plan.merge_script_path(), merge, true);
    } catch (const Error&) {
        fs::remove_all(dir, ec);
        throw;
    }
    fmt::print("{} parts of {} spp for {} ({} spp of seed {} in all), in {}\n", plan.parts.size(), part_spp, plan.out,
               plan.spp, plan.seed, plan.dir);
    try {
        queue_jobs(plan, all, true);
    } catch (const RuntimeFailure& e) {
        // Nothing queued: the folder goes, so that the same command can be run again.
        if (read_job_records(plan).empty()) {
            fs::remove_all(dir, ec);
            throw RuntimeFailure(std::string(e.what()) + "\nnothing was queued; " + dir + " was removed");
        }
        throw;
    }
    return 0;
}

int status(const std::vector<std::string>& args) {
    if (args.size() == 1 && (args[0] == "-h" || args[0] == "--help")) return print_usage("status");
    if (args.size() != 1) throw ParameterError("status: expected the OUT.exr given to gdr submit\n" + usage("status"));
    const SubmitPlan plan = read_plan(args[0]);
    const std::vector<JobRecord> records = read_job_records(plan);
    const QueueView queue = look_up_jobs(records, true);
    fmt::print("{}: {} parts of seed {}, {} spp in all ({})\n", plan.out, plan.parts.size(), plan.seed, plan.spp, plan.dir);
    int complete = 0, partial = 0, missing = 0, unusable = 0, running = 0, pending = 0;
    std::vector<int> stopped;  // not complete, and no job of theirs is queued
    std::vector<std::array<std::string, 4>> rows = {{"part", "samples", "file", "job"}};
    for (const Part& p : plan.parts) {
        const PartStatus s = part_status(plan, p);
        std::string file;
        switch (s.file) {
            case PartFile::missing: file = "missing", ++missing; break;
            case PartFile::partial: file = fmt::format("partial ({} of {} spp)", s.spp, p.samples.count), ++partial; break;
            case PartFile::complete: file = fmt::format("complete ({} spp)", s.spp), ++complete; break;
            case PartFile::unusable: file = "unusable: " + s.note, ++unusable; break;
        }
        const std::string task = task_of(records, p.index);
        const JobState* j = task.empty() ? nullptr : state_of(queue, task);
        const bool active = !task.empty() && in_queue(queue, task);
        if (active && j->state == "RUNNING") ++running;
        else if (active) ++pending;
        if (s.file != PartFile::complete && !active) stopped.push_back(p.index);
        const std::string job = task.empty() ? "not submitted"
                                : j          ? task + " " + job_text(j)
                                : queue.squeue ? task + " not in the queue"
                                               : task;
        rows.push_back({std::to_string(p.index), samples_text(p.samples), file, job});
    }
    const std::string problem = merged_problem(plan);
    const std::string merge_id = merge_job_of(records);
    const JobState* mj = merge_id.empty() ? nullptr : state_of(queue, merge_id);
    const std::string merge_job = merge_id.empty() ? "not submitted"
                                  : mj             ? merge_id + " " + job_text(mj)
                                  : queue.squeue   ? merge_id + " not in the queue"
                                                   : merge_id;
    rows.push_back({"merge", "", problem.empty() ? "merged" : problem, merge_job});
    size_t w[3] = {0, 0, 0};
    for (const auto& r : rows)
        for (int k = 0; k < 3; ++k) w[k] = std::max(w[k], r[size_t(k)].size());
    for (const auto& r : rows) fmt::print("  {:<{}}  {:<{}}  {:<{}}  {}\n", r[0], w[0], r[1], w[1], r[2], w[2], r[3]);
    fmt::print("parts: {} complete, {} partial, {} missing{}; jobs: {} running, {} pending\n", complete, partial,
               missing, unusable ? fmt::format(", {} unusable", unusable) : "", running, pending);
    fmt::print("merged: {}\n", problem.empty() ? "yes" : "no");
    if (!queue.squeue) fmt::print("scheduler: {}; states come from the part files alone\n", queue.squeue_note);
    else if (!queue.sacct && !records.empty())
        fmt::print("scheduler: squeue ({}; ended jobs are not shown)\n", queue.sacct_note);
    const bool merge_active = !merge_id.empty() && in_queue(queue, merge_id);
    if (problem.empty()) {
        fmt::print("done: {} holds all {} spp\n", plan.out, plan.spp);
    } else if (!queue.squeue && !records.empty()) {
        // Without squeue a part that is not complete may still be running.
    } else if (!stopped.empty() && running + pending == 0) {
        fmt::print("stopped or failed: {} {}; gdr submit --resume {} resubmits {} and the merge\n",
                   stopped.size() == 1 ? "part" : "parts", array_ranges(stopped), shell_quote(plan.out),
                   stopped.size() == 1 ? "it" : "them");
    } else if (stopped.empty() && running + pending == 0 && !merge_active && queue.squeue) {
        fmt::print("every part is complete but nothing merges them: gdr submit --resume {} submits the merge\n",
                   shell_quote(plan.out));
    }
    return 0;
}

}  // namespace gdr::cli
