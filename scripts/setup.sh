#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a gradient-domain render:
# installs the missing packages, builds gdr and its Python module (Release,
# ./build), and renders the bundled Cornell box with gradient-domain path
# tracing into out/cornell-box.exr (all layers) and out/cornell-box.png (the L1
# reconstruction).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)" --target gdr_cli
# The Python module, where CMake found what it needs (it says so otherwise).
if grep -q "/gdr_python.dir$" build/CMakeFiles/TargetDirectories.txt 2>/dev/null; then
    cmake --build build -j"$(nproc)" --target gdr_python
    python=$(sed -n 's/^Python3_EXECUTABLE:[A-Z]*=//p' build/CMakeCache.txt)
    echo "setup: the Python module is in build/python, for $python: PYTHONPATH=build/python $python -c 'import gdr'"
fi
mkdir -p out
./build/bin/gdr render scenes/cornell-box/scene.json --integrator gpt --spp 32 -o out/cornell-box.exr
