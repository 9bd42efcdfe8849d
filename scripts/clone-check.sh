#!/usr/bin/env bash
# A clone of the repository works on its own. Clones the committed HEAD into a
# temporary folder with nothing beside it (no ../shared), configures it,
# builds the gdr tool there, renders every scene file in scenes/ at 16x16 and
# 1 spp, checks that the one scene that needs the larger public scenes
# (scenes/bathroom) stops with a message naming GDR_SCENES, and that the
# tests needing them are reported as skipped by ctest when GDR_SCENES names
# an empty place.
#
# Usage: scripts/clone-check.sh [BUILD_DIR]   (default ./build: its ctest)
# The clone's build uses ccache where installed (CCACHE_BASEDIR makes its
# paths relative, so that one run's objects serve the next); without ccache
# it renders with BUILD_DIR/bin/gdr instead of compiling gdr a second time.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
root=$PWD
build=${1:-build}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/gdr-clone.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
git clone --quiet --no-hardlinks "$root" "$tmp/gdr"
# Nothing beside the clone, and no GDR_SCENES from the caller's environment.
[[ ! -e "$tmp/shared" ]]
unset GDR_SCENES
launcher=()
if command -v ccache > /dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
    export CCACHE_BASEDIR=$tmp CCACHE_NOHASHDIR=1
fi
cmake -S "$tmp/gdr" -B "$tmp/gdr/build" -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" \
    -DGDR_BUILD_TESTS=OFF -DGDR_BUILD_BENCHMARKS=OFF -DGDR_BUILD_NEURAL=OFF > "$tmp/configure.log" ||
    { cat "$tmp/configure.log"; exit 1; }
if [[ ${#launcher[@]} -gt 0 ]]; then
    cmake --build "$tmp/gdr/build" -j2 --target gdr_cli > "$tmp/build.log" || { tail -50 "$tmp/build.log"; exit 1; }
    gdr=$tmp/gdr/build/bin/gdr
else
    echo "clone-check: ccache is not installed; rendering with $build/bin/gdr instead of building the clone"
    gdr=$root/$build/bin/gdr
    export GDR_SCENES=$tmp/shared/scenes  # what the clone's own build would default to
fi
cd "$tmp/gdr"
n=0
for scene in scenes/*/*.json scenes/*/original-mitsuba-scene.xml; do
    [[ $(basename "$scene") == camera.json ]] && continue  # a camera read by a scene file, not a scene
    # veach-bidir's original Mitsuba file is kept as the source of its
    # conversion; its meshes are in GDR_SCENES (mitsuba/veach-bidir/models).
    if [[ $scene == *.xml ]] && grep -q 'value="models/' "$scene"; then
        echo "clone-check: $scene names meshes of GDR_SCENES (models/), not rendered"
        continue
    fi
    if [[ $scene == scenes/bathroom/* ]]; then
        if "$gdr" render "$scene" --resolution 16x16 --spp 1 -o "$tmp/out.exr" 2> "$tmp/err.txt"; then
            echo "clone-check: $scene rendered without the public scenes beside the clone" >&2; exit 1
        fi
        grep -q "GDR_SCENES" "$tmp/err.txt" ||
            { echo "clone-check: $scene failed without naming GDR_SCENES:" >&2; cat "$tmp/err.txt" >&2; exit 1; }
        continue
    fi
    "$gdr" render "$scene" --resolution 16x16 --spp 1 -o "$tmp/out.exr" > "$tmp/render.log" 2>&1 ||
        { echo "clone-check: $scene does not render from a clone:" >&2; cat "$tmp/render.log" >&2; exit 1; }
    n=$((n + 1))
done
echo "clone-check: $n scene files of a clone rendered; scenes/bathroom names GDR_SCENES"
# The tests of the public scenes: skipped, not failed, where they are absent.
cd "$root"
GDR_SCENES=$tmp/shared/scenes ctest --test-dir "$build" -R "published scenes load" > "$tmp/ctest.log" 2>&1 ||
    { cat "$tmp/ctest.log"; exit 1; }
grep -q "Skipped" "$tmp/ctest.log" || { cat "$tmp/ctest.log"; echo "clone-check: the public-scene test was not skipped" >&2; exit 1; }
echo "clone-check: the tests of the public scenes are reported as skipped without GDR_SCENES"
