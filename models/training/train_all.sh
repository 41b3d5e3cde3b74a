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
python -m tre_training.train cache-n0 --data "../../$DATA" --frames 480
python -m tre_training.train refiner --data "../../$DATA" --minutes "${REFINER_MIN:-10}"
python -m tre_training.train cache-n --data "../../$DATA"
python -m tre_training.train centroid --data "../../$DATA" --minutes "${CENTROID_MIN:-14}"
python -m tre_training.train e2e --data "../../$DATA" --minutes "${E2E_MIN:-18}"
python -m tre_training.export --data "../../$DATA"
python -m tre_training.eval_real
