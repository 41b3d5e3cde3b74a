"""DSAC normals exactly as serving computes them, in numpy, operation by operation.

This is the reference for the serving estimator defined once in
`crates/tre-core/src/geometry/dsac/SAMPLER.md` (the sampler contract; the parity vectors are
`vectors.json` beside it), with `crates/tre-core/src/geometry/fastmath.rs` and
`crates/tre-core/src/geometry/hash.rs` (docs/design.md, "DSAC normals").
Every float32 step is one numpy float32 operation and every float64 step one float64 operation, in
the documented order; numpy never fuses a multiply and an add across two operations, so the hash,
ρ, the sampler's triples and the float32 scores are bit-identical to serving.

Step 5 (the least-squares refit) takes the smallest eigenvector of the inliers' covariance from
`numpy.linalg.eigh`, not from serving's solver (Halley's method on the characteristic cubic); both
are accurate to rounding, so normals agree to about 1e-14 on well-conditioned windows.
`NORMAL_TOLERANCE` is the bound the shared test vectors are checked with.

Speed does not matter here: pixels are processed one at a time, for tiny frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from numpy.typing import ArrayLike, NDArray

MASK64 = (1 << 64) - 1
"""All bits of a u64."""

CANDIDATES = 49
"""Candidates per pixel (7 × 7), index `k = (dy + 3)·7 + (dx + 3)`."""
WINDOW = 7
"""Side of the candidate window."""
CENTRE = CANDIDATES // 2
"""The candidate that is the pixel itself."""
BLOCK = 8
"""Lanes of one block of serving's lane arrays."""
LANES = 56
"""Lanes of the per-pixel lane arrays: the candidates padded to whole blocks."""

NORMAL_TOLERANCE = 1e-9
"""Largest per-coordinate difference allowed between serving's normals and this reference's.

Serving and `eigh` solve the same symmetric 3×3 eigenproblem; each is backward stable, so their
unit eigenvectors differ by about 1e-16 · λ_max / (λ_mid − λ_min), i.e. 1e-15 to 1e-13 for the
windows of the test vectors. 1e-9 leaves room for worse-conditioned windows.
"""

EIGEN_GAP = 1e-6
"""Serving's degeneracy test: an LS plane needs λ_mid − λ_min > 1e-6 of the largest entry."""


# --- hash.rs --------------------------------------------------------------------------------------


def splitmix64(x: int) -> int:
    """One SplitMix64 step as a mixing function, on Python ints masked to 64 bits."""
    z = (x + 0x9E3779B97F4A7C15) & MASK64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
    return z ^ (z >> 31)


def uniform_hash(seed: int, pixel: int, hypothesis: int, draw: int) -> int:
    """`splitmix64(splitmix64(splitmix64(seed) ^ pixel) ^ (hypothesis << 8 | draw))`."""
    if not (0 <= seed <= MASK64 and 0 <= pixel <= MASK64):
        raise ValueError("seed and pixel must be u64")
    if not (0 <= hypothesis < 1 << 32 and 0 <= draw < 1 << 32):
        raise ValueError("hypothesis and draw must be u32")
    key = ((hypothesis << 8) | draw) & MASK64
    return splitmix64(splitmix64(splitmix64(seed) ^ pixel) ^ key)


def uniform(seed: int, pixel: int, hypothesis: int, draw: int) -> float:
    """The uniform number in [0, 1) for one draw: the top 53 bits of the hash times 2⁻⁵³."""
    return float(uniform_hash(seed, pixel, hypothesis, draw) >> 11) * 2.0**-53


# --- fastmath.rs ----------------------------------------------------------------------------------


def f32_literal(text: str) -> np.float32:
    """The float32 nearest to the decimal `text` (ties to even), as a Rust `f32` literal is.

    Going through float64 could round twice; this rounds the exact decimal once.
    """
    exact = Fraction(text.replace("_", ""))
    guess = np.float32(float(exact))
    around = [
        np.nextafter(guess, np.float32(-np.inf)),
        guess,
        np.nextafter(guess, np.float32(np.inf)),
    ]
    return min(
        around,
        key=lambda c: (abs(Fraction(float(c)) - exact), int(np.array(c).view(np.uint32)) & 1),
    )


