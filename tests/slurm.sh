#!/usr/bin/env bash
# gdr submit against a real single-node Slurm cluster started here, on
# localhost, without systemd: munged, slurmctld -D and slurmd -D with a
# slurm.conf and a munge key in a temporary folder (whose outputs sit under a
# name with a space, so the scripts' quoting is exercised by sbatch and bash).
#   1. a 4-part render is submitted, runs, and is merged by the dependent job;
#      the merge equals a local gdr merge of the same part files bit for bit;
#   2. a re-run of a task whose part is complete leaves the part as it was;
#   3. one task killed mid-render (scancel: SIGTERM) leaves a partial part and
#      no merge; gdr submit --resume renders only that part on and merges, and
#      the image equals the uninterrupted one to within float rounding.
# The cluster is scripts/local-slurm.sh's; the test stops only the daemons it
# started, by their pids, and removes its folder, also on failure. Exit status
# 77 (ctest: skipped) when Slurm or munge is not installed, or when not run as
# root (slurmd runs jobs as their user).
#   tests/slurm.sh GDR_BINARY SCENE.json
set -u
gdr=$1 scene=$2
export PATH="$PATH:/usr/sbin:/sbin"
spp=8000  # per part: seconds on one thread, so that a task can be stopped mid-render
# A resumed part against an uninterrupted one: float rounding. Each pixel's
# running mean rounds once per sample in single precision, so a mean of n
# samples is within about sqrt(n) float roundings of the exact one, and where
# the part was stopped changes which roundings happen: measured up to 1.1e-5
# at 8000 spp (albedo at edges), against 1.4e-7 with double sums.
tolerance=1e-4

skip() { echo "SKIPPED: $*"; exit 77; }
source "$(dirname "${BASH_SOURCE[0]}")/../scripts/local-slurm.sh"
missing=$(local_slurm_missing)
[ -z "$missing" ] || skip "$missing not found (Debian packages slurm-wlm and munge; scripts/install-deps.sh installs them)"
[ "$(id -u)" = 0 ] || skip "needs root to run slurmd"

work=$(mktemp -d /tmp/gdr-slurm.XXXXXX)
out="$work/out dir"
passed=0
trap 'local_slurm_stop "$work"' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$work"/log/*.log "$out"/*.parts/logs/*.log; do
        [ -f "$f" ] && { echo "--- $f"; tail -n 15 "$f"; }
    done
    exit 1
}
pass() { echo "ok: $*"; passed=$((passed + 1)); }

# --- the cluster: the daemons are this script's children, stopped by the trap
local_slurm_start "$work" || fail "the local Slurm cluster did not start"
mkdir -p "$out"
echo "slurm: node $(hostname -s) up, daemons $(tr '\n' ' ' < "$work/pids")"

# --- helpers
wait_for_queue() {
    for _ in $(seq 720); do [ -z "$(squeue -h -o %i)" ] && return 0; sleep 0.25; done
    fail "jobs still queued after 180 s: $(squeue)"
}
# Submits a 4-part render to $1; sets render_id and merge_id. batch=1 traces
# each ray alone: in a packet, Embree breaks an exact tie between two triangles
# at one distance by its traversal order, which depends on the other rays of
# the packet, and a resumed part packs its samples differently (about one
# sample in 10^7 on the Cornell box); that is not what this test is about.
submit() {
    "$gdr" submit "$scene" --parts 4 --spp "$spp" --threads 1 --set batch=1 -o "$1" > "$work/submit.out" 2>&1 ||
        fail "gdr submit: $(cat "$work/submit.out")"
    render_id=$(awk '$1 == "render" && $2 == "job" {sub(":", "", $3); print $3}' "$work/submit.out")
    merge_id=$(awk '$1 == "merge" && $2 == "job" {sub(":", "", $3); print $3}' "$work/submit.out")
    [ -n "$render_id" ] && [ -n "$merge_id" ] || fail "gdr submit printed no job ids: $(cat "$work/submit.out")"
}
layers() { "$gdr" info "$1" | awk '/^layers:/ {on = 1; next} /^settings:/ {on = 0} on {print $1}'; }
setting() { "$gdr" info "$1" | awk -v k="$2" '$1 == k && $2 == "=" {print $3}'; }
# Every layer of $1 equals $2's bit for bit.
same_bits() {
    local layer
    for layer in $(layers "$1"); do
        "$gdr" compare "$1" "$2" --layer "$layer" > "$work/cmp" || fail "gdr compare $1 $2 --layer $layer"
        grep -q "^differences: *0 of" "$work/cmp" || fail "layer $layer of $1 differs from $2: $(grep differences "$work/cmp")"
    done
}
# Every layer of $1 equals $2's to a relative $3 (over values that are not 0).
close_to() {
    local layer rel
    for layer in $(layers "$1"); do
        "$gdr" compare "$1" "$2" --layer "$layer" > "$work/cmp" || fail "gdr compare $1 $2 --layer $layer"
        rel=$(sed -n 's/.*max |x-r|\/|r| \([^ ]*\).*/\1/p' "$work/cmp")
        awk -v r="$rel" -v t="$3" 'BEGIN { exit !(r <= t) }' ||
            fail "layer $layer of $1 differs from $2 by a relative $rel (more than $3)"
        echo "  layer $layer: max relative difference $rel"
    done
}

