#!/usr/bin/env bash
# Measures a release `tre serve` on this machine with `tre loadtest`: one frame at a time (a
# closed loop on one connection: what a frame alone takes on the day, to compare runs made on
# different days), an HTTP open-loop rate sweep at 256×256 in rgb mode (the default for an
# image-only request), one HTTP and one WebSocket open-loop run at the sweep's last clean rate
# (compared), a WebSocket closed loop, the server's RSS before and after, and a CPU log that
# shows what else ran on the machine.
#
#   cargo build --release && scripts/loadtest_measure.sh [path/to/tre]
#
# Environment: OUT (results/loadtest/default), SERVE_ARGS (extra `tre serve` options, e.g.
# "--workers 1"), PORT (18080), RATES (2,3,4,5,6,7,8,9,10,12,15), DURATION (20 s per run),
# WARMUP (2 s), RATE (single-run rate; default: the sweep's last clean rate).
set -euo pipefail
cd "$(dirname "$0")/.."
TRE=${1:-target/release/tre}
OUT=${OUT:-results/loadtest/default}
SERVE_ARGS=${SERVE_ARGS:-}
PORT=${PORT:-18080}
RATES=${RATES:-2,3,4,5,6,7,8,9,10,12,15}
DURATION=${DURATION:-20}
WARMUP=${WARMUP:-2}
URL=http://127.0.0.1:$PORT
mkdir -p "$OUT"

# shellcheck disable=SC2086
"$TRE" serve --addr "127.0.0.1:$PORT" --models models $SERVE_ARGS >/dev/null \
  2>"${TMPDIR:-/tmp}/tre-serve-measure.log" &
PID=$!
SAMPLER=
trap 'kill $SAMPLER $PID 2>/dev/null; wait $PID 2>/dev/null || true' EXIT
for _ in $(seq 1 600); do curl -sf "$URL/readyz" >/dev/null && break; sleep 0.2; done
rss() { grep -E '^(VmRSS|VmHWM)' "/proc/$PID/status" | tr -s ' \t' ' ' | paste -sd ';' -; }

# Every 2 s: unix time, cores busy on the machine, cores used by the server, by everything else.
sample_cpu() {
  local ncpu busy all srv b a s
  ncpu=$(nproc)
  read -r busy all < <(awk '/^cpu /{b=$2+$3+$4+$7+$8+$9; print b, b+$5+$6}' /proc/stat)
  srv=$(awk '{print $14+$15}' "/proc/$PID/stat")
  echo -e "unix_s\tmachine_cores\tserver_cores\tother_cores"
  while sleep 2; do
    read -r b a < <(awk '/^cpu /{b=$2+$3+$4+$7+$8+$9; print b, b+$5+$6}' /proc/stat)
    s=$(awk '{print $14+$15}' "/proc/$PID/stat" 2>/dev/null) || break
    awk -v t="$(date +%s)" -v n="$ncpu" -v db=$((b - busy)) -v da=$((a - all)) -v ds=$((s - srv)) \
      'BEGIN { if (da > 0) printf "%d\t%.2f\t%.2f\t%.2f\n", t, n*db/da, n*ds/da, n*(db-ds)/da }'
    busy=$b; all=$a; srv=$s
  done
}
sample_cpu >"$OUT/cpu.tsv" &
SAMPLER=$!

env_txt=$OUT/environment.txt
{
  echo "date: $(date -u +%FT%TZ)"
  echo "commit: $(git rev-parse --short HEAD)"
  echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
  echo "server: $TRE serve --addr 127.0.0.1:$PORT --models models $SERVE_ARGS (pid $PID)"
  echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "server RSS when ready: $(rss)"
} >"$env_txt"

"$TRE" loadtest --url "$URL" --connections 1 --requests 20 --warmup "$WARMUP" \
  --json "$OUT/alone.json" | tee "$OUT/alone.txt"
echo "a frame alone (closed loop, 1 connection, 20 requests): $(grep -E '^ok ' "$OUT/alone.txt" | tail -1)" >>"$env_txt"

"$TRE" loadtest --url "$URL" --sweep "$RATES" --duration "$DURATION" --warmup "$WARMUP" \
  --slo-ms 150 --json "$OUT/http-sweep.json" --plot "$OUT/http-sweep.svg" | tee "$OUT/http-sweep.txt"
echo "server RSS after the HTTP sweep: $(rss)" >>"$env_txt"

RATE=${RATE:-$(sed -n 's/^  "clean_rate_per_s": \([0-9.]*\),*$/\1/p' "$OUT/http-sweep.json")}
RATE=${RATE:-2}
"$TRE" loadtest --url "$URL" --rate "$RATE" --duration "$DURATION" --warmup "$WARMUP" \
  --json "$OUT/http-open.json" --plot "$OUT/http-open.svg" | tee "$OUT/http-open.txt"
"$TRE" loadtest --url "$URL" --protocol ws --connections 2 --rate "$RATE" --duration "$DURATION" \
  --warmup "$WARMUP" --json "$OUT/ws-open.json" --plot "$OUT/ws-open.svg" \
  --compare "$OUT/http-open.json" | tee "$OUT/ws-open.txt"
"$TRE" loadtest --url "$URL" --protocol ws --connections 2 --duration "$DURATION" \
  --warmup "$WARMUP" --json "$OUT/ws-closed.json" --plot "$OUT/ws-closed.svg" | tee "$OUT/ws-closed.txt"
{
  echo "server RSS after all runs: $(rss)"
  echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
} >>"$env_txt"

# Mean CPU of the server and of everything else during each run's measured window.
python3 - "$OUT" <<'PY' | tee -a "$env_txt"
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
rows = [l.split("\t") for l in (out / "cpu.tsv").read_text().splitlines()[1:]]
cpu = [(float(t), float(m), float(s), float(o)) for t, m, s, o in rows]
runs = [json.loads((out / "alone.json").read_text())]
runs += json.loads((out / "http-sweep.json").read_text())["rows"]
runs += [json.loads((out / f).read_text()) for f in ("http-open.json", "ws-open.json", "ws-closed.json")]
print("cores used during each measured window (2 s samples): server / everything else")
for r in runs:
    t0 = r["window_start_unix_s"]; t1 = t0 + max(r["window_s"], r["answered_s"])
    inside = [c for c in cpu if t0 + 2 <= c[0] <= t1]
    if inside:
        srv = sum(c[2] for c in inside) / len(inside)
        other = sum(c[3] for c in inside) / len(inside)
        print(f"  {r['protocol']} {r['load']} {r['offered_rate_per_s'] or ''}: server {srv:.2f}, other {other:.2f}, max other {max(c[3] for c in inside):.2f}")
PY
cat "$env_txt"