ROUND = np.float32(12582912.0)
"""1.5 · 2²³: `(y + ROUND) − ROUND` rounds `y` to an integer (ties to even) for |y| < 2²²."""
LOG2_E_F32 = f32_literal("1.44269504088896340735992468100189214")
"""log₂ e rounded to float32 (Rust's `std::f32::consts::LOG2_E`)."""
LOG2_E_F64 = float(Fraction("1.44269504088896340735992468100189214"))
"""log₂ e rounded to float64 (Rust's `std::f64::consts::LOG2_E`)."""
LN2_HI = f32_literal("0.693_359_4")
"""ln 2, high part (355/512 exactly)."""
LN2_LO = f32_literal("-2.121_944_4e-4")
"""ln 2 − `LN2_HI`."""
EXP_POLY = (
    f32_literal("1.987_569_1e-4"),
    f32_literal("1.398_199_9e-3"),
    f32_literal("8.333_452e-3"),
    f32_literal("4.166_579_6e-2"),
    f32_literal("1.666_666_5e-1"),
    np.float32(0.5),
)
"""Coefficients E₀ … E₅ of `exp`'s polynomial (Cephes `expf`)."""
EXP2_RATIONAL = (f32_literal("0.039_936_27"), f32_literal("0.346_571_37"))
"""`A` and `B` of the rational approximation of 2ᶠ in `recip_one_plus_exp2`."""
EXP_DOMAIN = (np.float32(-87.0), np.float32(88.0))
"""Inputs of `exp` are clamped to this range."""
LOGISTIC2_DOMAIN = (np.float32(-120.0), np.float32(120.0))
"""Inputs of `recip_one_plus_exp2` are clamped to this range."""
_ONE = np.float32(1.0)
_ZERO = np.float32(0.0)


def _as_f32(x: ArrayLike) -> NDArray[np.float32]:
    """`x` as a float32 array with at least one dimension (so uint32 arithmetic wraps quietly)."""
    return np.atleast_1d(np.asarray(x, dtype=np.float32)).copy()


def _pow2_of_rounded(r: NDArray[np.float32]) -> NDArray[np.float32]:
    """2ⁿ for `r = n + ROUND`: float32 bits `(bits(r) + 127) << 23`, wrapping u32 arithmetic."""
    bits = r.view(np.uint32)
    return ((bits + np.uint32(127)) << np.uint32(23)).view(np.float32)


def fast_exp_f32(x: ArrayLike) -> NDArray[np.float32]:
    """fastmath::exp: eˣ in float32 with relative error below 2e-7; NaN gives NaN.

    `x ← min(max(x, −87), 88)` (NaN kept); `r = x·log₂e + ROUND`; `n = r − ROUND`;
    `f = (x − n·LN2_HI) − n·LN2_LO`; `p = (((((E₀f + E₁)f + E₂)f + E₃)f + E₄)f + E₅)·(f·f) + f + 1`;
    result `p · 2ⁿ`.
    """
    shape = np.shape(x)
    x = _as_f32(x)
    lo, hi = EXP_DOMAIN
    with np.errstate(all="ignore"):
        x = np.where(x < lo, lo, x)
        x = np.where(x > hi, hi, x)
        r = x * LOG2_E_F32 + ROUND
        n = r - ROUND
        f = (x - n * LN2_HI) - n * LN2_LO
        e0, e1, e2, e3, e4, e5 = EXP_POLY
        poly = ((((e0 * f + e1) * f + e2) * f + e3) * f + e4) * f + e5
        p = poly * (f * f) + f + _ONE
        return (p * _pow2_of_rounded(r)).reshape(shape)


