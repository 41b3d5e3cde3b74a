#!/usr/bin/env bash
# Reproduces the committed models on CPU: dataset, five trainings, caches, export, real-frame
# depth check. Run from the repository root with the training venv active
# (pip install -r models/training/requirements.txt). Minutes are wall-clock budgets per stage.
set -euo pipefail
DATA=${DATA:-data/synth256}
cargo run --release -- synth --out "$DATA" --scenes 200 --seed 2026 --width 256 --height 256 \
  --random-mounting --no-ply
cd models/training
python -m tre_training.train depth --data "../../$DATA" --minutes "${DEPTH_MIN:-22}"
python -m tre_training.train neighbour --data "../../$DATA" --minutes "${NEIGHBOUR_MIN:-14}"
python -m tre_training.train cache-n0 --data "../../$DATA" --frames 400
python -m tre_training.train refiner --data "../../$DATA" --minutes "${REFINER_MIN:-10}"
python -m tre_training.train cache-n --data "../../$DATA"
python -m tre_training.train centroid --data "../../$DATA" --minutes "${CENTROID_MIN:-13}"
python -m tre_training.train e2e --data "../../$DATA" --minutes "${E2E_MIN:-15}"
# Fine-tune the refiner and the centroid net with every other batch on points from the depth
# net's depth, so one set of weights serves both the rgb and the rgbd modes.
python -m tre_training.train cache-depth --data "../../$DATA"
python -m tre_training.train cache-n0 --depth pred --data "../../$DATA" --frames 400
cp checkpoints/refiner.pt checkpoints/refiner_gt.pt; cp checkpoints/refiner.json checkpoints/refiner_gt.json
cp checkpoints/centroid.pt checkpoints/centroid_gt.pt; cp checkpoints/centroid.json checkpoints/centroid_gt.json
python -m tre_training.train refiner --data "../../$DATA" --minutes 5 --mix-pred --init checkpoints/refiner_gt.pt
python -m tre_training.train cache-n --data "../../$DATA"
python -m tre_training.train cache-n --depth pred --data "../../$DATA"
python -m tre_training.train centroid --data "../../$DATA" --minutes 8 --mix-pred --init checkpoints/centroid_gt.pt
python -m tre_training.export --data "../../$DATA"
python -m tre_training.eval_real
