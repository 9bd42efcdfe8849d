#!/usr/bin/env bash
# Paired CPU-time comparison of two gdr binaries on one render.
#
#   benchmarks/ab.sh OLD_GDR NEW_GDR ROUNDS SCENE.json [render options...]
#
# Each round runs both binaries at the same time, one per core, each on one
# thread (--threads 1 is added), alternating which starts first, and prints
# new/old of their CPU times (user + system). Running the pair together gives
# both the same machine conditions, which on a shared machine move more
# between rounds than a small code change does; the median of the per-round
# ratios is the figure to quote. Both must write bit-identical images for the
# comparison to time the same work: EXR and PNG compression time depends on
# the pixels (compare them with `gdr compare` first).
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n '2,4p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
fi
old=$1 new=$2 rounds=$3 scene=$4
shift 4
for b in "$old" "$new"; do [ -x "$b" ] || { echo "ab.sh: $b is not an executable" >&2; exit 2; }; done
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "ab.sh: ROUNDS must be a positive integer, got '$rounds'" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

run() {  # binary, tag, render options...
    local bin=$1 tag=$2
    shift 2
    /usr/bin/time -f "%U %S" -o "$work/$tag.time" "$bin" render "$scene" "$@" --threads 1 -o "$work/$tag.exr" \
        >/dev/null 2>"$work/$tag.log" || { echo "ab.sh: $bin failed:" >&2; tail -3 "$work/$tag.log" >&2; exit 1; }
}
seconds() { awk '{print $1 + $2}' "$work/$1.time"; }

ratios=()
for i in $(seq "$rounds"); do
    if (( i % 2 )); then
        run "$old" old "$@" & sleep 0.05; run "$new" new "$@"; wait
    else
        run "$new" new "$@" & sleep 0.05; run "$old" old "$@"; wait
    fi
    r=$(awk -v a="$(seconds old)" -v b="$(seconds new)" 'BEGIN {printf "%.4f", b / a}')
    ratios+=("$r")
    echo "round $i: old $(seconds old) s, new $(seconds new) s CPU, new/old $r"
done
printf '%s\n' "${ratios[@]}" | sort -g | awk '{v[NR] = $1} END {
    m = NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
    printf "median new/old CPU time over %d rounds: %.4f\n", NR, m }'
