#!/usr/bin/env bash
# Installs the Debian packages gdr builds against, but only those missing
# (apt-get update runs once, and only if something is missing). Uses sudo
# when not root. Shared by scripts/setup.sh and .ci/run.
#
# Optional parts: slurm-wlm and munge, for the test of gdr submit on a real
# Slurm cluster (tests/slurm.sh starts its own daemons; without the packages
# it is skipped). They are installed without starting any service (a
# policy-rc.d denies it for the duration of the install) and their services
# are left disabled, so the machine runs no Slurm or munge daemon afterwards.
# And python3-dev, pybind11-dev, python3-numpy and python3-matplotlib, for the
# Python module and its example (without them the module is not built and its
# tests are reported as skipped); python3-venv, python3-setuptools,
# python3-wheel and python3-build, for `pip install .` and `python3 -m build`
# of the package offline (the test of them is skipped without them);
# python3-tqdm, which draws the module's progress=True bar; ccache,
# which a package build that configures its own CMake tree compiles through,
# so that a second build of the same sources costs little; and libtorch-dev, for the optional neural
# reconstructor (CMake skips that target without it). And ffmpeg, for gdr video's
# MP4 output (without it gdr video writes the PNG sequence, and its MP4 test is
# skipped).
# Failing to install any of these groups is reported and stops nothing;
# GDR_SKIP_OPTIONAL=1 leaves them all out.
set -euo pipefail
packages=(cmake g++ make pkg-config libembree-dev libglm-dev libopenexr-dev libtinyobjloader-dev catch2 libfmt-dev
          libtbb-dev libfftw3-dev nlohmann-json3-dev libstb-dev libpugixml-dev zlib1g-dev)
optional=(slurm-wlm munge)
optional_python=(python3-dev pybind11-dev python3-numpy python3-matplotlib python3-venv python3-setuptools python3-wheel
                 python3-build python3-tqdm ccache)
optional_neural=(libtorch-dev)
optional_video=(ffmpeg)
installed() {
    # Installed means "install ok installed"; a removed package can leave its status entry behind.
    dpkg -s "$1" 2>/dev/null | grep -q '^Status: install ok installed'
}
missing=() missing_optional=() missing_python=() missing_neural=() missing_video=()
for p in "${packages[@]}"; do installed "$p" || missing+=("$p"); done
if [[ ${GDR_SKIP_OPTIONAL:-0} != 1 ]]; then
    for p in "${optional[@]}"; do installed "$p" || missing_optional+=("$p"); done
    for p in "${optional_python[@]}"; do installed "$p" || missing_python+=("$p"); done
    for p in "${optional_neural[@]}"; do installed "$p" || missing_neural+=("$p"); done
    for p in "${optional_video[@]}"; do installed "$p" || missing_video+=("$p"); done
fi
if ((${#missing[@]} == 0 && ${#missing_optional[@]} == 0 && ${#missing_python[@]} == 0 && ${#missing_neural[@]} == 0 &&
      ${#missing_video[@]} == 0)); then
    echo "install-deps: all build dependencies are installed"
    exit 0
fi
sudo=()
[[ $(id -u) -eq 0 ]] || sudo=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update
if ((${#missing[@]} > 0)); then
    echo "install-deps: installing ${missing[*]}"
    "${sudo[@]}" apt-get install -y --no-install-recommends "${missing[@]}" </dev/null
fi
if ((${#missing_python[@]} > 0)); then
    echo "install-deps: installing the optional ${missing_python[*]} (for the Python module)"
    "${sudo[@]}" apt-get install -y --no-install-recommends "${missing_python[@]}" </dev/null ||
        echo "install-deps: warning: could not install ${missing_python[*]}; the Python module and its tests will be skipped" >&2
fi
if ((${#missing_neural[@]} > 0)); then
    echo "install-deps: installing the optional ${missing_neural[*]} (for the neural reconstructor)"
    "${sudo[@]}" apt-get install -y --no-install-recommends "${missing_neural[@]}" </dev/null ||
        echo "install-deps: warning: could not install ${missing_neural[*]}; the neural reconstructor will be skipped" >&2
fi
if ((${#missing_video[@]} > 0)); then
    echo "install-deps: installing the optional ${missing_video[*]} (for gdr video's MP4 output)"
    "${sudo[@]}" apt-get install -y --no-install-recommends "${missing_video[@]}" </dev/null ||
        echo "install-deps: warning: could not install ${missing_video[*]}; gdr video will write PNG sequences only" >&2
fi
((${#missing_optional[@]} > 0)) || exit 0

# The optional parts, with services denied: invoke-rc.d and deb-systemd-invoke
# ask /usr/sbin/policy-rc.d, and exit status 101 means "do not start". An
# existing policy is put back afterwards.
policy=/usr/sbin/policy-rc.d
saved=""
restore_policy() {
    if [[ -n $saved ]]; then "${sudo[@]}" mv -f "$saved" "$policy"; else "${sudo[@]}" rm -f "$policy"; fi
}
if [[ -e $policy ]]; then
    saved=$policy.gdr-saved
    "${sudo[@]}" mv -f "$policy" "$saved"
fi
trap restore_policy EXIT
printf '#!/bin/sh\n# Written by gdr scripts/install-deps.sh while it installs packages: start no service.\nexit 101\n' |
    "${sudo[@]}" tee "$policy" > /dev/null
"${sudo[@]}" chmod 755 "$policy"
echo "install-deps: installing the optional ${missing_optional[*]} (for the Slurm test; no service is started)"
if "${sudo[@]}" apt-get install -y --no-install-recommends "${missing_optional[@]}" </dev/null; then
    # Installing enabled their services for the next boot: gdr's test starts its own daemons.
    # (systemctl disables them, sysv links too, also where systemd is not running.)
    if command -v systemctl > /dev/null; then
        "${sudo[@]}" systemctl disable --quiet slurmctld.service slurmd.service munge.service 2>/dev/null || true
    fi
else
    echo "install-deps: warning: could not install ${missing_optional[*]}; the Slurm test will be skipped" >&2
fi
