#!/usr/bin/env bash
# Memory that comes back: `tre serve`'s resident memory warm, at its peak through two large
# frames (a 2048×2048 depth-only frame in the geometric mode, the costliest allowed, and a
# 2048×2048 RGB frame), and after 10 s idle. docs/security.md has the figures.
#
#   scripts/memory.sh [IDLE_SECONDS]      (default 10)
#
# The environment passes through to the server (`GLIBC_TUNABLES=...`, `TRE_MALLOC_TRIM=...`),
# so allocator settings are compared by running it under each. Needs a release build
# (`cargo build --release`), python3 (no packages), curl and a free port 18081.
set -euo pipefail
cd "$(dirname "$0")/.."
idle=${1:-10}
tre=${TRE:-target/release/tre}
data=../shared/data/real-rgbd/slambook2_ch7
port=18081
url=http://127.0.0.1:$port
work=$(mktemp -d)

# The large frames, written with the standard library alone: a tilted floor 1–4 m deep with
# ripples (16-bit millimetres) and a textured RGB image.
python3 - "$work" <<'PY'
import math, struct, sys, zlib
def png(path, w, h, kind, rows):
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    ihdr = struct.pack(">IIBBBBB", w, h, *kind, 0, 0, 0)
    raw = b"".join(b"\0" + r for r in rows)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
                + chunk(b"IDAT", zlib.compress(raw, 1)) + chunk(b"IEND", b""))
n = 2048
depth_rows = (b"".join(struct.pack(">H", int(1000 + 1.4 * y + 8 * math.sin(x / 9) * math.cos(y / 7)))
                       for x in range(n)) for y in range(n))
png(sys.argv[1] + "/depth_2048.png", n, n, (16, 0), depth_rows)
rgb_rows = (bytes(((x * 7 + y * 3) ^ (x * y >> 5)) & 255 for x in range(n) for _ in range(3))
            for y in range(n))
png(sys.argv[1] + "/rgb_2048.png", n, n, (8, 2), rgb_rows)
PY

"$tre" serve --addr "127.0.0.1:$port" --workers 2 --log warn &
server=$!
trap 'kill $server 2>/dev/null || true; rm -rf "$work"' EXIT
until curl -sf "$url/readyz" > /dev/null; do sleep 0.5; done
rss() { awk '/VmRSS/ {printf "%d", $2 / 1024}' "/proc/$server/status"; }
hwm() { awk '/VmHWM/ {printf "%d", $2 / 1024}' "/proc/$server/status"; }
post() { curl -s -o /dev/null -w '%{http_code} ' "$@"; }

# Warm: each mode on a real 640×480 frame, twice.
for _ in 1 2; do
    post --data-binary "@$data/1.png" -H 'content-type: image/png' "$url/v1/roughness?mode=rgb"
    post -F "rgb=@$data/1.png" -F "depth=@$data/1_depth.png" "$url/v1/roughness?depth_scale=5000&fx=520.9&fy=521&cx=325.1&cy=249.7"
    post -F "depth=@$data/1_depth.png" "$url/v1/roughness?mode=geometric&depth_scale=5000&fx=520.9&fy=521&cx=325.1&cy=249.7"
done
sleep 2
warm=$(rss)
post -F "depth=@$work/depth_2048.png" "$url/v1/roughness?mode=geometric"
post --data-binary "@$work/rgb_2048.png" -H 'content-type: image/png' "$url/v1/roughness?mode=rgb"
echo
right_after=$(rss)
peak=$(hwm)
sleep "$idle"
after=$(rss)
echo "warm ${warm} MiB, peak ${peak} MiB, right after ${right_after} MiB, after ${idle} s idle ${after} MiB (+$((after - warm)) MiB)"