# --- 1. four parts, merged by the dependent job
clean="$out/clean box.exr"
submit "$clean"
wait_for_queue
[ -f "$clean" ] || fail "the merge job wrote no $clean"
"$gdr" status "$clean" > "$work/status" || fail "gdr status"
grep -q "^parts: 4 complete" "$work/status" && grep -q "^merged: yes" "$work/status" ||
    fail "gdr status after the run: $(cat "$work/status")"
[ "$(setting "$clean" sample_ranges)" = "0:0:$((4 * spp))" ] || fail "merged sample_ranges $(setting "$clean" sample_ranges)"
parts=()
for i in 0 1 2 3; do parts+=("$out/clean box.parts/part-$i.exr"); done
"$gdr" merge "${parts[@]}" -o "$work/local.exr" > /dev/null 2>&1 || fail "local gdr merge"
same_bits "$clean" "$work/local.exr"
pass "4 parts rendered by array job $render_id and merged by job $merge_id; equal to a local merge bit for bit"

# --- 2. a task whose part is complete does nothing
cp "${parts[1]}" "$work/part-1.before"
sbatch --array=1 "$out/clean box.parts/render.sbatch" > /dev/null || fail "sbatch of task 1 again"
wait_for_queue
cmp -s "${parts[1]}" "$work/part-1.before" || fail "a re-run of task 1 changed its complete part"
grep -q "nothing to render" "$out/clean box.parts/logs/part-1.log" || fail "the re-run of task 1 did not say it had nothing to do"
"$gdr" submit --resume "$clean" | grep -q "merged already" || fail "gdr submit --resume of a merged render"
pass "a re-run of a complete task leaves its part as it was; --resume of a merged render submits nothing"

# --- 3. one task stopped mid-render, then resubmitted
killed="$out/killed box.exr"
submit "$killed"
log2="$out/killed box.parts/logs/part-2.log"
for _ in $(seq 720); do grep -q "^progress" "$log2" 2>/dev/null && break; sleep 0.25; done
grep -q "^progress" "$log2" || fail "task 2 did not start"
scancel "${render_id}_2" || fail "scancel ${render_id}_2"
wait_for_queue
part2="$out/killed box.parts/part-2.exr"
[ -f "$part2" ] || fail "the stopped task 2 wrote no partial part"
held=$(setting "$part2" spp)
[ "$(setting "$part2" interrupted)" = true ] && [ "$held" -lt "$spp" ] ||
    fail "part 2 is not partial (spp $held, interrupted $(setting "$part2" interrupted)): the stop came too late"
[ -e "$killed" ] && fail "the merge ran although part 2 had failed"
"$gdr" status "$killed" > "$work/status"
grep -q "^parts: 3 complete, 1 partial" "$work/status" || fail "gdr status after the stop: $(cat "$work/status")"
grep -q "gdr submit --resume" "$work/status" || fail "gdr status does not say to resubmit: $(cat "$work/status")"
pass "task 2 stopped by scancel after $held of $spp spp: a partial part, no merge"

"$gdr" submit --resume "$killed" > "$work/resume.out" 2>&1 || fail "gdr submit --resume: $(cat "$work/resume.out")"
grep -q "array tasks 2 " "$work/resume.out" || fail "--resume did not resubmit part 2 alone: $(cat "$work/resume.out")"
wait_for_queue
[ -f "$killed" ] || fail "no merged image after --resume"
grep -q "^merged: yes" <("$gdr" status "$killed") || fail "gdr status after --resume"
[ "$(setting "$part2" spp)" = "$spp" ] || fail "part 2 holds $(setting "$part2" spp) spp after --resume"
[ "$(setting "$killed" sample_ranges)" = "0:0:$((4 * spp))" ] || fail "merged sample_ranges $(setting "$killed" sample_ranges)"
kparts=()
for i in 0 1 2 3; do kparts+=("$out/killed box.parts/part-$i.exr"); done
"$gdr" merge "${kparts[@]}" -o "$work/local-killed.exr" > /dev/null 2>&1 || fail "local gdr merge"
same_bits "$killed" "$work/local-killed.exr"
for i in 0 1 3; do same_bits "${kparts[i]}" "${parts[i]}"; done  # the parts that ran through
close_to "$killed" "$clean" "$tolerance"
pass "--resume rendered part 2 on from sample $((2 * spp + held)) and merged: the image of the uninterrupted run to within $tolerance"

echo "$passed passed, 0 failed"
