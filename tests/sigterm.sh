#!/usr/bin/env bash
# A render stopped by SIGTERM, as a batch scheduler stops a job, still writes
# the samples it took: exit status 143, an EXR marked interrupted=true.
#   tests/sigterm.sh GDR_BINARY SCENE.json
set -u
gdr=$1 scene=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$gdr" render "$scene" --spp 1000000 --threads 1 -o "$work/out.exr" 2>"$work/log" &
pid=$!
# The handler is installed once the scene is loaded (its summary line is printed first).
for _ in $(seq 400); do grep -q "^scene " "$work/log" && break; sleep 0.05; done
sleep 0.5
kill -TERM "$pid"
wait "$pid"
rc=$?
[ "$rc" = 143 ] || { echo "exit status $rc, expected 143"; cat "$work/log"; exit 1; }
"$gdr" info "$work/out.exr" | grep -q "interrupted *= true" || { echo "the EXR is not marked interrupted"; exit 1; }
spp=$("$gdr" info "$work/out.exr" | awk '$1 == "spp" && $2 == "=" {print $3}')
{ [ -n "$spp" ] && [ "$spp" -ge 1 ] && [ "$spp" -lt 1000000 ]; } || { echo "unexpected spp '$spp'"; exit 1; }
echo "stopped by SIGTERM after $spp spp: exit status 143, image written"
