#!/usr/bin/env bash
# Dynamic batching against none, in one run: `tre serve` three times (2 workers alone; 2 workers
# with --batch-max 2; 4 workers with --batch-max 4), each loaded closed loop by `tre loadtest`
# with 4 connections of `rgb` frames (the synthetic 256×256 frame), then the mean batch size
# from /metrics. Prints one line per setting and writes OUT/batching-*.{txt,json,metrics}.
#
#   scripts/batching_ab.sh            # OUT=/tmp, DURATION=30, TRE=target/release/tre
set -euo pipefail
cd "$(dirname "$0")/.."
TRE=${TRE:-target/release/tre}
OUT=${OUT:-${TMPDIR:-/tmp}}
DURATION=${DURATION:-30}
PORT=${PORT:-18191}
DELAY=${DELAY:-5}
# shellcheck source=scripts/serve_lib.sh
. scripts/serve_lib.sh
run() {
  local label=$1
  shift
  serve_up "$TRE" "$OUT/batching-$label.log" --ort-threads 1 "$@"
  "$TRE" loadtest --url "http://127.0.0.1:$PORT" --mode rgb --connections 4 \
    --duration "$DURATION" --warmup 3 --json "$OUT/batching-$label.json" >"$OUT/batching-$label.txt"
  curl -sf "http://127.0.0.1:$PORT/metrics" >"$OUT/batching-$label.metrics"
  serve_down
  local sum count
  sum=$(awk '$1 == "tre_batch_size_sum" {print $2}' "$OUT/batching-$label.metrics")
  count=$(awk '$1 == "tre_batch_size_count" {print $2}' "$OUT/batching-$label.metrics")
  echo "$label: $(grep -E '^ok ' "$OUT/batching-$label.txt" | tail -1) | net runs $count, mean batch $(
    python3 -c "print(round($sum / max($count, 1), 2))")"
}
run none --workers 2
run batch2 --workers 2 --batch-max 2 --batch-delay-ms "$DELAY"
run batch4 --workers 4 --batch-max 4 --batch-delay-ms "$DELAY"