def recip_one_plus_exp2_f32(y: ArrayLike) -> NDArray[np.float32]:
    """fastmath::recip_one_plus_exp2: `1 / (1 + 2ʸ)` in float32, relative error below 7e-7.

    `y ← max(min(y, 120), −120)` (NaN taken as +∞); `r = y + ROUND`; `n = r − ROUND`; `f = y − n`;
    `e = A·(f·f) + 1`; `o = B·f`; `q = e − o`; result `q / (q + (e + o)·2ⁿ)`.
    """
    shape = np.shape(y)
    y = _as_f32(y)
    lo, hi = LOGISTIC2_DOMAIN
    with np.errstate(all="ignore"):
        y = np.where(y < hi, y, hi)
        y = np.where(y > lo, y, lo)
        r = y + ROUND
        n = r - ROUND
        f = y - n
        a, b = EXP2_RATIONAL
        e = a * (f * f) + _ONE
        o = b * f
        q = e - o
        return (q / (q + (e + o) * _pow2_of_rounded(r))).reshape(shape)


def sum_block(a: ArrayLike) -> np.float32:
    """fastmath::sum_block: `((a₀ + a₄) + (a₂ + a₆)) + ((a₁ + a₅) + (a₃ + a₇))` in float32."""
    a = np.asarray(a, dtype=np.float32)
    if a.shape != (BLOCK,):
        raise ValueError(f"a block has {BLOCK} lanes, got shape {a.shape}")
    h = a[:4] + a[4:]
    q = h[:2] + h[2:]
    return q[0] + q[1]


