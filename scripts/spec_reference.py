"""Annotation spec v1 in plain numpy: an independent, slow and simple reference of the roughness
`tre annotate` and `--geometric spec` compute (docs/design.md), to check the Rust kernels
against on real frames (tests/it/spec_reference.rs).

    python scripts/spec_reference.py DEPTH.npy FX FY CX CY OUT.npy

DEPTH.npy: float depth in metres (≤ 0 or not finite: no data). OUT.npy: float64 roughness in
metres (NaN where the pixel has no point). Defaults of the spec: R 0.05 m, window half-width
cap 7 px, ε 0.015 m, segment angle 10°, edge band sigma 1.5 px; one label for all, LS normals.

Everything is written from the spec's definitions, with whole-array operations and a
union-find in Python; no code is shared with the Rust crates. Two choices are the
implementation's, as the spec leaves them open. A neighbour is within R when its squared
distance, computed in float32 on float32 coordinates ((dx² + dy²) + dz²), is at most R² in
float32: the same test in float64 puts a point that lies at R to the last bit on the other side
now and then, and one point more or less moves a centroid by up to R / n. And the window sums
within R are float32 sums, row by row and left to right: on sparse LiDAR most windows hold one
scan line, points on a line, whose plane (and so the segments and edges around them) is set by
the sums' rounding. Everything else is float64.
"""

import sys

import numpy as np

RADIUS_M = 0.05
MAX_HALF = 7
EPSILON_M = 0.015
SEGMENT_ANGLE_DEG = 10.0
EDGE_SIGMA_PX = 1.5


def back_project(depth, fx, fy, cx, cy):
    """Points (h, w, 3) in the camera frame; NaN where there is no depth."""
    h, w = depth.shape
    valid = np.isfinite(depth) & (depth > 0)
    z = np.where(valid, depth, np.nan)
    u = np.arange(w, dtype=np.float64)[None, :]
    v = np.arange(h, dtype=np.float64)[:, None]
    return np.stack([(u - cx) / fx * z, (v - cy) / fy * z, z], axis=-1), valid


def shifted(a, dx, dy, fill):
    """out[y, x] = a[y + dy, x + dx], `fill` outside the image."""
    h, w = a.shape[:2]
    out = np.full_like(a, fill)
    ys, yd = slice(max(dy, 0), h + min(dy, 0)), slice(max(-dy, 0), h + min(-dy, 0))
    xs, xd = slice(max(dx, 0), w + min(dx, 0)), slice(max(-dx, 0), w + min(-dx, 0))
    out[yd, xd] = a[ys, xs]
    return out


def window_moments(pts, valid, half, radius_test):
    """Count, Σd and Σddᵀ (d = q − p) over each pixel's window of half-width `half` (per
    pixel), of the valid points within R (`radius_test`; else all of them), summed row by row,
    left to right: in float32 within R, in float64 without the radius."""
    h, w = valid.shape
    dtype = np.float32 if radius_test else np.float64
    pts_t = pts.astype(dtype)
    n = np.zeros((h, w))
    s1 = np.zeros((h, w, 3), dtype=dtype)
    s2 = np.zeros((h, w, 3, 3), dtype=dtype)
    r2 = np.float32(RADIUS_M) * np.float32(RADIUS_M)
    reach = int(half[valid].max(initial=0))
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            d = shifted(pts_t, dx, dy, np.nan) - pts_t
            keep = valid & (max(abs(dx), abs(dy)) <= half) & np.isfinite(d[..., 2])
            if radius_test:
                d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]
                keep &= (d2 + d[..., 2] * d[..., 2]) <= r2
            d = np.where(keep[..., None], d, dtype(0))
            n += keep
            s1 += d
            s2 += d[..., :, None] * d[..., None, :]
    return n, s1.astype(np.float64), s2.astype(np.float64)


def plane_normals(n, s1, s2):
    """Unit normals of the least-squares planes (smallest eigenvector of the covariance), NaN
    for fewer than 3 points or where the two smallest eigenvalues of the covariance, scaled by
    its largest entry, are not 1e-6 apart (no unique plane)."""
    safe = np.maximum(n, 1.0)
    mean = s1 / safe[..., None]
    cov = s2 / safe[..., None, None] - mean[..., :, None] * mean[..., None, :]
    scale = np.abs(cov).max(axis=(-2, -1))
    ok = (n >= 3) & (scale > 0) & np.isfinite(scale)
    scaled = np.where(ok[..., None, None], cov / np.where(ok, scale, 1.0)[..., None, None], 0.0)
    values, vectors = np.linalg.eigh(scaled)
    ok &= values[..., 1] - values[..., 0] > 1e-6
    return np.where(ok[..., None], vectors[..., :, 0], np.nan)


