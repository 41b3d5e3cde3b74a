#!/usr/bin/env python3
"""The floor figures of a map written by `tre map` (docs/map.md), and, given a second map of the
same frames in another order, how far the two agree.

    python3 scripts/map_figures.py out/kitchen-map [out/kitchen-map-reverse]

Floor cells: seen cells within 8 cm above the map's 2nd-percentile elevation (the floor level).
Needs numpy.
"""

import json
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


if __name__ == "__main__":
    floor_figures(sys.argv[1])
    if len(sys.argv) > 2:
        agreement(sys.argv[1], sys.argv[2])
