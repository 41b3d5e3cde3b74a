#!/usr/bin/env bash
# Soak test: `tre serve` under mixed load, its resident memory and frame rate sampled every 5 s.
#
#   scripts/soak.sh [SECONDS_HTTP] [SECONDS_STREAM]      (defaults 150 and 60)
#   scripts/soak.sh --frames N [--out DIR]               (e.g. --frames 10000)
#
# Load, all at once for SECONDS_HTTP: `tre loadtest` closed loop with 3 clients over three
# 640×480 RGB frames of ../shared/data/real-rgbd (PNG and JPEG); beside it, in turn, an RGB-D
# request with all five extra maps, a depth-only request answered as `npy`, a truncated PNG (422)
# and a body that is not an image (415). Then SECONDS_STREAM of the WebSocket stream at 20
# frames/s on 2 connections (latest frame wins: drops expected).
#
# With --frames N the same traffic runs until the workers have run N frames: the HTTP load test
# and the side requests for 80% of them, then the stream for the rest (the count is the server's
# own, `tre_batch_size_count`: every frame a worker ran, broken ones it refused included). With --out
# DIR the samples (`soak.tsv`: seconds since ready, RSS MiB, frames run, frames/s over the last
# 5 s) and the summary (`soak.txt`) are kept, and `soak.svg` plots them.
#
# Prints the RSS samples, the load tests' summaries, the side requests' statuses and the
# server's request counters. Needs a release build (`cargo build --release`), curl, python3
# (no packages) for the plot, and a free port 18080.
set -euo pipefail
cd "$(dirname "$0")/.."
frames=""
out=""
if [ "${1:-}" = "--frames" ]; then
    frames=$2
    shift 2
    if [ "${1:-}" = "--out" ]; then out=$2; shift 2; fi
fi
http_s=${1:-150}
stream_s=${2:-60}
tre=${TRE:-target/release/tre}
data=../shared/data/real-rgbd
ch5=$data/slambook2_ch5
port=18080
url=http://127.0.0.1:$port
work=$(mktemp -d)
mkdir "$work/frames"
cp "$data/metric3d_nyu/rgb/rgb_00000.jpg" "$work/frames/a.jpg"
cp "$data/slambook2_ch7/1.png" "$work/frames/b.png"
cp "$ch5/color/1.png" "$work/frames/c.png"

"$tre" serve --addr "127.0.0.1:$port" --workers 2 --log warn &
server=$!
trap 'kill $server 2>/dev/null || true; rm -rf "$work"' EXIT
until curl -sf "$url/readyz" > /dev/null; do sleep 1; done
run_frames() { curl -s "$url/metrics" | awk '/^tre_batch_size_count/ {print $2}'; }
start=$(date +%s)
(last=0
while kill -0 $server 2> /dev/null; do
    n=$(run_frames || echo "$last")
    printf '%s\t%s\t%s\t%.2f\n' "$(($(date +%s) - start))" \
        "$(awk '/VmRSS/ {printf "%.1f", $2 / 1024}' /proc/$server/status)" "$n" \
        "$(echo "$n $last" | awk '{print ($1 - $2) / 5}')"
    last=$n
    sleep 5
done) > "$work/rss.tsv" &
sampler=$!

side_loop() {
    n=0
    while [ ! -e "$work/http.done" ]; do
        i=$((n % 5 + 1))
        curl -s -o /dev/null -w '%{http_code}\n' -F "rgb=@$ch5/color/$i.png" -F "depth=@$ch5/depth/$i.png" \
            "$url/v1/roughness?outputs=depth,normals,slope,traversable,boundary"
        curl -s -o /dev/null -w '%{http_code}\n' -F "depth=@$ch5/depth/$i.png" "$url/v1/roughness?format=npy"
        head -c 5000 "$ch5/color/$i.png" | curl -s -o /dev/null -w '%{http_code}\n' --data-binary @- \
            -H 'content-type: image/png' "$url/v1/roughness"
        curl -s -o /dev/null -w '%{http_code}\n' --data-binary 'not an image' \
            -H 'content-type: image/png' "$url/v1/roughness"
        n=$((n + 1))
    done
}
side_loop > "$work/side.txt" &
side=$!
if [ -n "$frames" ]; then
    # The load test's requests are 80% of the frames less what the side requests add meanwhile
    # (about one frame in six); the stream then tops the count up to N.
    "$tre" loadtest --url "$url" --frames "$work/frames" --connections 3 \
        --requests $((frames * 8 / 10 * 6 / 7)) --warmup 0 --log warn > "$work/http.txt"
else
    "$tre" loadtest --url "$url" --frames "$work/frames" --connections 3 --duration "$http_s" \
        --warmup 0 --log warn > "$work/http.txt"
fi
touch "$work/http.done"
wait $side
if [ -n "$frames" ]; then
    left=$((frames - $(run_frames)))
    [ $left -lt 1 ] && left=1
    # Latest frame wins: at 20 frames/s on 2 connections some frames are dropped, not run, so
    # as-fast-as-results (closed loop) makes every frame sent a frame run.
    "$tre" loadtest --url "$url" --protocol ws --frames "$work/frames" --connections 2 \
        --requests "$left" --warmup 0 --log warn > "$work/stream.txt"
else
    "$tre" loadtest --url "$url" --protocol ws --frames "$work/frames" --rate 20 --connections 2 \
        --duration "$stream_s" --warmup 0 --log warn > "$work/stream.txt"
fi
sleep 6
kill $sampler

{
echo "== RSS (MiB) and frames every 5 s: seconds since ready, RSS, frames run, frames/s"
awk '{printf "%s %s %s %s | ", $1, $2, $3, $4} END {print ""}' "$work/rss.tsv"
awk 'NR > 2 { if (min == "" || $2 < min) min = $2; if ($2 > max) max = $2 }
     { t = $1; n = $3 }
     END { printf "after the first 10 s: %.0f to %.0f MiB; %d frames in %d s (%.2f frames/s)\n",
           min, max, n, t, n / t }' "$work/rss.tsv"
echo "== HTTP load"; head -n 13 "$work/http.txt"
echo "== stream load"; head -n 13 "$work/stream.txt"
echo "== side requests: count, status"; sort "$work/side.txt" | uniq -c
echo "== the server's counters"
curl -s "$url/metrics" | grep -E '^tre_requests_total|^tre_frames_dropped_total|^tre_batch_size_count'
} | tee "$work/summary.txt"
if [ -n "$out" ]; then
    mkdir -p "$out"
    cp "$work/rss.tsv" "$out/soak.tsv"
    cp "$work/summary.txt" "$out/soak.txt"
    python3 scripts/plot_soak.py "$out/soak.tsv" "$out/soak.svg"
fi
