#!/usr/bin/env bash
# Installs the Debian packages gdr builds against, but only those missing
# (apt-get update runs once, and only if something is missing). Uses sudo
# when not root. Shared by scripts/setup.sh and .ci/run.
set -euo pipefail
packages=(cmake g++ make pkg-config libembree-dev libglm-dev libopenexr-dev libtinyobjloader-dev catch2 libfmt-dev
          libtbb-dev libfftw3-dev nlohmann-json3-dev libstb-dev libpugixml-dev)
missing=()
for p in "${packages[@]}"; do
    # Installed means "install ok installed"; a removed package can leave its status entry behind.
    dpkg -s "$p" 2>/dev/null | grep -q '^Status: install ok installed' || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
    echo "install-deps: all build dependencies are installed"
    exit 0
fi
echo "install-deps: installing ${missing[*]}"
sudo=()
[[ $(id -u) -eq 0 ]] || sudo=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update
"${sudo[@]}" apt-get install -y --no-install-recommends "${missing[@]}" </dev/null
