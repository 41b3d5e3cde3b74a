#!/usr/bin/env bash
# The rgb mode's depth net on every real train frame (models/real_splits.json) and the synthetic
# set, the checkpoint chosen on the val frames, exported to ONNX and measured on the test frames.
# The same command on a GPU (DEVICE=auto finds it) and on the CPU, only slower. Run from the
# repository root with the training venv active (pip install -r models/training/requirements.txt).
#
#   MINUTES    wall-clock budget of the depth training (default 100)
#   DEVICE     auto (CUDA where PyTorch sees it, else the CPU), cpu, cuda
#   THREADS    PyTorch's CPU threads (default 2)
#   BATCH      crops per batch (default 12; more on a GPU)
#   INIT       start from this checkpoint (default: the committed model; a run's depth_last.pt to
#              go on from where a run stopped)
#   VAL_EVERY  seconds between validations (default 300)
#   PY         the Python with PyTorch (default python3)
#   DATA       the synthetic set (default data/sensor256; made by tre synth when missing)
#   RUN        where the run's checkpoint, curve and log are copied (default: runs/depth-DATE
#              beside this script)
#
# The test split is read only after training, by eval_real.
# Every validation writes checkpoints/depth.pt (best so far), depth_last.pt and
# depth_progress.json (the curve), so a run cut short leaves what it reached;
# `touch models/training/checkpoints/depth.stop` ends it early (a last validation, the log).
# Edit this file only while no run of it is going on: bash reads it as it goes.
set -euo pipefail
MINUTES=${MINUTES:-100}
DEVICE=${DEVICE:-auto}
THREADS=${THREADS:-2}
BATCH=${BATCH:-12}
VAL_EVERY=${VAL_EVERY:-300}
PY=${PY:-python3}
DATA=${DATA:-data/sensor256}
RUN=${RUN:-models/training/runs/depth-$(date +%F)}
TRE=${TRE:-target/release/tre}
if [ ! -f "$DATA/dataset.json" ]; then
  "$TRE" synth --out "$DATA" --scenes 200 --seed 2031 --width 256 \
    --random-optics --no-ply --content mixed \
    --sensor kinect_v1,realsense_d435,azure_kinect,lidar,exact \
    --effects exposure,white_balance,vignetting,defocus,motion_blur,noise,jpeg --resume
fi
mkdir -p "$RUN"
RUN=$(cd "$RUN" && pwd)
D=$(cd "$DATA" && pwd)
cd models/training
[ -f checkpoints/depth_committed.pt ] || "$PY" -m tre_training.from_onnx
[ -f ../../data/real256/train.npz ] || "$PY" -m tre_training.real train
[ -f ../../data/real256/val.npz ] || "$PY" -m tre_training.real val
init=()
[ -n "${INIT:-}" ] && init=(--init "$INIT")
"$PY" -m tre_training.train_real depth --data "$D" --minutes "$MINUTES" --lr 2e-4 \
  --val-every "$VAL_EVERY" --batch "$BATCH" --device "$DEVICE" --threads "$THREADS" --seed 2027 \
  "${init[@]}" 2>&1 | tee "$RUN/train.log"
cp checkpoints/depth.pt checkpoints/depth.json checkpoints/depth_progress.json "$RUN/"
cp checkpoints/depth_last.pt "$RUN/"
# The test figures of the committed net, then the chosen checkpoint exported over it (the one
# with the best val score: the committed net itself when no step beat it) and measured again.
"$PY" -m tre_training.eval_real --split test | tee "$RUN/eval_test_before.txt"
"$PY" -m tre_training.export --data "$D" --nets depth_net
"$PY" -m tre_training.eval_real --split test | tee "$RUN/eval_test_after.txt"
