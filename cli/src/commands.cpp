#include "gdr/cli/commands.h"
#include "gdr/cli/submit.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <thread>

#include <fmt/core.h>

#include "gdr/core/error.h"
#include "gdr/io/exr.h"
#include "stop.h"

namespace gdr::cli {


namespace {

// One command's synopsis and options, as `gdr COMMAND --help` prints them.
struct CommandHelp {
    const char* name;
    const char* synopsis;
    const char* details;
};

const CommandHelp kCommands[] = {
    {"render",
     "gdr render SCENE.json|SCENE.xml [--integrator NAME] [--spp N | --time SECONDS] [--threads N] [--seed S]\n"
     "           [--width W] [--height H] [--resolution WxH] [--set key=value]... [--resume PREVIOUS.exr]\n"
     "           [-D name=value]... [--lenient] [--first-sample K] [--continue] [--exposure STOPS]\n"
     "           [--adaptive SHARE | --select-gradients SHARE] [--frame K | --frames FIRST:LAST]\n"
     "           -o OUT.exr",
     "Renders a scene into a multi-layer EXR (every layer, the settings in its header) and a PNG\n"
     "preview beside it (OUT.png).\n"
     "  --integrator NAME     pt, gpt, bdpt, gbdpt, tgpt or any registered one (gdr list); default: the scene's\n"
     "  --spp N               samples per pixel (with --resume: the new total)\n"
     "  --time SECONDS        render whole passes until the wall-clock budget is spent (with --resume: the new total)\n"
     "  --threads N           worker threads (0: all cores)\n"
     "  --seed S              sampler seed; parts with different seeds merge (gdr merge)\n"
     "  --width W, --height H resolution; one of them alone keeps the camera's aspect ratio\n"
     "  --resolution WxH      both at once\n"
     "  --set key=value       an integrator parameter (gdr list shows them), or the scene's fov (degrees);\n"
     "                        gpt, gbdpt, tgpt: reconstruct=NAME[,NAME...] (each writes reconstruction_NAME),\n"
     "                        reconstruct.KEY=V (reconstruct.NAME.KEY=V of a list), shift.KEY=V; a name not\n"
     "                        registered loads the plugins (GDR_PLUGIN_PATH, else <libdir>/gdr)\n"
     "  --resume FILE.exr     continue FILE's sample sequence towards its target (or a new --spp/--time\n"
     "                        total), with its integrator and parameters; refused for another scene,\n"
     "                        integrator, parameter or resolution\n"
     "  --first-sample K      start at sample K of the seed's sequence (default 0): parts of one seed with\n"
     "                        consecutive samples merge into one render of all of them\n"
     "  --continue            if OUT exists, continue it in place (it must hold this seed's samples from\n"
     "                        the first sample); if it holds all --spp, do nothing. For parts that a\n"
     "                        scheduler may stop and run again\n"
     "  --adaptive SHARE      adaptive sampling: a pilot of SHARE of the budget (0 to 0.5, e.g. 0.125) with\n"
     "                        a seed of its own finds where the gradients (or, for pt, the colours) are\n"
     "                        noisy, and the rest of the budget goes there; the pilot's samples are not\n"
     "                        kept, so every pixel stays unbiased. The layers spp and sample_density\n"
     "                        record each pixel's count and density; --resume keeps the density\n"
     "  --select-gradients SHARE\n"
     "                        gpt: pilots of SHARE of the budget decide per 16x16 tile whether gradients\n"
     "                        pay for their cost; the other pixels take primal-only samples, as many as\n"
     "                        fit in the same time (layers gradient_mask, sample_density; --resume keeps\n"
     "                        both)\n"
     "  -D name=value         a Mitsuba XML scene's $parameter (overrides its <default>)\n"
     "  --lenient             a Mitsuba XML scene's unsupported elements become warnings and are skipped\n"
     "  --exposure STOPS      exposure of the PNG preview\n"
     "  -o OUT.exr            the output; never one of the inputs\n"
     "  --frame K             frame K of an animated scene (default: its first frame); the image gets the\n"
     "                        layers motion_fwd, motion_bwd (pixels to frames K+1, K-1) and object_id\n"
     "  --frames FIRST:LAST   every frame from FIRST to LAST (inclusive), each an independent render whose\n"
     "                        seed derives from --seed and the frame; -o (and --resume) take a frame\n"
     "                        pattern such as out.%04d.exr\n"
     "Ctrl-C (or SIGTERM) stops within about a second and writes the finished passes (exit status 130,\n"
     "143); a second Ctrl-C stops at once, still writing the finished passes. A signal during the final\n"
     "write lets it finish, then exits 130/143; a signal while the scene loads exits at once. No\n"
     "temporary file is left behind.\n"
     "OUT is locked for the whole run (flock on OUT.exr.lock, which names the holder's pid and host): a\n"
     "second run to OUT, such as another --continue of the same part, is refused. --continue replaces\n"
     "OUT only if it still holds what it read, else its new samples go to a rescue file. Where the file\n"
     "system has no flock a warning says so; where flock works on one node only (Lustre with\n"
     "localflock), runs on different nodes are not kept apart and only that last check remains."},
    {"merge", "gdr merge A.exr B.exr [...] [--complete] [--frames FIRST:LAST] -o OUT.exr",
     "Pools renders of one scene with one integrator and its parameters (parts rendered with different\n"
     "seeds, or continuations of one seed) into the image of all their samples. Renders that hold the\n"
     "same samples, or differ in scene, integrator, parameter or resolution, are refused. A merged\n"
     "file can be merged again.\n"
     "  --complete   refuse renders short of the samples they were asked for (stopped early)\n"
     "  --frames FIRST:LAST  merge each frame of an animation: every file name is a pattern (a.%04d.exr)\n"
     "OUT is locked while the merge runs (OUT.exr.lock, as for gdr render). Ctrl-C or SIGTERM during the\n"
     "write lets it finish, then exits 130/143; no temporary file is left behind."},
    {"submit",
     "gdr submit SCENE.json --parts N [--spp N] [--seed S] [--integrator NAME] [--set key=value]...\n"
     "           [--width W] [--height H] [--resolution WxH] [--threads N] [--partition NAME]\n"
     "           [--cpus-per-task N] [--sbatch OPTION]... [--gdr PATH] [--dry-run] -o OUT.exr\n"
     "gdr submit --resume OUT.exr [--dry-run]",
     "Renders a scene on a Slurm cluster: an array job whose task i renders part i, and a job that\n"
     "merges the parts into OUT.exr once every part has succeeded (sbatch --dependency=afterok). Part i\n"
     "takes samples i*N .. (i+1)*N-1 of one seed, so the merge equals one render of all the samples.\n"
     "The scripts, part files, logs and job ids go into a folder beside OUT named after it (box.parts/\n"
     "for box.exr). OUT and that folder must not exist yet. The scene, the gdr binary and the folder\n"
     "must be reachable at the same paths on the compute nodes.\n"
     "  --parts N             number of parts (array tasks), at least 2\n"
     "  --spp N               samples per pixel of each part (default: the scene's): OUT gets N x parts\n"
     "  --seed, --integrator, --set, --width, --height, --resolution\n"
     "                        as for gdr render (default: the scene's)\n"
     "  --threads N           worker threads per part (default: the CPUs Slurm gives the task)\n"
     "  --partition NAME      Slurm partition of both jobs\n"
     "  --cpus-per-task N     CPUs per task (and --threads N)\n"
     "  --sbatch OPTION       another sbatch option for both jobs, --name=value or --flag (repeatable)\n"
     "  --gdr PATH            the gdr binary the jobs run (default: this one)\n"
     "  --dry-run             print the scripts and the sbatch commands; write and submit nothing\n"
     "  --resume OUT.exr      resubmit the parts of OUT that are not complete, and the merge\n"
     "A task whose part is complete does nothing; a part stopped by SIGTERM (scancel, a time limit) is\n"
     "continued by the next run of its task. Prints the job ids; gdr status OUT shows the progress."},
    {"status", "gdr status OUT.exr",
     "Reports each part of a render submitted with gdr submit: complete, partial (stopped before its\n"
     "samples were all taken) or missing, from the part files; and its job's state from squeue, and\n"
     "from sacct once it has ended (where Slurm keeps accounting). Says what to resubmit."},
    {"info", "gdr info FILE.exr", "Prints the layers of an EXR, their means, and the settings stored in its header."},
    {"reconstruct", "gdr reconstruct IN.exr|NAME-primal.exr [--method NAME] [--alpha A] [--set key=value]... -o OUT.exr\n"
                    "gdr reconstruct --frames 'IN.%04d.exr' FIRST:LAST [--set key=value]... -o 'OUT.%04d.exr'",
     "Reconstructs an image from a gradient-domain render's primal and gradients (gdr's layers, or the\n"
     "NAME-primal/dx/dy/direct.exr files of the Mitsuba-based implementation).\n"
     "  --frames        a frame sequence with temporal differences (layers dt, motion_fwd, dt_valid),\n"
     "                  solved together in Hann-blended windows (gdr/reconstruct/temporal.h; --set\n"
     "                  takes its options, e.g. norm=l2, window=10, step=5, w_t=1)\n"
     "  --method NAME   poisson-l1 (default), poisson-l2, neural (where built: a plugin, loaded when asked\n"
     "                  for; --set weights=W.pt, default the shipped model), or any registered\n"
     "                  reconstructor or a plugin's (gdr list; plugins are looked for in GDR_PLUGIN_PATH,\n"
     "                  else <libdir>/gdr); --set key=value gives its parameters\n"
     "  --alpha A       weight of the primal in the screened Poisson energy (default 0.2)\n"
     "OUT is locked while it runs (OUT.exr.lock, as for gdr render; with --frames one lock named after\n"
     "the pattern). Ctrl-C or SIGTERM lets the file being written finish (with --frames: the frame being\n"
     "written), then exits 130/143."},
    {"compare", "gdr compare IMAGE.exr REFERENCE.exr [--layer NAME] [--ref-layer NAME] [--downsample K]\n"
                "gdr compare --frames 'IMAGE.%04d.exr' 'REFERENCE.%04d.exr' FIRST:LAST [--layer NAME] [...]",
     "Prints which layers are compared, the error of IMAGE against REFERENCE (MSE, relMSE, MAE, SSIM)\n"
     "and the per-channel means of both.\n"
     "  --layer NAME      layer of IMAGE (default: its final image, the one its PNG preview shows:\n"
     "                    reconstruction_neural, else reconstruction_weighted, else reconstruction_l1,\n"
     "                    else its first other reconstruction_NAME, else color); REFERENCE uses it too if it has that layer and --ref-layer\n"
     "                    is not given, else its own final image\n"
     "  --ref-layer NAME  layer of REFERENCE\n"
     "  --downsample K    box-filter the larger image down by K, which must be exactly K times the\n"
     "                    smaller in both dimensions; without it, sizes that differ by one integer\n"
     "                    factor in both dimensions are downsampled automatically\n"
     "  --frames          compare frames FIRST to LAST (inclusive) of two sequences: each frame's relMSE,\n"
     "                    their mean, and the temporal (flicker) relMSE, mean over consecutive frames,\n"
     "                    pixels and channels of ((x[k+1]-x[k])-(r[k+1]-r[k]))^2/(((r[k+1]+r[k])/2)^2+0.01)\n"
     "A grey layer is broadcast to compare with an RGB one, and alpha is dropped to compare with RGB."},
    {"video",
     "gdr video 'IN.%04d.exr' FIRST:LAST -o OUT.mp4|'OUT.%04d.png' [--layer NAME] [--png 'F.%04d.png']\n"
     "          [--fps F] [--crf N] [--exposure STOPS]",
     "Makes a video of an animation's frames FIRST to LAST (inclusive): each frame's EXR is tone-mapped\n"
     "as gdr's PNG previews are (sRGB, clamped to [0,1], NaN black), and written as a PNG sequence\n"
     "and/or encoded as an MP4 by ffmpeg (H.264 with libx264 if it has it, yuv420p; an odd width or\n"
     "height is padded to even by repeating the last column or row). Without ffmpeg on PATH the PNG\n"
     "sequence is written instead (--png, else OUT.%04d.png beside OUT.mp4) and the exit status is 0.\n"
     "OUT.mp4 is written under a temporary name and renamed when complete, so a failed encode leaves\n"
     "an existing OUT.mp4 as it was. Outputs never replace an input; other existing outputs are replaced.\n"
     "  --layer NAME      the layer shown (default: each frame's final image, as its PNG preview shows:\n"
     "                    reconstruction_neural, else reconstruction_weighted, else reconstruction_l1,\n"
     "                    else the first other reconstruction_NAME, else color; for frames of gdr reconstruct --frames, color); every frame\n"
     "                    must have it\n"
     "  --png PATTERN     also write the PNG sequence (with -o OUT.mp4)\n"
     "  --fps F           frame rate (default: the \"fps\" gdr render --frames stores, also found through a\n"
     "                    reconstructed frame's input; else 24)\n"
     "  --crf N           H.264 quality, 0 (lossless) to 51 (default 18)\n"
     "  --exposure STOPS  exposure, as gdr render --exposure gives the PNG previews"},
    {"check-shift",
     "gdr check-shift SCENE.json|SCENE.xml [--shift NAME] [--set key=value]... [--integrator gpt|gbdpt]\n"
     "                [--paths N] [--seed S] [--max-depth D] [--threshold T] [--probabilistic] [-D name=value]...\n"
     "                [--lenient]",
     "Samples base paths, shifts each to its right-hand neighbour, and checks the failure rate,\n"
     "reversibility and each step's analytic against a finite-difference Jacobian. Ends with PASS or FAIL.\n"
     "  --shift NAME    a registered shift mapping, or a plugin's (gdr list); --set key=value its parameters\n"
     "  --integrator gbdpt  base paths that join a camera and a light subpath, shifted as gbdpt does\n"
     "  -D name=value   a Mitsuba XML scene's $parameter (overrides its <default>)\n"
     "  --lenient       a Mitsuba XML scene's unsupported elements become warnings and are skipped"},
    {"list", "gdr list", "Lists the registered integrators with their parameters, shift mappings and reconstructors."},
    {"help", "gdr help [COMMAND]", "Prints the usage of every command, or one command's options."},
    {"version", "gdr --version", "Prints gdr's version."},
};

const CommandHelp* find_command(const std::string& name) {
    for (const CommandHelp& c : kCommands)
        if (name == c.name) return &c;
    return nullptr;
}

}  // namespace

std::string version() { return GDR_VERSION; }

std::string usage() {
    std::string s = "usage:\n";
    for (const CommandHelp& c : kCommands) {
        std::string syn = c.synopsis;
        for (size_t at = syn.find('\n'); at != std::string::npos; at = syn.find('\n', at + 1)) syn.insert(at + 1, "  ");
        s += "  " + syn + "\n";
    }
    return s + "'gdr help COMMAND' or 'gdr COMMAND --help' prints a command's options.\n";
}

std::string usage(const std::string& command) {
    const CommandHelp* c = find_command(command);
    if (!c) return usage();
    return std::string("usage: ") + c->synopsis + "\n\n" + c->details + "\n";
}

int print_usage(const std::string& command) {
    fmt::print("{}", command.empty() ? usage() : usage(command));
    return 0;
}

int list_plugins();
int check_shift(const std::vector<std::string>& args);
int reconstruct(const std::vector<std::string>& args);
int compare(const std::vector<std::string>& args);
int video(const std::vector<std::string>& args);

int run(const std::vector<std::string>& args) {
    if (args.empty()) {
        fmt::print(stderr, "{}", usage());
        return 2;
    }
    if (args[0] == "-h" || args[0] == "--help") return print_usage("");
    if (args[0] == "--version" || args[0] == "-V" || args[0] == "version") {
        fmt::print("gdr {}\n", version());
        return 0;
    }
    if (args[0] == "help") {
        if (args.size() > 2) throw ParameterError("help: takes at most one command, got '" + args[2] + "'");
        if (args.size() == 2 && !find_command(args[1]))
            throw ParameterError("help: unknown command '" + args[1] + "'\n" + usage());
        return print_usage(args.size() == 2 ? args[1] : "");
    }
    // Before any worker thread starts: the threads inherit the blocked
    // signals, and the command's handling covers it from start to end.
    const CommandSignals signals;
    // Writing a 512x512 G-PT render's EXR (25 MB of ZIP-compressed floats)
    // took 1.15 s on one thread and 0.64 s on two.
    static const bool exr_threads = [] {
        set_exr_threads(int(std::max(1u, std::thread::hardware_concurrency())));
        return true;
    }();
    (void)exr_threads;
    const std::vector<std::string> rest(args.begin() + 1, args.end());
    const std::string& cmd = args[0];
    const auto dispatch = [&]() -> int {
        // `gdr COMMAND --help` for every command, before its own option parsing.
        if (find_command(cmd) && rest.size() == 1 && (rest[0] == "-h" || rest[0] == "--help")) return print_usage(cmd);
        if (cmd == "render") return render(rest);
        if (cmd == "info") return info(rest);
        if (cmd == "merge") return merge(rest);
        if (cmd == "submit") return submit(rest);
        if (cmd == "status") return status(rest);
        if (cmd == "list") {
            if (!rest.empty()) throw ParameterError("list: takes no arguments, got '" + rest[0] + "'");
            return list_plugins();
        }
        if (cmd == "check-shift") return check_shift(rest);
        if (cmd == "reconstruct") return reconstruct(rest);
        if (cmd == "compare") return compare(rest);
        if (cmd == "video") return video(rest);
        throw ParameterError("unknown command '" + cmd + "'\n" + usage());
    };
    const int rc = dispatch();
    // A stop signal that came while a file was being finished: the file is
    // complete, the status still says the command was stopped.
    return stop_status() ? stop_status() : rc;
}

}  // namespace gdr::cli
