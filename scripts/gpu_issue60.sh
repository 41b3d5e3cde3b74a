#!/usr/bin/env bash
# One call on a lent GPU: the rgb mode's depth net trained on the packed frames, then the nets
# timed on CUDA and the CPU. Prepared on a machine with the frames and tre:
#
#   (cd models/training && python -m tre_training.pack pack ../../.gpu/pack)   # ~31 MB
#   python3 -m pip download --no-deps --only-binary=:all: -d .gpu/wheels pypng==0.20220715.0
#   echo /.gpu/ >> .git/info/exclude
#
# then, with the device tool: run(command="bash scripts/gpu_issue60.sh", carry=[".gpu"],
# timeout_s=590; it takes about 9 minutes with MINUTES=4.5). The same script runs on the CPU (DEVICE=cpu MINUTES=0.3 OUT=/tmp/x: a dry
# run). What comes back under $OUT: train.log, the curve (depth_progress.json), the test
# figures before and after, nets.md / nets.json, and run.tgz (checkpoint, ONNX, manifest,
# parity vectors) to unpack at the repository root.
set -euo pipefail
OUT=${OUT:-/tmp/gpu-out}
MINUTES=${MINUTES:-4.5}
PY=${PY:-python3}
mkdir -p "$OUT"
if compgen -G ".gpu/wheels/*.whl" >/dev/null; then
  "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .gpu/wheels/*.whl
  export PYTHONPATH=/tmp/site${PYTHONPATH:+:$PYTHONPATH}
fi
(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv || echo "no nvidia-smi") |
  tee "$OUT/gpu.txt"
"$PY" -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())" |
  tee -a "$OUT/gpu.txt"
start=$(date +%s)
(cd models/training && "$PY" -m tre_training.pack unpack ../../.gpu/pack)
echo "unpacked in $(($(date +%s) - start)) s"
RUN=models/training/runs/depth-gpu-$(date +%F)
# Larger batches on a GPU; validation every minute of a short budget.
DEVICE=${DEVICE:-auto} BATCH=${BATCH:-48} THREADS=${THREADS:-$(nproc)} VAL_EVERY=${VAL_EVERY:-60} \
  MINUTES=$MINUTES RUN=$RUN PY=$PY bash models/training/train_depth_real.sh 2>&1 |
  tee "$OUT/train.log" | grep -v " step " || true
echo "trained and measured in $(($(date +%s) - start)) s"
cp "$RUN/depth_progress.json" "$RUN/eval_test_before.txt" "$RUN/eval_test_after.txt" "$OUT/" || true
quick=()
[ "${QUICK:-0}" = 1 ] && quick=(--quick)
PYTHONPATH=models/training${PYTHONPATH:+:$PYTHONPATH} "$PY" scripts/gpu_nets.py --out "$OUT" "${quick[@]}" ||
  echo "timing failed"
tar czf "$OUT/run.tgz" "$RUN" models/depth_net.onnx models/manifest.json \
  tests/fixtures/onnx_parity/depth_net
echo "done in $(($(date +%s) - start)) s"
