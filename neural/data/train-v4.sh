#!/bin/bash
# Trains unet-v4 and its primal-only twin on the data of make-data-v4.sh, side
# by side with one thread each (neural/README.md, "The shipped model").
#
#   neural/data/train-v4.sh DATA_DIR RUN_DIR [STEPS]
#
# unet-v4 reads and corrects poisson-weighted's reconstruction (the default
# final image) where unet-v2 corrected poisson-l1's. Both runs start from the
# previous shipped pair (unet-v2 and unet-v2-primal, fine-tuning: the same
# shapes, trained on the bundled scenes) and take the same steps, seed and
# augmentation, so the twin has the same data and budget. Each
# writes its checkpoint every 500 steps: stop the script at any time (or run it
# under `timeout 2h`) and run it again to continue exactly where it was; a
# larger STEPS continues a finished run.
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
data=${1:?usage: train-v4.sh DATA_DIR RUN_DIR [STEPS]}
run=${2:?usage: train-v4.sh DATA_DIR RUN_DIR [STEPS]}
steps=${3:-12000}
W=${GDR_TRAIN:-$here/build/bin/gdr_train}
models=$here/neural/models
mkdir -p "$run"
export OMP_WAIT_POLICY=PASSIVE
common=(--data "$data/train" --validation "$data/val" --steps "$steps" --every 500 --threads 1 --seed 4 --augment)
$W train "${common[@]}" --poisson-weighted --init "$models/unet-v2.pt" \
    --checkpoint "$run/v4.ckpt" --weights "$run/unet-v4.pt" > "$run/v4.log" 2>&1 &
gradients=$!
$W train "${common[@]}" --primal-only --init "$models/unet-v2-primal.pt" \
    --checkpoint "$run/v4p.ckpt" --weights "$run/unet-v4-primal.pt" > "$run/v4p.log" 2>&1 &
primal=$!
status=0
wait $gradients || status=$?
wait $primal || status=$?
exit $status