def local_planes(pts, valid, fx):
    """LS normals (facing the camera) and the window centroids of each valid pixel."""
    with np.errstate(divide="ignore", invalid="ignore"):
        half = np.ceil(RADIUS_M * fx / pts[..., 2])
    half = np.where(np.isfinite(half), np.clip(half, 1, MAX_HALF), MAX_HALF).astype(int)
    n, s1, s2 = window_moments(pts, valid, half, radius_test=True)
    centroids = pts + s1 / np.maximum(n, 1.0)[..., None]
    normals = plane_normals(n, s1, s2)
    # Too sparse within R: the 3×3, then the 5×5, window's valid points, without the radius.
    for fallback in (1, 2):
        lacking = valid & ~np.isfinite(normals[..., 0])
        if not lacking.any():
            break
        m = window_moments(pts, valid, np.full(valid.shape, fallback), radius_test=False)
        normals = np.where(lacking[..., None], plane_normals(*m), normals)
    facing_away = np.sum(normals * pts, axis=-1) > 0
    normals = np.where(facing_away[..., None], -normals, normals)
    return normals, centroids


def find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


def segments(pts, valid, normals):
    """Segment ids (0: no point): 4-connected components of neighbours whose normals lie within
    the segment angle and whose points lie within ε of each other's planes."""
    h, w = valid.shape
    cos_max = np.cos(np.radians(SEGMENT_ANGLE_DEG))
    parent = list(range(h * w))
    for dx, dy in ((1, 0), (0, 1)):
        q, m = shifted(pts, dx, dy, np.nan), shifted(normals, dx, dy, np.nan)
        with np.errstate(invalid="ignore"):
            joins = (
                valid
                & shifted(valid, dx, dy, False)
                & (np.sum(normals * m, axis=-1) > cos_max)
                & (np.abs(np.sum(normals * (q - pts), axis=-1)) < EPSILON_M)
                & (np.abs(np.sum(m * (pts - q), axis=-1)) < EPSILON_M)
            )
        for i in np.flatnonzero(joins).tolist():
            a, b = find(parent, i), find(parent, i + dy * w + dx)
            if a != b:
                parent[max(a, b)] = min(a, b)
    roots = np.array([find(parent, i) for i in range(h * w)]).reshape(h, w)
    return np.where(valid, roots + 1, 0)


def edge_transient(pts, valid, ids):
    """The edge term of the boundary pixels (edge weight W: the largest distance to a valid
    8-neighbour; W ≥ ε: W, W > ε/2: 2W, else 0), spread as e·exp(−d²/(2 sigma²)) over
    d ≤ 3 sigma (the largest where spreads overlap)."""
    boundary = np.zeros(valid.shape, dtype=bool)
    weight = np.zeros(valid.shape)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            other = shifted(ids, dx, dy, 0)
            boundary |= (ids != 0) & (other != 0) & (other != ids)
            if (dx, dy) != (0, 0):
                dist = np.linalg.norm(shifted(pts, dx, dy, np.nan) - pts, axis=-1)
                weight = np.fmax(weight, np.where(np.isnan(dist), 0.0, dist))
    weight = np.where(boundary, weight, 0.0)
    term = np.where(
        weight >= EPSILON_M, weight, np.where(weight > 0.5 * EPSILON_M, 2 * weight, 0.0)
    )
    reach = int(np.floor(3 * EDGE_SIGMA_PX))
    out = np.zeros(valid.shape)
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            d2 = dx * dx + dy * dy
            if d2 <= 9 * EDGE_SIGMA_PX**2:
                wt = np.exp(-d2 / (2 * EDGE_SIGMA_PX**2))
                out = np.maximum(out, shifted(term, dx, dy, 0.0) * wt)
    return np.where(valid, out, 0.0)


def spec_roughness(depth, fx, fy, cx, cy):
    """Roughness r = max(surface term, edge transient), metres; NaN where there is no point."""
    pts, valid = back_project(np.asarray(depth, dtype=np.float64), fx, fy, cx, cy)
    normals, centroids = local_planes(pts, valid, fx)
    surface = np.abs(np.sum(normals * (pts - centroids), axis=-1))
    edge = edge_transient(pts, valid, segments(pts, valid, normals))
    return np.where(valid, np.fmax(surface, edge), np.nan)


def main(argv):
    if len(argv) != 7:
        sys.exit(__doc__.split("\n\n")[1])
    depth = np.load(argv[1])
    fx, fy, cx, cy = (float(v) for v in argv[2:6])
    np.save(argv[6], spec_roughness(depth, fx, fy, cx, cy))


if __name__ == "__main__":
    main(sys.argv)
