#!/usr/bin/env bash
# Receive rates of `tre ros2`'s outputs at a stock subscriber of another DDS implementation
# (docs/ros2.md, "Receive rates"). Starts the node on a domain of its own, runs
# scripts/ros2_rates.py against it and prints the peer's JSON, then the node's own count.
#
#   PY=/path/to/venv/bin/python scripts/ros2_rates.sh cyclone 15 90 reliable [tre ros2 options]
#   PY=... scripts/ros2_rates.sh fastdds 15 90 best-effort [tre ros2 options]
#
# cyclone: the peer in Eclipse Cyclone DDS; fastdds: a real rclpy node over Fast DDS. PY: a
# Python with the packages of scripts/requirements-dds.txt (and requirements-rclpy.txt).
# SUBSCRIBE: the output topics the peer subscribes to (default: all); SHOW_LOG=1: the node's
# most frequent log lines. TRE: the binary (default target/release/tre). FRAMES: the kitchen
# sequence (default ../shared/data/real-rgbd-2/sevenscenes_redkitchen).
set -euo pipefail
cd "$(dirname "$0")/.."
dds=${1:-cyclone} hz=${2:-15} count=${3:-90} rel=${4:-reliable}
shift $(($# < 4 ? $# : 4))
py=${PY:-python3}
tre=${TRE:-target/release/tre}
frames=${FRAMES:-../shared/data/real-rgbd-2/sevenscenes_redkitchen}
domain=${DOMAIN:-$((20 + $$ % 80))}
gravity=$("$py" -c "import json,sys; print(','.join(repr(v) for v in json.load(open(sys.argv[1]))['gravity']))" "$frames/gravity.json")
log=$(mktemp)
duration=$("$py" -c "print($count / $hz + 45)")
"$tre" ros2 --domain-id "$domain" --odom-topic /odom --sensor kinect_v1 --gravity="$gravity" \
    --map-frame world --duration-s "$duration" "$@" >"$log.out" 2>"$log.err" &
node=$!
trap 'kill $node 2>/dev/null || true; rm -f "$log" "$log.out" "$log.err"' EXIT
"$py" scripts/ros2_rates.py --dds "$dds" --domain "$domain" --frames "$frames" --hz "$hz" \
    --count "$count" --reliability "$rel" ${SUBSCRIBE:+--subscribe "$SUBSCRIBE"}
kill -INT $node 2>/dev/null || true
wait $node || true
echo "node: $(tail -n 1 "$log.out")"
echo "node log lines: $(wc -l <"$log.err")"
[ -z "${SHOW_LOG:-}" ] || sort "$log.err" | uniq -c | sort -rn | head -n 5
