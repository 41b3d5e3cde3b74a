#!/usr/bin/env bash
# Camera rate over HTTP, in one run (docs/benchmarks.md): one `tre serve` and `tre loadtest` on
# this machine, depth-only 7-Scenes kitchen frames with the kinect_v1 model, the uncertainty and
# the three-state map (`--mode geometric --sensor kinect_v1 --traversal`):
#   1. one client, closed loop, 640x480 and 320x240 (every second pixel of each row and column);
#   2. one client, open loop at RATE frames/s offered, 320x240;
#   3. the numpy surface-only peer (scripts/surface_peer.py) in-process on the same frames,
#      and the ratio of its median time to the closed loop's p50 round trip.
#
#   cargo build --release && PY=python-with-numpy-and-pillow scripts/camera_rate.sh
#
# Environment: TRE (target/release/tre), PY (python3), OUT (camera_rate in TMPDIR), PORT (18091),
# FRAMES (30), REQUESTS (60), RATE (30), DURATION (20 s), SERVE_ARGS (extra `tre serve` options).
set -euo pipefail
cd "$(dirname "$0")/.."
TRE=${TRE:-target/release/tre}
PY=${PY:-python3}
OUT=${OUT:-${TMPDIR:-/tmp}/camera_rate}
PORT=${PORT:-18091}
FRAMES=${FRAMES:-30}
REQUESTS=${REQUESTS:-60}
RATE=${RATE:-30}
DURATION=${DURATION:-20}
SERVE_ARGS=${SERVE_ARGS:-}
KITCHEN=${KITCHEN:-../shared/data/real-rgbd-2/sevenscenes_redkitchen}
URL=http://127.0.0.1:$PORT
mkdir -p "$OUT"

# The frames: the kitchen's first FRAMES depth images, and each halved.
"$PY" - "$KITCHEN" "$OUT" "$FRAMES" <<'EOF'
import json, os, sys
import numpy as np
from PIL import Image
kitchen, out, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
camera = json.load(open(os.path.join(kitchen, "intrinsics.json")))
camera.pop("frames", None)
names = sorted(os.listdir(os.path.join(kitchen, "depth")))[:count]
for size, step in (("640", 1), ("320", 2)):
    os.makedirs(os.path.join(out, size, "depth"), exist_ok=True)
    for name in names:
        depth = np.asarray(Image.open(os.path.join(kitchen, "depth", name)))[::step, ::step]
        Image.fromarray(depth.astype(np.uint16)).save(os.path.join(out, size, "depth", name))
    c = dict(camera)
    for key in ("fx", "fy"):
        c[key] = camera[key] / step
    for key in ("cx", "cy"):
        c[key] = (camera[key] + 0.5) / step - 0.5
    c["width"], c["height"] = camera["width"] // step, camera["height"] // step
    json.dump(c, open(os.path.join(out, size, "camera.json"), "w"))
EOF

# shellcheck disable=SC2086
"$TRE" serve --addr "127.0.0.1:$PORT" $SERVE_ARGS >/dev/null 2>"$OUT/serve.log" &
PID=$!
trap 'kill $PID 2>/dev/null; wait $PID 2>/dev/null || true' EXIT
for _ in $(seq 1 600); do curl -sf "$URL/readyz" >/dev/null && break; sleep 0.2; done
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)" | tee "$OUT/environment.txt"

load() {
  local size=$1 name=$2
  shift 2
  "$TRE" loadtest --url "$URL" --depth-dir "$OUT/$size/depth" --camera "$OUT/$size/camera.json" \
    --mode geometric --sensor kinect_v1 --traversal --json "$OUT/$name.json" "$@" \
    >"$OUT/$name.txt" 2>&1
  grep -E "achieved|^ok " "$OUT/$name.txt" | sed "s/^/$name: /"
}
load 640 closed_640 --connections 1 --requests "$REQUESTS"
load 320 closed_320 --connections 1 --requests "$REQUESTS"
load 320 open_320 --rate "$RATE" --duration "$DURATION" --warmup 2
for size in 640 320; do
  "$PY" scripts/surface_peer.py "$OUT/$size/camera.json" "$OUT/$size"/depth/*.png \
    >"$OUT/peer_$size.txt"
  echo "peer_$size: $(tail -1 "$OUT/peer_$size.txt")"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/environment.txt"

# The ratio: the peer's median in-process time over the closed loop's p50 round trip.
"$PY" - "$OUT" <<'EOF'
import json, sys
out = sys.argv[1]
for size in ("640", "320"):
    run = json.load(open(f"{out}/closed_{size}.json"))
    p50 = run["latency_ms"]["p50_ms"]
    peer = float(open(f"{out}/peer_{size}.txt").read().strip().splitlines()[-1].split("\t")[1].split()[0])
    print(f"{size}: round trip p50 {p50:.1f} ms, peer {peer:.1f} ms in-process: {peer / p50:.2f}x")
EOF
