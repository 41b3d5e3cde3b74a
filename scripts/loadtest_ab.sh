#!/usr/bin/env bash
# One open-loop HTTP run of `tre loadtest` against a fresh `tre serve` of the binary given, to
# compare two builds back to back on the same machine (the load generator is always CLIENT):
#
#   scripts/loadtest_ab.sh /tmp/tre-old old1 3; scripts/loadtest_ab.sh /tmp/tre-new new1 3
#
# Arguments: server binary, label, rate per second, then any `tre serve` options. Environment:
# CLIENT (target/release/tre), OUT (a folder, /tmp), PORT (18190), DURATION (20), WARMUP (2).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$1 LABEL=$2 RATE=$3
shift 3
CLIENT=${CLIENT:-target/release/tre}
OUT=${OUT:-/tmp}
PORT=${PORT:-18190}
# shellcheck source=scripts/serve_lib.sh
. scripts/serve_lib.sh
serve_up "$BIN" "${TMPDIR:-/tmp}/tre-serve-ab.log" "$@"
trap serve_down EXIT
"$CLIENT" loadtest --url "http://127.0.0.1:$PORT" --rate "$RATE" --duration "${DURATION:-20}" \
  --warmup "${WARMUP:-2}" --json "$OUT/ab-$LABEL.json" >"$OUT/ab-$LABEL.txt"
echo "$LABEL: $(grep -E '^ok ' "$OUT/ab-$LABEL.txt" | tail -1)"
