"""The surface term alone, in vectorised numpy: the peer the camera-rate figures are measured
against (docs/benchmarks.md). Per pixel, the least-squares plane of the valid points in the
15x15 window around it (summed-area tables of the moments, `np.linalg.eigh` on every pixel's
covariance at once) and the distance of the pixel's point to it. No step term, no noise model,
no uncertainty, no three-state map: less than what `tre serve` answers.

    python scripts/surface_peer.py CAMERA.json DEPTH.png [DEPTH.png ...]

Prints the in-process time of each frame (decoding excluded) and their median, milliseconds.
"""

import json
import sys
import time

import numpy as np
from PIL import Image

HALF = 7
MIN_POINTS = 6


def surface_term(depth, fx, fy, cx, cy):
    """Roughness (metres) of the surface term; NaN where the pixel has no point or no plane."""
    h, w = depth.shape
    valid = np.isfinite(depth) & (depth > 0)
    z = np.where(valid, depth, 0.0)
    u = np.arange(w, dtype=np.float64)[None, :]
    v = np.arange(h, dtype=np.float64)[:, None]
    pts = np.stack([(u - cx) / fx * z, (v - cy) / fy * z, z], axis=-1)
    origin = pts[valid].mean(axis=0) if valid.any() else np.zeros(3)
    d = np.where(valid[..., None], pts - origin, 0.0)
    iu = np.triu_indices(3)
    moments = np.concatenate(
        [
            valid[..., None].astype(np.float64),
            d,
            (d[..., :, None] * d[..., None, :])[..., iu[0], iu[1]],
        ],
        axis=-1,
    )
    table = np.zeros((h + 1, w + 1, moments.shape[-1]))
    table[1:, 1:] = moments.cumsum(axis=0).cumsum(axis=1)
    y0 = np.clip(np.arange(h) - HALF, 0, h)
    y1 = np.clip(np.arange(h) + HALF + 1, 0, h)
    x0 = np.clip(np.arange(w) - HALF, 0, w)
    x1 = np.clip(np.arange(w) + HALF + 1, 0, w)
    s = table[y1][:, x1] - table[y0][:, x1] - table[y1][:, x0] + table[y0][:, x0]
    n = np.maximum(s[..., 0], 1.0)
    mean = s[..., 1:4] / n[..., None]
    cov = np.empty((h, w, 3, 3))
    cov[..., iu[0], iu[1]] = s[..., 4:] / n[..., None]
    cov[..., iu[1], iu[0]] = cov[..., iu[0], iu[1]]
    cov -= mean[..., :, None] * mean[..., None, :]
    _, vectors = np.linalg.eigh(cov)
    normal = vectors[..., :, 0]
    r = np.abs(np.einsum("hwi,hwi->hw", normal, d - mean))
    return np.where(valid & (s[..., 0] >= MIN_POINTS), r, np.nan)


def main():
    with open(sys.argv[1]) as f:
        camera = json.load(f)
    scale = float(camera.get("depth_scale", 1000.0))
    k = [float(camera[key]) for key in ("fx", "fy", "cx", "cy")]
    times = []
    for path in sys.argv[2:]:
        depth = np.asarray(Image.open(path), dtype=np.float64) / scale
        start = time.perf_counter()
        surface_term(depth, *k)
        times.append(1e3 * (time.perf_counter() - start))
        print(f"{path}\t{times[-1]:.1f} ms")
    print(f"median\t{float(np.median(times)):.1f} ms\t{len(times)} frames")


if __name__ == "__main__":
    main()
