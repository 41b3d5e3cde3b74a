#!/usr/bin/env python3
"""The floor figures of a map written by `tre map` (docs/map.md), and, given a second map of the
same frames in another order, how far the two agree; or, with --lane SEQUENCE, the lane ahead
of the sequence's first camera.

    python3 scripts/map_figures.py out/kitchen-map [out/kitchen-map-reverse]
    python3 scripts/map_figures.py out/road-map --lane ../shared/data/real-rgbd-3/kitti_0023_stereo

Floor cells: seen cells within 8 cm above the map's 2nd-percentile elevation (the floor level).
The lane ahead: cells whose centre lies 5 to 20 m ahead of the first camera and within 1.5 m of
its optical axis, both measured in the map's level plane (unseen cells count as unknown).
Needs numpy.
"""

import json
import os
import sys

import numpy as np


def load(d):
    layers = {
        n: np.load(f"{d}/{n}.npy")
        for n in ["elevation", "variance", "count", "roughness", "slope", "step", "traversal"]
    }
    with open(f"{d}/map.json") as f:
        return layers, json.load(f)


def floor_figures(d):
    layers, _ = load(d)
    seen = layers["count"] > 0
    lo = np.percentile(layers["elevation"][seen], 2)
    f = seen & (layers["elevation"] < lo + 0.08)
    e = layers["elevation"][f]
    rows, cols = np.nonzero(f)
    a = np.c_[cols * 0.04, rows * 0.04, np.ones_like(e)]
    coef = np.linalg.lstsq(a, e, rcond=None)[0]
    resid = e - a @ coef
    t = layers["traversal"][f]
    r = layers["roughness"][f]
    print(
        f"floor cells {f.sum()}; roughness < 1 cm {(r < 0.01).mean():.1%} "
        f"(median {np.nanmedian(r) * 100:.2f} cm)"
    )
    print(
        f"floor height spread p5-p95 {np.subtract(*np.percentile(e, [95, 5])) * 100:.1f} cm; "
        f"tilt {np.degrees(np.arctan(np.hypot(coef[0], coef[1]))):.2f} deg, "
        f"after removing it {np.subtract(*np.percentile(resid, [95, 5])) * 100:.1f} cm"
    )
    print(
        f"floor traversable {(t == 1).mean():.1%}, hazard {(t == 2).mean():.1%}, "
        f"unknown {(t == 0).mean():.1%}"
    )
    sigma = np.sqrt(layers["variance"][f])
    print(
        f"floor elevation std {e.std() * 100:.2f} cm ({resid.std() * 100:.2f} cm about its "
        f"plane); median cell sigma {np.median(sigma) * 100:.2f} cm"
    )


def cells(d):
    layers, j = load(d)
    (ox, oy), side = j["origin_cell"], j["side_cells"]
    out = {}
    for r, c in zip(*np.nonzero(np.isfinite(layers["elevation"])), strict=True):
        out[(ox + c, oy + side - 1 - r)] = (
            layers["elevation"][r, c],
            layers["variance"][r, c],
            layers["traversal"][r, c],
        )
    return out


def agreement(a, b):
    a, b = cells(a), cells(b)
    common = set(a) & set(b)
    d = np.array([abs(a[k][0] - b[k][0]) for k in common])
    s = np.array([np.sqrt(a[k][1] + b[k][1]) for k in common])
    same = np.mean([a[k][2] == b[k][2] for k in common])
    print(
        f"cells seen in both {len(common)} (of {len(a)} and {len(b)}); within 3 sigma "
        f"{(d <= 3 * s).mean():.1%}; same three-state {same:.1%}"
    )


def lane_figures(d, sequence):
    layers, j = load(d)
    poses = sorted(f for f in os.listdir(f"{sequence}/poses") if f.endswith(".txt"))
    pose = np.loadtxt(f"{sequence}/poses/{poses[0]}").reshape(4, 4)
    m = np.array(j["map_from_world"]).reshape(3, 3)
    cam = (m @ pose[:3, 3])[:2]
    fwd = (m @ pose[:3, :3] @ [0, 0, 1])[:2]
    fwd /= np.linalg.norm(fwd)
    right = np.array([fwd[1], -fwd[0]])
    (ox, oy), side, cell = j["origin_cell"], j["side_cells"], j["cell_m"]
    rows, cols = np.mgrid[0:side, 0:side]
    xy = np.stack([(ox + cols + 0.5) * cell, (oy + side - 1 - rows + 0.5) * cell], -1) - cam
    ahead, across = xy @ fwd, xy @ right
    lane = (ahead >= 5) & (ahead <= 20) & (np.abs(across) <= 1.5)
    t = layers["traversal"][lane]
    seen = layers["count"][lane] > 0
    print(
        f"lane cells {lane.sum()} ({seen.mean():.1%} seen): traversable {(t == 1).mean():.1%}, "
        f"hazard {(t == 2).mean():.1%}, unknown {(t == 0).mean():.1%}"
    )


if __name__ == "__main__":
    if len(sys.argv) > 3 and sys.argv[2] == "--lane":
        lane_figures(sys.argv[1], sys.argv[3])
    else:
        floor_figures(sys.argv[1])
        if len(sys.argv) > 2:
            agreement(sys.argv[1], sys.argv[2])
