#!/usr/bin/env bash
# The project's test command, used by the README and by CI: configure a
# Release build in ./build, build everything on 2 cores, run every test
# (unit, statistical, examples, and the install + find_package consumer),
# and check that a clone works on its own (scripts/clone-check.sh).
# Then the same suite on the portable scalar build in ./build-scalar
# (GDR_SIMD=OFF, what processors other than x86-64 get), without the
# benchmarks and without the neural reconstructor (it uses no SIMD code of
# gdr's, and compiling against libtorch twice would double its cost), so the
# scalar build also checks that gdr builds and tests without it. The Slurm
# test (tests/slurm.sh) runs where slurm-wlm and munge are installed and the
# user is root, and is reported as skipped elsewhere; so are the Python
# module's tests (tests/python) where the module is not built. Among those,
# python.pip_install installs the package with pip into a fresh virtual
# environment (reusing the module just built, so it compiles nothing) and
# runs the Python suite against the installed package.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
# What the suite will skip, said up front (ctest's summary lists it again at
# the end): the test of gdr submit on a real Slurm cluster needs slurm-wlm
# and munge (installed by scripts/install-deps.sh) and root.
skipped() {
    local p
    for p in munged mungekey slurmctld slurmd sbatch squeue scancel sinfo; do
        if ! PATH="$PATH:/usr/sbin:/sbin" command -v "$p" > /dev/null; then
            echo "test.sh: $p is not installed, so the Slurm test (cli.slurm_array_job_renders_merges_and_resumes) is skipped; scripts/install-deps.sh installs slurm-wlm and munge"
            return
        fi
    done
    [[ $(id -u) -eq 0 ]] ||
        echo "test.sh: not root, so the Slurm test (cli.slurm_array_job_renders_merges_and_resumes) is skipped: it starts slurmd"
}
skipped
# Through ccache where it is installed (scripts/install-deps.sh installs it),
# with paths made relative to the repository: the clone that
# scripts/clone-check.sh builds then reuses this build's objects instead of
# compiling the library a second time.
launcher=()
if command -v ccache > /dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
    export CCACHE_BASEDIR=$PWD CCACHE_NOHASHDIR=1
fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "${launcher[@]}"
cmake --build build -j2
ctest --test-dir build --output-on-failure
# A clone with nothing beside it renders every scene in scenes/ and skips the
# tests of the larger public scenes (GDR_SCENES).
bash scripts/clone-check.sh build
cmake -S . -B build-scalar -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" -DGDR_SIMD=OFF -DGDR_BUILD_BENCHMARKS=OFF -DGDR_BUILD_NEURAL=OFF
cmake --build build-scalar -j2
ctest --test-dir build-scalar --output-on-failure
