#!/usr/bin/env bash
# Two `tre` builds back to back on the depth-only service at 640x480: for each build, a fresh
# `tre serve` (defaults) and that build's `tre loadtest` on the 40 real kitchen depth frames of
# docs/loadtest/depth-geometric.md (frames 800-995, every 5th, of
# ../shared/data/real-rgbd-2/sevenscenes_redkitchen, with its camera file):
#
#   - HTTP closed loop, 1 client, then 2 clients (roughness only);
#   - one WebSocket stream at 15 frames/s asking for the three-state and uncertainty maps;
#
# 20 s measured after 3 s of warm-up each, the builds alternated ROUNDS times.
#
#   scripts/ab_depth.sh OLD_TRE NEW_TRE [ROUNDS]      (OUT: a folder, default /tmp/ab-depth)
#
# Prints one line per run: build, round, load and the `ok` row of the latency table (p50, p90,
# p99, p99.9, max, mean, count); the full reports and JSON are left in OUT.
set -euo pipefail
cd "$(dirname "$0")/.."
old=$1 new=$2 rounds=${3:-2}
out=${OUT:-/tmp/ab-depth}
port=${PORT:-18190}
cam=cameras/real-rgbd-2_sevenscenes_redkitchen.json
mkdir -p "$out/frames"
for i in $(seq 800 5 995); do
    cp "../shared/data/real-rgbd-2/sevenscenes_redkitchen/depth/$(printf 'frame-%06d.png' "$i")" \
        "$out/frames/"
done
for round in $(seq 1 "$rounds"); do
    for label in old new; do
        bin=$old
        [ "$label" = new ] && bin=$new
        "$bin" serve --addr "127.0.0.1:$port" --models models >/dev/null 2>"$out/serve-$label.log" &
        pid=$!
        for _ in $(seq 1 300); do
            curl -sf "http://127.0.0.1:$port/readyz" >/dev/null && break
            sleep 0.2
        done
        common=(--url "http://127.0.0.1:$port" --depth-dir "$out/frames" --camera "$cam"
            --mode geometric --duration 20 --warmup 3)
        "$bin" loadtest "${common[@]}" --connections 1 --json "$out/$label-$round-c1.json" \
            >"$out/$label-$round-c1.txt" 2>&1
        "$bin" loadtest "${common[@]}" --connections 2 --json "$out/$label-$round-c2.json" \
            >"$out/$label-$round-c2.txt" 2>&1
        "$bin" loadtest "${common[@]}" --protocol ws --traversal --rate 15 \
            --json "$out/$label-$round-ws.json" >"$out/$label-$round-ws.txt" 2>&1
        kill "$pid"
        wait "$pid" 2>/dev/null || true
        for load in c1 c2 ws; do
            echo "$label $round $load: $(grep -E '^(requests|ok) ' "$out/$label-$round-$load.txt" \
                | tr -s ' ' | paste -sd ' ')"
        done
    done
done
