#!/bin/bash
# The data sets of unet-v4 (neural/README.md, "The shipped model"): training views of the
# public Mitsuba 0.6 scenes and of the bundled scenes, and validation views of
# two interiors that no training view or variant shows (living-room,
# dining-room) and of veach-bidir.
#
#   neural/data/make-data-v4.sh OUT_DIR [THREADS]
#
# OUT_DIR gets train/<family>/ and val/<scene>/, one crop-NNNNN.exr per view.
# Every step keeps the views it finds, so the script can be stopped at any
# time (or run under `timeout 2h`) and run again to continue; the files depend
# only on these options. A scene file that does not load is named and its
# views are left out: run the script again once it loads to add them.
#
# Needs: gdr_train (build/bin), the Mitsuba scenes in $GDR_SCENES/mitsuba
# (default ../shared/scenes beside the repository) and the bundled scenes.
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:?usage: make-data-v4.sh OUT_DIR [THREADS]}
threads=${2:-2}
W=${GDR_TRAIN:-$here/build/bin/gdr_train}
export GDR_SCENES=${GDR_SCENES:-$here/../shared/scenes}
M=$GDR_SCENES/mitsuba
S=$here/scenes/cornell-box

# Noise levels and targets. Training: 64x64 views at 4-256 spp against 1024
# spp; validation: 80x80 views against 2048 spp of gpt (a view of the living
# room takes about 2 minutes on two cores). veach-bidir's targets are bdpt's
# (1024 spp, about gpt's 4096 in time): there, at equal time, the
# variance of bdpt's image is about 20 times below that of gpt's primal, whose
# caustics through the lamp's glass leave fireflies at any sample count.
train=(--size 64 --spp 4,16,64,256 --target-spp 1024 --threads "$threads")
val=(--size 80 --spp 4,16,64,256 --target-spp 2048 --threads "$threads")

# A family's scene files: its scene.xml (if any) and its randomised variants
# 0..N-1, comma-separated.
family() {
    local dir=$M/$1 n=$2 list=""
    [ -f "$dir/scene.xml" ] && list=$dir/scene.xml
    for ((k = 0; k < n; ++k)); do
        f=$dir/$1_rand_scene$k.xml
        [ -f "$f" ] && list=${list:+$list,}$f
    done
    echo "$list"
}

# Validation first: it is small and every later measurement needs it.
$W data --out "$out/val/living-room" --scenes "$(family living-room 5)" --crops 8 --roam --lenient --seed 2001 "${val[@]}"
$W data --out "$out/val/dining-room" --scenes "$(family dining-room 5)" --crops 8 --roam --lenient --seed 2002 "${val[@]}"
$W data --out "$out/val/veach-bidir" --scenes "$here/scenes/veach-bidir/scene.json" --crops 8 --seed 2003 "${val[@]}" \
    --target-integrator bdpt --target-spp 1024

# Training: the Mitsuba families (views from anywhere in each scene).
seed=101
for fam in box:5 classroom:5 sponza:5 torus:5 veach-lamp:5 water:5 spaceship:5 cbox-caustics:20; do
    name=${fam%%:*}
    $W data --out "$out/train/$name" --scenes "$(family "$name" "${fam##*:}")" --crops 16 --roam --lenient --seed $seed "${train[@]}"
    seed=$((seed + 1))
done
# The bundled scenes, recoloured (odd views) and with the shared meshes
# standing in them (views 2 and 3 of every 4).
$W data --out "$out/train/bundled" --crops 48 --vary --seed 1 "${train[@]}" \
    --meshes "$here/scenes/meshes/spot-cow/spot_triangulated.obj,$GDR_SCENES/meshes/utah-teapot/teapot.obj" \
    --scenes $S/scene.json,$S/glossy.json,$S/sphere.json,$S/mirror.json,$here/scenes/veach-mis/scene.json,$S/water.json,$here/scenes/bathroom/scene.json,$S/glossy-floor.json,$here/scenes/cornell-box-cc0/scene.json,$S/empty-rg.json
