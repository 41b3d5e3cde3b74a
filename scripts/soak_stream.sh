#!/usr/bin/env bash
# Stream soak: ONE WebSocket stream held at a fixed rate for a fixed time, on the real kitchen
# depth frames, with the server's resident memory sampled every 5 s.
#
#   scripts/soak_stream.sh [--minutes M] [--rate R] [--out DIR]   (defaults 10, 15, results/soak-stream)
#
# Starts `tre serve` (defaults: 2 workers on this machine, one per core) on a free port (PORT,
# default 18081), waits for /readyz, then runs
#
#   tre client --server ws://127.0.0.1:PORT --frames RGB --depth DEPTH --camera CAMERA \
#       --mode geometric --rate R --loop --out DIR/client
#
# on the 200 frames of ../shared/data/real-rgbd-2/sevenscenes_redkitchen (640×480, 16-bit depth
# in millimetres; `geometric` checks the colour frames' headers but does not decode them), with
# cameras/real-rgbd-2_sevenscenes_redkitchen.json (intrinsics, depth_scale 1000, kinect_v1).
# After M minutes (and 5 s, so that the M-th minute is whole) the client gets SIGINT: it stops
# sending, waits for the frames in flight and writes frames.csv. Then the server's counters are
# read and the server is stopped.
#
# Writes into DIR: `client/frames.csv` (one row per frame sent; the returned maps are deleted
# unless KEEP_MAPS=1), `rss.tsv` (every 5 s: unix time, seconds since ready, the server's VmRSS
# KiB, load average over 1 min, CPU seconds so far of the server, of the client and of the whole
# machine: the machine is shared, and what else ran shows in the last), `summary.txt` (the
# client's notices and last progress line, the server's counters), and through
# scripts/soak_table.py `table.md` (per minute: answered rate, drops, errors, latency
# percentiles, median RSS; the verdict) and `soak-stream.svg`.
#
# DATA and CAMERA choose other frames and their camera file (e.g. the kitchen at 320×240);
# DEPTH_ONLY=1 streams the depth alone.
#
# Needs a release build (`cargo build --release`, or TRE=path/to/tre), curl and python3 (no
# packages).
set -euo pipefail
cd "$(dirname "$0")/.."
minutes=10
rate=15
out=results/soak-stream
while [ $# -gt 0 ]; do
    case $1 in
        --minutes) minutes=$2; shift 2 ;;
        --rate) rate=$2; shift 2 ;;
        --out) out=$2; shift 2 ;;
        *) echo "usage: $0 [--minutes M] [--rate R] [--out DIR]" >&2; exit 2 ;;
    esac
done
tre=${TRE:-target/release/tre}
data=${DATA:-../shared/data/real-rgbd-2/sevenscenes_redkitchen}
camera=${CAMERA:-cameras/real-rgbd-2_sevenscenes_redkitchen.json}
# DEPTH_ONLY=1: stream the depth alone (`tre client --depth` without `--frames`), as a depth
# camera would; DATA then needs only depth/.
frames=(--frames "$data/rgb")
[ -z "${DEPTH_ONLY:-}" ] || frames=()
port=${PORT:-18081}
url=http://127.0.0.1:$port
if curl -s -o /dev/null "$url/healthz"; then
    echo "port $port is taken: set PORT" >&2
    exit 1
fi
mkdir -p "$out"
rm -rf "$out/client"

"$tre" serve --addr "127.0.0.1:$port" --log warn &
server=$!
sampler=""
client=""
cleanup() {
    for p in $client $sampler $server; do kill "$p" 2> /dev/null || true; done
}
trap cleanup EXIT
until curl -sf "$url/readyz" > /dev/null; do
    kill -0 $server 2> /dev/null || { echo "tre serve exited" >&2; exit 1; }
    sleep 1
done
ready=$(date +%s.%N)
tick=$(getconf CLK_TCK)
# CPU seconds a process has used (user and system), or nothing once it is gone.
cpu_s() {
    [ -n "$1" ] && awk -v t="$tick" '{print ($14 + $15) / t}' "/proc/$1/stat" 2> /dev/null || echo
}
(while kill -0 $server 2> /dev/null; do
    now=$(date +%s.%N)
    printf '%.3f\t%.1f\t%s\t%s\t%s\t%s\t%s\n' "$now" \
        "$(echo "$now $ready" | awk '{print $1 - $2}')" \
        "$(awk '/^VmRSS/ {print $2}' /proc/$server/status)" "$(cut -d' ' -f1 /proc/loadavg)" \
        "$(cpu_s $server)" "$(cpu_s "$(cat "$out/client.pid" 2> /dev/null)")" \
        "$(awk -v t="$tick" '/^cpu / {print ($2 + $3 + $4 + $7 + $8 + $9) / t}' /proc/stat)"
    sleep 5
done) > "$out/rss.tsv" &
sampler=$!

# A background job of a script starts with SIGINT ignored; `set -m` gives it its own process
# group with the default disposition, so that the client's Ctrl-C handling sees the SIGINT.
set -m
"$tre" client --server "ws://127.0.0.1:$port" "${frames[@]}" --depth "$data/depth" \
    --camera "$camera" --mode geometric --rate "$rate" --loop --out "$out/client" \
    > "$out/client.log" 2>&1 &
client=$!
set +m
echo $client > "$out/client.pid"
sleep $((minutes * 60 + 5))
kill -INT $client
status=0
wait $client || status=$?
client=""

counters=$(curl -s "$url/metrics" |
    grep -E '^tre_requests_total|^tre_frames_dropped_total|^tre_batch_size_count|^tre_stream' || true)
kill $sampler
sampler=""
kill -TERM $server
wait $server || true
server=""
[ "${KEEP_MAPS:-0}" = 1 ] || find "$out/client" -name '*.png' -delete

{
    echo "== $minutes min at $rate frames/s, one stream; client exit status $status"
    echo "== the client's output, less its progress line a second, and its last progress line"
    grep -v -e '^\[' -e '^answers:' "$out/client.log" || true
    grep '^\[' "$out/client.log" | tail -n 1
    echo "== how the answers were made (the client tells it when it changes): count, notice"
    grep '^answers:' "$out/client.log" | sed 's/; pitch_deg=.*//; s/ (.*//' | sort | uniq -c
    echo "== the server's counters"
    echo "$counters"
} | tee "$out/summary.txt"
rm -f "$out/client.log" "$out/client.pid"
python3 scripts/soak_table.py "$out/client/frames.csv" "$out/rss.tsv" \
    --md "$out/table.md" --svg "$out/soak-stream.svg"
cat "$out/table.md"
