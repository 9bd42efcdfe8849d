#!/bin/sh
# Renders (or finds cached) high-sample PT references for the equal-time
# benchmark scenes. References live outside git, by default in
# $HOME/.cache/gdr-references (override with GDR_REFERENCE_CACHE or --cache DIR),
# named <scene>-<W>x<H>-spp<N>-<hash of scene file and geometry>.exr, and are
# re-rendered only when missing (or with --refresh-references).
#
# Usage: scripts/references.sh [--quick] [extra bench_equal_time options]
#   BUILD_DIR=build-eval scripts/references.sh          # full-mode references
#   scripts/references.sh --quick                        # the CI ones
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD_DIR=${BUILD_DIR:-$ROOT/build}
case $BUILD_DIR in /*) ;; *) BUILD_DIR=$ROOT/$BUILD_DIR ;; esac
if [ ! -x "$BUILD_DIR/bin/bench_equal_time" ] && [ ! -x "$BUILD_DIR/benchmarks/bench_equal_time" ]; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$BUILD_DIR" --target bench_equal_time -j"$(nproc)"
BIN=$BUILD_DIR/bin/bench_equal_time
[ -x "$BIN" ] || BIN=$BUILD_DIR/benchmarks/bench_equal_time
exec "$BIN" --references-only "$@"
