// Renders as Slurm array jobs (`gdr submit`, `gdr status`): how a render is
// divided into parts, the sbatch scripts that render and merge them, the plan
// kept beside the output, and what the part files and the scheduler say of
// each part. Pure functions of their arguments where they can be, so that the
// scripts are tested without Slurm.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gdr/cli/commands.h"

namespace gdr::cli {

/// gdr submit SCENE.json --parts N [render options] [sbatch options] [--dry-run] -o OUT.exr,
/// or gdr submit --resume OUT.exr [--dry-run]
int submit(const std::vector<std::string>& args);
/// gdr status OUT.exr
int status(const std::vector<std::string>& args);

/// Splits `total` samples per pixel of `seed` into `parts` consecutive runs
/// from sample 0, whose sizes differ by at most one (the first runs get the
/// extra samples). Merged, they hold the samples of one render of `total`.
/// Throws a ParameterError unless 1 <= parts <= total.
std::vector<SampleRange> divide_samples(uint64_t seed, uint64_t total, int parts);

/// One part of a submitted render: array task `index` renders `samples` into `file`.
struct Part {
    int index = 0;          ///< Array task index, 0-based.
    SampleRange samples;    ///< Seed, first sample number and samples per pixel of the part.
    std::string file;       ///< Its render file (absolute path).
};

/// What `gdr submit` decided, kept in the parts folder as plan.txt so that
/// `gdr submit --resume` and `gdr status` know the parts.
struct SubmitPlan {
    std::string out;                       ///< The merged render, absolute path.
    std::string dir;                       ///< The parts folder: part files, scripts, logs, plan and job records.
    std::string scene;                     ///< Scene file, absolute path.
    std::string gdr;                       ///< The gdr binary the jobs run, absolute path.
    std::string integrator;                ///< Integrator name every part is rendered with.
    std::string job_name;                  ///< Slurm job name of the render array; the merge's adds "-merge".
    uint64_t seed = 0;                     ///< Sampler seed of every part.
    uint64_t spp = 0;                      ///< Samples per pixel of the merged render (all parts).
    std::vector<std::string> render_args;  ///< Options every part's gdr render gets besides its samples and output.
    std::vector<std::string> sbatch;       ///< Options given to sbatch in both scripts (#SBATCH lines), as "--name=value".
    std::vector<Part> parts;               ///< The parts, by index.

    /// The array-job script: task i renders part i.
    std::string render_script_path() const { return dir + "/render.sbatch"; }
    /// The merge job's script.
    std::string merge_script_path() const { return dir + "/merge.sbatch"; }
    /// The plan file (format_plan()).
    std::string plan_path() const { return dir + "/plan.txt"; }
    /// The record of submitted jobs (format_job_record(), one line each).
    std::string jobs_path() const { return dir + "/jobs.txt"; }
};

/// The parts folder of the merged render `out`: OUT's name without ".exr" plus ".parts", beside it.
std::string parts_dir_of(const std::string& out);

/// `s` as one word for bash: unchanged if it holds only characters that
/// need no quoting, else in single quotes (a ' becomes '\'').
std::string shell_quote(const std::string& s);

/// `s` as one argument of an #SBATCH line: in double quotes, with a double quote or backslash
/// escaped by a backslash (sbatch's own rule), unchanged if it needs none.
std::string sbatch_quote(const std::string& s);

/// Slurm's --array list of the task indices `tasks`: runs joined, "0-3" or "1,3,5-7".
std::string array_ranges(std::vector<int> tasks);

/// The array-job script of `plan`: its #SBATCH lines, a table of each part's
/// samples, and a gdr render --continue of part $SLURM_ARRAY_TASK_ID.
std::string render_script(const SubmitPlan& plan);

/// The merge job's script: gdr merge --complete of every part into plan.out.
std::string merge_script(const SubmitPlan& plan);

/// `plan` as the text of plan.txt: one "key value" line each, values to the end of the line.
std::string format_plan(const SubmitPlan& plan);

/// The plan in `text`, read from `file` (named in errors); throws an InputError for a malformed line.
SubmitPlan parse_plan(const std::string& text, const std::string& file);

/// The plan of the merged render `out`, read from its parts folder; throws an
/// InputError naming the folder if `out` was never submitted.
SubmitPlan read_plan(const std::string& out);

/// One job that gdr submit queued, as recorded in jobs.txt.
struct JobRecord {
    std::string kind;        ///< "render" (the array job) or "merge".
    std::string id;          ///< Slurm job id.
    std::vector<int> parts;  ///< The parts a render array job renders (none for a merge).
};

/// `job` as a line of jobs.txt ("render 123 0-3" or "merge 124"), with its newline.
std::string format_job_record(const JobRecord& job);

/// The records in the text of jobs.txt, oldest first (malformed lines are skipped).
std::vector<JobRecord> parse_job_records(const std::string& text);

/// What Slurm says of one job or array task.
struct JobState {
    std::string id;      ///< "123" (a job) or "123_4" (task 4 of array job 123).
    std::string state;   ///< Slurm's state: PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, TIMEOUT, ...
    std::string reason;  ///< squeue's reason (Dependency, Resources, ...) or sacct's exit code; "" if none.
};

/// The jobs in the output of `squeue -h -r -o '%i|%T|%r'`, one per array task.
std::vector<JobState> parse_squeue(const std::string& text);

/// The jobs in the output of `sacct -n -X -P -o JobID,State,ExitCode`
/// ("CANCELLED by 0" becomes CANCELLED; pending task ranges "123_[1-3]" are dropped: squeue has them).
std::vector<JobState> parse_sacct(const std::string& text);

/// True if a job in `state` may still run or is running (pending, running,
/// suspended, completing, ...), false once it has ended.
bool job_active(const std::string& state);

/// What a part's file holds.
enum class PartFile {
    missing,   ///< No file yet.
    partial,   ///< The part's first samples, short of its target (a task stopped before it finished).
    complete,  ///< All of the part's samples.
    unusable,  ///< Unreadable, or samples other than the part's (note says which).
};

/// A part's file as read from its header.
struct PartStatus {
    PartFile file = PartFile::missing;  ///< What the file holds.
    uint64_t spp = 0;                   ///< Samples per pixel it holds.
    std::string note;                   ///< Why it is unusable; "" otherwise.
};

/// What the file of `part` holds, read from its EXR header (the pixels are not read).
PartStatus part_status(const SubmitPlan& plan, const Part& part);

/// What `gdr submit --resume` submits again.
struct Resubmission {
    std::vector<int> parts;                ///< The parts to render again: those whose file is not complete.
    std::vector<std::string> stale_merges; ///< Merge jobs still queued that can never run (a part failed): to cancel.
};

/// The resubmission of a plan whose parts are in `status` (by index), whose
/// jobs are `records` and of which squeue lists `queued`. Throws an
/// InputError if a part file is unusable (naming it and why), or if a job of
/// the plan is still pending or running, other than a merge that can never
/// run: its parts would be rendered twice.
Resubmission choose_resubmission(const SubmitPlan& plan, const std::vector<PartStatus>& status,
                                 const std::vector<JobRecord>& records, const std::vector<JobState>& queued);

}  // namespace gdr::cli
