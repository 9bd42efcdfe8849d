#!/usr/bin/env bash
# The project's test command, used by the README and by CI: configure a
# Release build in ./build, build everything on 2 cores, run every test
# (unit, statistical, examples, and the install + find_package consumer).
# Then the same suite on the portable scalar build in ./build-scalar
# (GDR_SIMD=OFF, what processors other than x86-64 get), without the
# benchmarks.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j2
ctest --test-dir build --output-on-failure
cmake -S . -B build-scalar -DCMAKE_BUILD_TYPE=Release -DGDR_SIMD=OFF -DGDR_BUILD_BENCHMARKS=OFF
cmake --build build-scalar -j2
ctest --test-dir build-scalar --output-on-failure