def lane_sum(v: ArrayLike) -> np.float32:
    """Serving's lane sum: the 49 values then seven zeros as seven blocks of eight, accumulated
    per lane (`a_l = ((0 + v_l) + v_{8+l}) + … + v_{48+l}`), then `sum_block`."""
    lanes = np.zeros(LANES, dtype=np.float32)
    lanes[:CANDIDATES] = np.asarray(v, dtype=np.float32)
    acc = np.zeros(BLOCK, dtype=np.float32)
    for b in range(LANES // BLOCK):
        acc = acc + lanes[b * BLOCK : (b + 1) * BLOCK]
    return sum_block(acc)


# --- dsac.rs, step 1: candidates ------------------------------------------------------------------


@dataclass(frozen=True)
class DsacConfig:
    """Sampler and scorer settings (serving's `DsacConfig`)."""

    hypotheses: int = 12
    """Hypotheses per pixel, K."""
    inlier_threshold_m: float = 0.01
    """Inlier threshold τ, metres."""
    softness: float = 5.0
    """β = softness / τ."""
    seed: int = 0
    """Seed of the per-request random stream (u64)."""


def candidate_offset(k: int) -> tuple[int, int]:
    """The pixel offset `(dx, dy)` of candidate `k`."""
    return k % WINDOW - 3, k // WINDOW - 3


def is_valid_point(p: ArrayLike) -> bool:
    """A real point in front of the camera: finite coordinates and z > 0."""
    x, y, z = (float(c) for c in np.asarray(p, dtype=np.float64))
    return z > 0.0 and math.isfinite(z) and math.isfinite(x) and math.isfinite(y)


def window_candidates(points: NDArray[np.float64], x: int, y: int) -> NDArray[np.float64]:
    """The 49 candidate points of pixel `(x, y)` of an H×W×3 point map; NaN where invalid or
    outside the image."""
    h, w, _ = points.shape
    out = np.full((CANDIDATES, 3), np.nan)
    for k in range(CANDIDATES):
        dx, dy = candidate_offset(k)
        cx, cy = x + dx, y + dy
        if 0 <= cx < w and 0 <= cy < h and is_valid_point(points[cy, cx]):
            out[k] = points[cy, cx]
    return out


def valid_mask(cands: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Which of the 49 candidates hold a valid point."""
    return np.array([is_valid_point(q) for q in cands], dtype=bool)


# --- step 2: ρ ------------------------------------------------------------------------------------


def candidate_probabilities(logits49: ArrayLike, valid49: ArrayLike) -> NDArray[np.float64]:
    """ρ: the float32 softmax (with `fast_exp_f32`) of the logits over the usable candidates
    (valid, finite logit), 0 elsewhere, widened exactly to float64. All 0 when none is usable."""
    logits = np.asarray(logits49, dtype=np.float32)
    valid = np.asarray(valid49, dtype=bool)
    if logits.shape != (CANDIDATES,) or valid.shape != (CANDIDATES,):
        raise ValueError("logits and valid need 49 entries each")
    usable = valid & np.isfinite(logits)
    if not usable.any():
        return np.zeros(CANDIDATES)
    m = logits[usable].max()
    with np.errstate(all="ignore"):
        e = np.where(usable, fast_exp_f32(logits - m), _ZERO)
    total = lane_sum(e)
    rho = e / total
    return rho.astype(np.float64)


# --- step 3: sampler ------------------------------------------------------------------------------


def sample_triple(
    rho: ArrayLike, seed: int, pixel: int, hypothesis: int
) -> tuple[int, int, int] | None:
    """Three distinct candidates drawn from ρ by the documented linear definition (float64):
    draw `d` takes the smallest undrawn `k` with `ρ_k > 0` and `t < F_d(k)`, else the largest
    undrawn `k` with `ρ_k > 0`. `None` when the remaining mass is not positive or nothing is left.
    """
    rho = np.asarray(rho, dtype=np.float64)
    if rho.shape != (CANDIDATES,):
        raise ValueError("rho needs 49 entries")
    ks = np.arange(CANDIDATES)
    prefix = np.empty(CANDIDATES)
    acc = np.float64(0.0)
    for k in range(CANDIDATES):
        acc = acc + rho[k]
        prefix[k] = acc
    drawn: list[int] = []
    total = prefix[CANDIDATES - 1]
    with np.errstate(all="ignore"):
        for d in range(3):
            if drawn:
                total = total - rho[drawn[-1]]
            if not total > 0.0:
                return None
            t = np.float64(uniform(seed, pixel, hypothesis, d)) * total
            f = prefix.copy()
            for e in drawn:
                f = f - np.where(ks >= e, rho[e], 0.0)
            eligible = (rho > 0.0) & ~np.isin(ks, drawn)
            hits = np.flatnonzero(eligible & (t < f))
            if hits.size:
                drawn.append(int(hits[0]))
            elif eligible.any():
                drawn.append(int(np.flatnonzero(eligible)[-1]))
            else:
                return None
    return drawn[0], drawn[1], drawn[2]


# --- planes (plane.rs), float64 -------------------------------------------------------------------

Vec3 = tuple[float, float, float]


def _vec(p: ArrayLike) -> Vec3:
    x, y, z = (float(c) for c in np.asarray(p, dtype=np.float64))
    return x, y, z


def _sub(a: Vec3, b: Vec3) -> Vec3:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


def _dot(a: Vec3, b: Vec3) -> float:
    return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]


def _cross(a: Vec3, b: Vec3) -> Vec3:
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def _norm(a: Vec3) -> float:
    return math.sqrt(_dot(a, a))


@dataclass(frozen=True)
class Plane:
    """A plane through `centroid` with unit `normal` (float64)."""

    centroid: Vec3
    normal: Vec3

    def distance(self, p: ArrayLike) -> float:
        """Eq. 1: `|n · (p − c)|`, metres."""
        return abs(_dot(self.normal, _sub(_vec(p), self.centroid)))


def plane_through(a: ArrayLike, b: ArrayLike, c: ArrayLike) -> Plane | None:
    """`Plane::through`: the plane through three points (centroid `a`, normal `ab × ac / |…|`),
    or `None` when `|ab × ac| ≤ 1e-9·|ab|·|ac|` (nearly collinear) or not finite."""
    a, b, c = _vec(a), _vec(b), _vec(c)
    ab, ac = _sub(b, a), _sub(c, a)
    n = _cross(ab, ac)
    length = _norm(n)
    if not (length > 1e-9 * _norm(ab) * _norm(ac)) or not math.isfinite(length):
        return None
    return Plane(centroid=a, normal=(n[0] / length, n[1] / length, n[2] / length))


def orient_towards_camera(normal: Vec3, point: Vec3) -> Vec3:
    """Flips `normal` if `normal · point > 0`, so that it faces a camera at the origin."""
    if _dot(normal, point) > 0.0:
        return -normal[0], -normal[1], -normal[2]
    return normal


@dataclass(frozen=True)
class LsFit:
    """A least-squares normal and how far its eigenvalue gap is from serving's threshold."""

    normal: Vec3 | None
    """Unit normal of the smallest eigenvalue, or `None` (fewer than 3 points, degenerate)."""
    gap: float | None
    """`λ_mid − λ_min` of the covariance scaled to a largest entry of 1 (None: not computed)."""


def ls_normal(offsets: list[Vec3]) -> LsFit:
    """`Moments::fit`: the covariance of `offsets` (moments accumulated in the order given,
    as serving does), its smallest eigenvector from `numpy.linalg.eigh`."""
    if len(offsets) < 3:
        return LsFit(None, None)
    s = [0.0, 0.0, 0.0]
    sq = [0.0] * 6
    for d in offsets:
        s = [s[0] + d[0], s[1] + d[1], s[2] + d[2]]
        for i, (u, v) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
            sq[i] = sq[i] + d[u] * d[v]
    n = float(len(offsets))
    m = (s[0] / n, s[1] / n, s[2] / n)
    xx, xy, xz = sq[0] / n - m[0] * m[0], sq[1] / n - m[0] * m[1], sq[2] / n - m[0] * m[2]
    yy, yz, zz = sq[3] / n - m[1] * m[1], sq[4] / n - m[1] * m[2], sq[5] / n - m[2] * m[2]
    cov = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    scale = float(np.abs(cov).max())
    if not (scale > 0.0) or not math.isfinite(scale):
        return LsFit(None, None)
    values, vectors = np.linalg.eigh(cov * (1.0 / scale))
    gap = float(values[1] - values[0])
    if not gap > EIGEN_GAP:
        return LsFit(None, gap)
    v = _vec(vectors[:, 0])
    length = _norm(v)
    return LsFit((v[0] / length, v[1] / length, v[2] / length), gap)


# --- steps 4 and 5: scores, best, refit -----------------------------------------------------------


def score_f32(cands: NDArray[np.float64], p: Vec3, plane: Plane, config: DsacConfig) -> np.float32:
    """The float32 soft inlier count of `plane` over the valid candidates (step 4)."""
    tau = config.inlier_threshold_m
    g = config.softness / tau * LOG2_E_F64
    m = (plane.normal[0] * g, plane.normal[1] * g, plane.normal[2] * g)
    u = _sub(plane.centroid, p)
    o = (m[0] * u[0] + m[1] * u[1]) + m[2] * u[2]
    n32 = np.array(m, dtype=np.float64).astype(np.float32)
    o32 = np.float32(o)
    gt = g * tau
    tau32 = np.float32(gt if gt < 120.0 else 120.0)
    valid = valid_mask(cands)
    with np.errstate(all="ignore"):
        rel = (cands - np.array(p)).astype(np.float32)
    rel = np.where(valid[:, None], rel, _ZERO)
    s = ((n32[0] * rel[:, 0] + n32[1] * rel[:, 1]) + n32[2] * rel[:, 2]) - o32
    y = np.abs(s) - tau32
    v = np.where(valid, recip_one_plus_exp2_f32(y), _ZERO)
    return lane_sum(v)


@dataclass(frozen=True)
class PixelHypotheses:
    """One pixel's DSAC outcome (serving's `PixelHypotheses`)."""

    triples: list[tuple[int, int, int] | None]
    """Sampled triples, in hypothesis order."""
    scores: list[np.float32]
    """float32 soft inlier scores (−∞ for a missing triple or a degenerate plane)."""
    best: int | None
    """First hypothesis with the largest score (None if all are −∞)."""
    normal: Vec3 | None
    """LS refit on the best plane's inliers, oriented towards the camera."""
    fit: LsFit | None
    """The refit (for checking how far from serving's thresholds it is)."""


def refit(cands: NDArray[np.float64], p: Vec3, plane: Plane, tau: float) -> tuple[Vec3, LsFit]:
    """Step 5: LS plane of the inliers (`distance < τ`, moments of `q_k − p` in `k` order); the
    hypothesis normal if that is degenerate; flipped to face the camera."""
    offsets = [_sub(_vec(q), p) for q in cands if plane.distance(q) < tau]
    fit = ls_normal(offsets)
    normal = fit.normal if fit.normal is not None else plane.normal
    return orient_towards_camera(normal, p), fit


def pixel_hypotheses(
    cands: NDArray[np.float64], rho: ArrayLike, pixel: int, config: DsacConfig
) -> PixelHypotheses:
    """Samples, scores and refits one pixel given its 49 candidates (NaN: invalid) and ρ."""
    centre = cands[CENTRE]
    p = _vec(centre) if is_valid_point(centre) else (0.0, 0.0, 0.0)
    triples: list[tuple[int, int, int] | None] = []
    scores: list[np.float32] = []
    planes: list[Plane | None] = []
    for j in range(config.hypotheses):
        triple = sample_triple(rho, config.seed, pixel, j)
        plane = None if triple is None else plane_through(*(cands[k] for k in triple))
        triples.append(triple)
        planes.append(plane)
        scores.append(np.float32(-np.inf) if plane is None else score_f32(cands, p, plane, config))
    best = None
    for j, s in enumerate(scores):
        if s > np.float32(-np.inf) and (best is None or s > scores[best]):
            best = j
    if best is None:
        return PixelHypotheses(triples, scores, None, None, None)
    plane = planes[best]
    assert plane is not None
    normal, fit = refit(cands, p, plane, config.inlier_threshold_m)
    return PixelHypotheses(triples, scores, best, normal, fit)


def pixel_logits(logits: NDArray[np.float32], x: int, y: int) -> NDArray[np.float32]:
    """The 49 logits of pixel `(x, y)` from a 49×H×W array."""
    return np.asarray(logits[:, y, x], dtype=np.float32)


def frame_hypotheses(
    points: NDArray[np.float64], logits: NDArray[np.float32], config: DsacConfig
) -> list[list[PixelHypotheses | None]]:
    """`pixel_hypotheses` for every pixel (rows of columns); None where the point is invalid."""
    points = np.asarray(points, dtype=np.float64)
    logits = np.asarray(logits, dtype=np.float32)
    h, w, _ = points.shape
    if logits.shape != (CANDIDATES, h, w):
        raise ValueError(f"logits must be 49×{h}×{w}, got {logits.shape}")
    rows: list[list[PixelHypotheses | None]] = []
    for y in range(h):
        row: list[PixelHypotheses | None] = []
        for x in range(w):
            if not is_valid_point(points[y, x]):
                row.append(None)
                continue
            cands = window_candidates(points, x, y)
            rho = candidate_probabilities(pixel_logits(logits, x, y), valid_mask(cands))
            row.append(pixel_hypotheses(cands, rho, y * w + x, config))
        rows.append(row)
    return rows


def dsac_normals(
    points: NDArray[np.float64],
    logits: NDArray[np.float32],
    seed: int,
    hypotheses: int = 12,
    tau: float = 0.01,
    softness: float = 5.0,
) -> NDArray[np.float64]:
    """DSAC normals of an H×W×3 point map (NaN: invalid) from 49×H×W neighbour logits, with K =
    `hypotheses`, τ = `tau` metres and β = `softness`/τ; NaN where a pixel gets no normal."""
    config = DsacConfig(hypotheses, tau, softness, seed)
    rows = frame_hypotheses(points, logits, config)
    out = np.full((len(rows), len(rows[0]) if rows else 0, 3), np.nan)
    for y, row in enumerate(rows):
        for x, px in enumerate(row):
            if px is not None and px.normal is not None:
                out[y, x] = px.normal
    return out
