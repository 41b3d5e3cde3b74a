#!/usr/bin/env bash
# Soak test: `tre serve` under mixed load for a while, its resident memory sampled every 5 s.
#
#   scripts/soak.sh [SECONDS_HTTP] [SECONDS_STREAM]      (defaults 150 and 60)
#
# Load, all at once for SECONDS_HTTP: `tre loadtest` closed loop with 3 clients over three
# 640×480 RGB frames of ../shared/data/real-rgbd (PNG and JPEG); beside it, in turn, an RGB-D
# request with all five extra maps, a depth-only `npy` request, a truncated PNG (422) and a
# body that is not an image (415). Then SECONDS_STREAM of the WebSocket stream at 20 frames/s
# on 2 connections (latest frame wins: drops expected). Prints the RSS samples, the load
# tests' summaries, the side requests' statuses and the server's request counters.
# Needs a release build (`cargo build --release`), curl, and a free port 18080.
set -euo pipefail
cd "$(dirname "$0")/.."
http_s=${1:-150}
stream_s=${2:-60}
tre=target/release/tre
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
start=$(date +%s)
(while kill -0 $server 2> /dev/null; do
    echo "$(($(date +%s) - start)) $(awk '/VmRSS/ {print $2}' /proc/$server/status)"
    sleep 5
done) > "$work/rss.txt" &
sampler=$!

(end=$((SECONDS + http_s)); n=0
while [ $SECONDS -lt $end ]; do
    i=$((n % 5 + 1))
    curl -s -o /dev/null -w '%{http_code}\n' -F "rgb=@$ch5/color/$i.png" -F "depth=@$ch5/depth/$i.png" \
        "$url/v1/roughness?outputs=depth,normals,slope,traversable,boundary"
    curl -s -o /dev/null -w '%{http_code}\n' -F "depth=@$ch5/depth/$i.png" "$url/v1/roughness?format=npy"
    head -c 5000 "$ch5/color/$i.png" | curl -s -o /dev/null -w '%{http_code}\n' --data-binary @- \
        -H 'content-type: image/png' "$url/v1/roughness"
    curl -s -o /dev/null -w '%{http_code}\n' --data-binary 'not an image' \
        -H 'content-type: image/png' "$url/v1/roughness"
    n=$((n + 1))
done) > "$work/side.txt" &
side=$!
"$tre" loadtest --url "$url" --frames "$work/frames" --connections 3 --duration "$http_s" \
    --warmup 0 --log warn > "$work/http.txt"
wait $side
"$tre" loadtest --url "$url" --protocol ws --frames "$work/frames" --rate 20 --connections 2 \
    --duration "$stream_s" --warmup 0 --log warn > "$work/stream.txt"
sleep 6
kill $sampler

echo "== RSS (KiB) every 5 s: seconds since ready, RSS"
tr '\n' ' ' < "$work/rss.txt"; echo
awk 'NR > 2 { if (min == "" || $2 < min) min = $2; if ($2 > max) max = $2 }
     END { printf "after the first 10 s: %.0f to %.0f MiB\n", min / 1024, max / 1024 }' "$work/rss.txt"
echo "== HTTP load"; head -n 13 "$work/http.txt"
echo "== stream load"; head -n 13 "$work/stream.txt"
echo "== side requests: count, status"; sort "$work/side.txt" | uniq -c
echo "== the server's counters"
curl -s "$url/metrics" | grep -E '^tre_requests_total|^tre_frames_dropped_total'
