"""Receive rates of `tre ros2`'s outputs at stock subscribers of other DDS implementations.

A ROS 2 peer built on a DDS implementation the node does not use, at its default settings:
Eclipse Cyclone DDS (`--dds cyclone`, the `cyclonedds` wheel; ROS 2 message types written out
in scripts/ros2_rates_cyclone.py) or a real rclpy node over eProsima Fast DDS, ROS 2's default
middleware (`--dds fastdds`, the `ros-*` wheels of ROS 2 Kilted; scripts/ros2_rates_rclpy.py).
It publishes real depth frames, their camera_info and odometry at a fixed rate, each frame
stamped with the wall clock when it is sent, and counts what arrives on the node's outputs: for
every output topic, how many of the sent frames came back and the latency from the frame's own
stamp (p50, p99).

    python scripts/ros2_rates.py --dds cyclone --domain 7 \
        --frames ../shared/data/real-rgbd-2/sevenscenes_redkitchen --hz 15 --count 90

with `tre ros2 --domain-id 7 --odom-topic /odom --sensor kinect_v1 ...` running
(scripts/ros2_rates.sh starts both). The result is one JSON object on stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from pathlib import Path

import numpy as np
import soak_table
from PIL import Image

TOPICS_OUT = (
    "roughness",
    "roughness/compressed",
    "uncertainty",
    "uncertainty/compressed",
    "traversal",
    "traversal/compressed",
    "grid_map",
    "occupancy",
)


def depth_le16(path: Path) -> tuple[int, int, bytes]:
    """Width, height and little-endian 16-bit pixels (16UC1) of a 16-bit depth PNG."""
    img = np.asarray(Image.open(path))
    if img.dtype != np.uint16 or img.ndim != 2:
        raise SystemExit(f"{path}: expected a 16-bit one-channel PNG")
    return img.shape[1], img.shape[0], img.astype("<u2").tobytes()


def quaternion(m: list[list[float]]) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix."""
    t = m[0][0] + m[1][1] + m[2][2]
    if t > 0:
        s = 2.0 * math.sqrt(t + 1.0)
        return ((m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, s / 4)
    i = max(range(3), key=lambda k: m[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i][i] - m[j][j] - m[k][k])
    q = [0.0, 0.0, 0.0]
    q[i] = s / 4
    q[j] = (m[j][i] + m[i][j]) / s
    q[k] = (m[k][i] + m[i][k]) / s
    return (q[0], q[1], q[2], (m[k][j] - m[j][k]) / s)


def load_frames(folder: Path, count: int, step: int) -> list[tuple[int, int, bytes, tuple]]:
    """(width, height, depth, pose) of `count` frames, every `step`-th of the folder."""
    stems = sorted(p.stem for p in (folder / "depth").glob("*.png"))[::step][:count]
    out = []
    for stem in stems:
        w, h, depth = depth_le16(folder / "depth" / f"{stem}.png")
        v = [float(s) for s in (folder / "poses" / f"{stem}.txt").read_text().split()]
        rot = [v[0:3], v[4:7], v[8:11]]
        out.append((w, h, depth, ((v[3], v[7], v[11]), quaternion(rot))))
    return out


def percentile(xs: list[float], p: float) -> float | None:
    """The nearest-rank percentile (scripts/soak_table.py's), `None` of nothing."""
    return soak_table.percentile(xs, p) if xs else None


class Tally:
    """Arrival times of each output topic's messages, by their stamp."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.seen: dict[str, dict[tuple[int, int], float]] = {t: {} for t in TOPICS_OUT}
        self.last = time.monotonic()

    def arrive(self, topic: str, stamp: tuple[int, int]) -> None:
        now = time.time()
        with self.lock:
            self.seen[topic].setdefault(stamp, now)
            self.last = time.monotonic()

    def drain(self, quiet_s: float, most_s: float) -> None:
        """Waits `quiet_s`, then until nothing has arrived for `quiet_s`; at most `most_s`."""
        end = time.monotonic() + most_s
        with self.lock:
            self.last = time.monotonic()
        while time.monotonic() < end:
            with self.lock:
                left = self.last + quiet_s - time.monotonic()
            if left <= 0:
                return
            time.sleep(min(left, 0.1))


def summary(sent: list[tuple[int, int]], tally: Tally, hz: float, meta: dict) -> dict:
    sent_at = {s: s[0] + s[1] * 1e-9 for s in sent}
    out = dict(meta, sent=len(sent), hz=hz, topics={})
    for topic, seen in tally.seen.items():
        got = [s for s in sent if s in seen]
        if not seen:
            continue
        lat = [1e3 * (seen[s] - sent_at[s]) for s in got]
        out["topics"][topic] = {
            "received": len(got),
            "fraction": round(len(got) / len(sent), 4) if sent else None,
            "latency_ms_p50": round(percentile(lat, 50), 1) if lat else None,
            "latency_ms_p99": round(percentile(lat, 99), 1) if lat else None,
            "latency_ms_max": round(max(lat), 1) if lat else None,
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dds", choices=["cyclone", "fastdds"], default="cyclone")
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--frames", type=Path, required=True, help="folder with depth/ and poses/")
    ap.add_argument("--count", type=int, default=90, help="frames to send")
    ap.add_argument("--step", type=int, default=1, help="send every step-th frame of the folder")
    ap.add_argument("--hz", type=float, default=15.0)
    ap.add_argument(
        "--reliability",
        choices=["reliable", "best-effort"],
        default="reliable",
        help="of the subscriptions to the outputs (the inputs are published reliable)",
    )
    ap.add_argument(
        "--subscribe",
        default=",".join(TOPICS_OUT),
        help="output topics to subscribe to, under /tre (a raw 640x480 image in the same socket "
        "buffer delays the small messages beside it)",
    )
    ap.add_argument("--fx", type=float, default=585.0)
    ap.add_argument("--fy", type=float, default=585.0)
    ap.add_argument("--cx", type=float, default=320.0)
    ap.add_argument("--cy", type=float, default=240.0)
    ap.add_argument("--discovery-s", type=float, default=30.0)
    ap.add_argument(
        "--drain-s",
        type=float,
        default=3.0,
        help="after the last frame, wait until nothing has arrived for this long",
    )
    ap.add_argument(
        "--drain-most-s", type=float, default=30.0, help="but no longer than this after it"
    )
    args = ap.parse_args()

    frames = load_frames(args.frames, args.count, args.step)
    if not frames:
        raise SystemExit(f"{args.frames}: no depth/*.png")
    if args.dds == "cyclone":
        from ros2_rates_cyclone import Peer
    else:
        from ros2_rates_rclpy import Peer
    tally = Tally()
    topics = [t for t in args.subscribe.split(",") if t]
    unknown = set(topics) - set(TOPICS_OUT)
    if unknown:
        raise SystemExit(f"--subscribe: unknown topics {sorted(unknown)}")
    peer = Peer(args.domain, args.reliability == "reliable", tally, topics)
    for w, h, depth, _ in frames:
        peer.prepare(w, h, depth)
    t0 = time.time()
    while not peer.matched():
        if time.time() - t0 > args.discovery_s:
            raise SystemExit(f"the node was not discovered in {args.discovery_s} s")
        time.sleep(0.05)
    # Give the other endpoints of the node (outputs) time to match too.
    time.sleep(1.0)
    sent, writes = [], []
    period = 1.0 / args.hz
    start = time.monotonic()
    for i in range(args.count):
        w, h, depth, pose = frames[i % len(frames)]
        target = start + i * period
        pause = target - time.monotonic()
        if pause > 0:
            time.sleep(pause)
        now = time.time_ns()
        stamp = (now // 1_000_000_000, now % 1_000_000_000)
        k = (args.fx, args.fy, args.cx, args.cy)
        peer.publish(stamp, w, h, depth, k, pose)
        writes.append(1e3 * (time.time() - now * 1e-9))
        sent.append(stamp)
    tally.drain(args.drain_s, args.drain_most_s)
    meta = {
        "dds": args.dds,
        "reliability": args.reliability,
        "frames": str(args.frames),
        # The peer's own share of each latency: serialising and writing the three inputs.
        "peer_write_ms_p50": round(percentile(writes, 50), 1),
    }
    json.dump(summary(sent, tally, args.hz, meta), sys.stdout, indent=1)
    sys.stdout.write("\n")
    peer.close()


if __name__ == "__main__":
    main()
