#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a gradient-domain render:
# installs the missing packages, builds gdr (Release, ./build), and renders the
# bundled Cornell box with gradient-domain path tracing into out/cornell-box.exr
# (all layers) and out/cornell-box.png (the L1 reconstruction).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)" --target gdr_cli
mkdir -p out
./build/bin/gdr render scenes/cornell-box/scene.json --integrator gpt --spp 32 -o out/cornell-box.exr
