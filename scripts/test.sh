#!/usr/bin/env bash
# The project's test command, used by the README and by CI: configure a
# Release build in ./build, build everything on 2 cores, run every test
# (unit, statistical, examples, and the install + find_package consumer).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release && cmake --build build -j2 && ctest --test-dir build --output-on-failure
