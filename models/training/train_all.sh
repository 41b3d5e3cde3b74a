#!/usr/bin/env bash
# Reproduces the committed models on CPU: the sensor-realistic dataset, five trainings, caches,
# end-to-end fine-tuning, export, real-frame depth check. Run from the repository root with the
# training venv active (pip install -r models/training/requirements.txt). Minutes are wall-clock
# budgets per stage; SCALE multiplies all of them (SCALE=0.05 for a smoke run; a GPU or more
# cores get more steps from the same budgets).
set -euo pipefail
DATA=${DATA:-data/sensor256}
SCALE=${SCALE:-1}
# Every frame draws its camera (pitch 0-85 deg, height 0.2-2 m, roll, field of view, shape), its
# depth-sensor model (the four presets and exact depth), its image effects and its content
# (natural, indoor, urban). Ground truth is always the spec on the exact depth.
if [ ! -f "$DATA/dataset.json" ]; then
  cargo run --release -- synth --out "$DATA" --scenes 200 --seed 2031 --width 256 \
    --random-optics --no-ply --content mixed \
    --sensor kinect_v1,realsense_d435,azure_kinect,lidar,exact \
    --effects exposure,white_balance,vignetting,defocus,motion_blur,noise,jpeg
fi
cd models/training
D="../../$DATA"
m() { python -c "print(round($1 * $SCALE, 3))"; }
t() { python -m tre_training.train "$@" --data "$D"; }
t depth --minutes "$(m 20)"
# The geometric stages read points from each frame's sensor depth (the rgbd input as a real
# camera gives it) and learn the roughness of the exact depth.
t neighbour --depth sensor --minutes "$(m 10)"
t cache-n0 --depth sensor --frames "${N0_FRAMES:-400}"
t refiner --depth sensor --minutes "$(m 8)"
t cache-n --depth sensor
t centroid --depth sensor --minutes "$(m 12)"
t e2e --minutes "$(m 8)"
# Fine-tune the refiner and the centroid net with every other batch on points from the depth
# net's depth, so that one set of weights serves both the rgb and the rgbd modes: the chain
# trained end to end on what each stage gets at serving time.
t cache-depth
t cache-n0 --depth pred --frames "${N0_FRAMES:-400}"
cp checkpoints/refiner.pt checkpoints/refiner_sensor.pt; cp checkpoints/refiner.json checkpoints/refiner_sensor.json
cp checkpoints/centroid.pt checkpoints/centroid_sensor.pt; cp checkpoints/centroid.json checkpoints/centroid_sensor.json
t refiner --depth sensor --mix-pred --init checkpoints/refiner_sensor.pt --minutes "$(m 4)"
t cache-n --depth sensor
t cache-n --depth pred
t centroid --depth sensor --mix-pred --init checkpoints/centroid_sensor.pt --minutes "$(m 6)"
python -m tre_training.export --data "$D"
python -m tre_training.eval_real
# Real frames (docs/real-training.md; REAL=1): the train split of models/real_splits.json, every
# other batch synthetic, the checkpoint chosen on the val split. Needs ../shared/data/real-rgbd*.
if [ "${REAL:-0}" = 1 ]; then
  python -m tre_training.from_onnx
  python -m tre_training.real train --annotate ../../target/release/tre
  python -m tre_training.real val --annotate ../../target/release/tre
  python -m tre_training.train_real depth --data "$D" --minutes "$(m 20)" --lr 2e-4 --val-every 120
  python -m tre_training.train_real cache-n0 --data "$D"
  python -m tre_training.train_real cache-n --data "$D"
  t cache-n0 --depth sensor --frames 60
  t cache-n --depth sensor
  python -m tre_training.train_real centroid --data "$D" --minutes "$(m 10)" --lr 2e-4 --val-every 120
  python -m tre_training.export --data "$D" --nets depth_net centroid_net
  python -m tre_training.eval_real --split test
fi
