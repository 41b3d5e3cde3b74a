"""Writes the DSAC test vectors that serving is checked against
(`crates/tre-core/tests/core/dsac_parity.rs`).

    python -m tre_training.make_vectors [--out PATH] [--check]

Every input is computed from integer hashes with +, −, ×, ÷ and √ only (no library RNG, no
transcendental functions), so the file is the same on any machine. Floats are written as decimal
strings that round-trip exactly: Python `repr` for float64, numpy's shortest repr for float32
(`"nan"`, `"inf"` and `"-inf"` included); u64 values as decimal strings.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from . import dsac

REPO_ROOT = Path(__file__).resolve().parents[3]
"""The repository root (models/training/tre_training/ is three levels down)."""
DEFAULT_OUT = REPO_ROOT / "crates" / "tre-core" / "src" / "geometry" / "dsac" / "vectors.json"
"""Where the Rust parity test reads the vectors."""

U64_MAX = dsac.MASK64
CONFIG = dsac.DsacConfig()
"""The serving defaults: K = 12, τ = 1 cm, softness 5."""


# --- number formats -------------------------------------------------------------------------------


def f64s(x: float) -> str:
    """A float64 as the shortest decimal that round-trips."""
    return repr(float(x))


def f32s(x: float | np.floating) -> str:
    """A float32 as the shortest decimal that round-trips to the same float32."""
    return str(np.float32(x))


def vec_s(v: Any) -> list[str]:
    """A float64 3-vector as strings."""
    return [f64s(c) for c in v]


# --- deterministic pseudo-random inputs -----------------------------------------------------------


def unit(tag: int, i: int) -> float:
    """A uniform number in [0, 1) for stream `tag`, index `i` (SplitMix64, exact)."""
    return float(dsac.splitmix64(dsac.splitmix64(tag) ^ i) >> 11) * 2.0**-53


def small_int(tag: int, i: int, n: int) -> int:
    """An integer in [0, n) for stream `tag`, index `i`."""
    return dsac.splitmix64(dsac.splitmix64(tag) ^ i) % n


# --- (a) hash -------------------------------------------------------------------------------------


def splitmix_cases() -> list[dict[str, str]]:
    xs = [0, 1, 2, 0x9E3779B97F4A7C15, 1 << 63, U64_MAX, 0x0123456789ABCDEF]
    return [{"x": str(x), "out": str(dsac.splitmix64(x))} for x in xs]


def uniform_cases() -> list[dict[str, Any]]:
    seeds = [0, 1, 7, 5, 1 << 32, 1 << 63, 0xDEADBEEFCAFEBABE, U64_MAX]
    pixels = [0, 1, 1234, 119, (1 << 32) + 5, 0x8000000000000011, U64_MAX]
    keys = [(0, 0), (0, 1), (3, 2), (11, 2), (255, 255), (256, 0), (1 << 24, 3), (U64_MAX >> 32, 0)]
    keys += [(5, 256), (0, (1 << 32) - 1)]
    out = []
    for s, seed in enumerate(seeds):
        for p, pixel in enumerate(pixels):
            for c in range(2):
                hyp, draw = keys[(2 * (s + p) + c) % len(keys)]
                out.append(
                    {
                        "seed": str(seed),
                        "pixel": str(pixel),
                        "hypothesis": hyp,
                        "draw": draw,
                        "hash": str(dsac.uniform_hash(seed, pixel, hyp, draw)),
                        "u": f64s(dsac.uniform(seed, pixel, hyp, draw)),
                    }
                )
    return out


# --- fastmath -------------------------------------------------------------------------------------


def fastmath_cases() -> dict[str, list[list[str]]]:
    special = [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 1.5, -2.5, 1e-30, -1e-30, 1e-45, 3.0, 10.0]
    special += [-86.9, -87.0, -87.5, 87.9, 88.0, 88.5, -125.5, 119.5, 120.0, -120.0, 120.5]
    special += [-1000.0, 1000.0, 3.4e38, -3.4e38, float("inf"), float("-inf"), float("nan")]
    exp_in = special + [(unit(0xE1, i) - 0.5) * 180.0 for i in range(120)]
    exp_in += [(unit(0xE2, i) - 0.5) * 4.0 for i in range(60)]
    log_in = special + [(unit(0xE3, i) - 0.5) * 250.0 for i in range(120)]
    log_in += [(unit(0xE4, i) - 0.5) * 6.0 for i in range(60)]
    xs = np.array(exp_in, dtype=np.float32)
    ys = np.array(log_in, dtype=np.float32)
    return {
        "exp": [[f32s(x), f32s(r)] for x, r in zip(xs, dsac.fast_exp_f32(xs), strict=True)],
        "recip_one_plus_exp2": [
            [f32s(y), f32s(r)] for y, r in zip(ys, dsac.recip_one_plus_exp2_f32(ys), strict=True)
        ],
    }


# --- (c) logits → ρ -------------------------------------------------------------------------------


def _logit_cases() -> list[tuple[str, np.ndarray, np.ndarray]]:
    n = dsac.CANDIDATES
    all_valid = np.ones(n, dtype=bool)
    column_2_invalid = np.array([k % 7 != 2 for k in range(n)])
    corner = np.array(
        [dsac.candidate_offset(k)[0] >= 0 and dsac.candidate_offset(k)[1] >= 0 for k in range(n)]
    )
    spread = np.array([(unit(0xC1, k) - 0.5) * 12.0 for k in range(n)], dtype=np.float32)
    wide = np.array([(unit(0xC2, k) - 0.5) * 400.0 for k in range(n)], dtype=np.float32)
    huge = np.array([(unit(0xC3, k) - 0.5) * 6.0e38 for k in range(n)], dtype=np.float32)
    non_finite = spread.copy()
    non_finite[[3, 10, 17, 30]] = [np.nan, np.inf, -np.inf, np.nan]
    invalid_max = spread.copy()
    invalid_max[2] = 50.0  # column 2 is invalid: this must not set the maximum
    ties = np.full(n, 3.25, dtype=np.float32)
    ties[[0, 24, 48]] = 4.25
    one = np.full(n, -1.0, dtype=np.float32)
    only_one = np.zeros(n, dtype=bool)
    only_one[24] = True
    return [
        ("zeros_all_valid", np.zeros(n, dtype=np.float32), all_valid),
        ("spread_column_2_invalid", spread, column_2_invalid),
        ("wide_range_underflow", wide, all_valid),
        ("huge_logits_overflowing_differences", huge, all_valid),
        ("non_finite_logits", non_finite, all_valid),
        ("invalid_candidate_with_largest_logit", invalid_max, column_2_invalid),
        ("ties", ties, all_valid),
        ("image_corner", spread, corner),
        ("single_usable", one, only_one),
        ("none_valid", spread, np.zeros(n, dtype=bool)),
        ("all_non_finite", np.full(n, np.nan, dtype=np.float32), all_valid),
    ]


def probability_cases() -> list[dict[str, Any]]:
    out = []
    for name, logits, valid in _logit_cases():
        rho = dsac.candidate_probabilities(logits, valid)
        out.append(
            {
                "name": name,
                "logits": [f32s(v) for v in logits],
                "valid": "".join("1" if v else "0" for v in valid),
                "rho": [f64s(r) for r in rho],
            }
        )
    return out


# --- (b) sampler ----------------------------------------------------------------------------------


def _rho_cases() -> list[tuple[str, list[float]]]:
    n = dsac.CANDIDATES
    cases: list[tuple[str, list[float]]] = [("uniform_ties", [1.0 / 49.0] * n)]
    three = [0.0] * n
    three[0], three[24], three[48] = 0.2, 0.5, 0.3
    cases.append(("exactly_three", three))
    two = [0.0] * n
    two[5], two[40] = 0.5, 0.5
    cases.append(("only_two_positive", two))
    cases.append(("all_zero", [0.0] * n))
    tiny = [0.0] * n
    tiny[1], tiny[7], tiny[20], tiny[33] = 5e-324, 0.1, 1e-300, 2.0**-1074 * 3
    tiny[34], tiny[47] = 1e-17, 1.1
    cases.append(("sparse_tiny_remainders", tiny))
    ties = [0.25 if k % 3 == 0 else (1.0 / 3.0 if k % 3 == 1 else 0.0) for k in range(n)]
    cases.append(("ties_quarter_third", ties))
    cases.append(("unnormalised", [7.0 if k % 5 == 0 else 0.0 for k in range(n)]))
    cases.append(
        (
            "random_with_zeros",
            [0.0 if small_int(0xB1, k, 3) == 0 else unit(0xB2, k) for k in range(n)],
        )
    )
    cases.append(
        (
            "dyadic_dynamic_range",
            [2.0 ** -small_int(0xB3, k, 41) if small_int(0xB4, k, 2) else 0.0 for k in range(n)],
        )
    )
    eps_mass = [0.0] * n
    eps_mass[3], eps_mass[9], eps_mass[44] = 1.0, 0.3 * 2.0**-52, 1e-17
    eps_mass[45] = 2.0**-60
    cases.append(("mass_left_is_rounding_error", eps_mass))
    negative = [0.1] * n
    negative[5] = -0.3
    cases.append(("negative_entry", negative))
    infinite = [0.1] * n
    infinite[30] = float("inf")
    cases.append(("infinite_entry", infinite))
    nan = [0.1] * n
    nan[9] = float("nan")
    cases.append(("nan_entry", nan))
    points = np.zeros((dsac.CANDIDATES, 3))
    points[:, 2] = 1.0
    logits = np.array([(unit(0xB5, k) - 0.5) * 16.0 for k in range(n)], dtype=np.float32)
    softmax = dsac.candidate_probabilities(logits, np.array([k % 7 != 6 for k in range(n)]))
    cases.append(("softmax_of_logits", [float(r) for r in softmax]))
    return cases


SAMPLER_STREAMS = [
    (0, 0, 0),
    (5, 1234, 0),
    (U64_MAX, 0x8000000000000011, 0),
    (0xDEADBEEF, 77, 0),
    (42, 3, 1000),
]
"""(seed, pixel, first hypothesis); each draws 12 hypotheses from the first."""


def sampler_cases() -> list[dict[str, Any]]:
    out = []
    for name, rho in _rho_cases():
        draws = []
        for seed, pixel, first in SAMPLER_STREAMS:
            triples = [dsac.sample_triple(rho, seed, pixel, first + j) for j in range(12)]
            draws.append(
                {
                    "seed": str(seed),
                    "pixel": str(pixel),
                    "first_hypothesis": first,
                    "triples": [None if t is None else list(t) for t in triples],
                }
            )
        out.append({"name": name, "rho": [f64s(r) for r in rho], "draws": draws})
    return out


# --- (d) frames -----------------------------------------------------------------------------------

FOCAL_PX = 500.0
"""Focal length of the synthetic pinhole camera (3 mm per pixel at 1.5 m)."""


def _plane_points(w: int, h: int, n: tuple[float, float, float], d: float) -> np.ndarray:
    """Back-projected points of the plane `n · X = d` seen by a pinhole camera (H×W×3)."""
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    out = np.empty((h, w, 3))
    for y in range(h):
        for x in range(w):
            ray = ((x - cx) / FOCAL_PX, (y - cy) / FOCAL_PX, 1.0)
            z = d / ((n[0] * ray[0] + n[1] * ray[1]) + n[2] * ray[2])
            out[y, x] = (ray[0] * z, ray[1] * z, z)
    return out


def _scale_rays(points: np.ndarray, x: int, y: int, z: float) -> None:
    """Moves pixel `(x, y)` along its ray to depth `z`."""
    points[y, x] = points[y, x] * (z / points[y, x, 2])


def _logits(tag: int, w: int, h: int) -> np.ndarray:
    """49×H×W logits in [−6, 6], multiples of 1/8 (exact in float32, short to write)."""
    q = [small_int(tag, i, 97) - 48 for i in range(dsac.CANDIDATES * h * w)]
    return (np.array(q, dtype=np.float32) / np.float32(8.0)).reshape(dsac.CANDIDATES, h, w)


def tilted_plane() -> tuple[np.ndarray, np.ndarray, int]:
    """A plane tilted by about 37° (ground seen from a pitched camera), 12×10."""
    w, h = 12, 10
    return _plane_points(w, h, (0.1, -0.6, -0.8), -1.2), _logits(0xF1, w, h), 7


def step_edge() -> tuple[np.ndarray, np.ndarray, int]:
    """A slightly tilted wall with a 5 cm step in depth between columns 4 and 5, 10×8."""
    w, h = 10, 8
    points = _plane_points(w, h, (0.05, -0.3, -1.0), -1.5)
    for y in range(h):
        for x in range(5, w):
            _scale_rays(points, x, y, points[y, x, 2] + 0.05)
    return points, _logits(0xF2, w, h), 12345


def holes_and_noise() -> tuple[np.ndarray, np.ndarray, int]:
    """A tilted plane with ±6 mm depth noise, scattered holes, an isolated pixel (< 3
    candidates: no normal), a corner whose only candidates are collinear (every plane
    degenerate: no normal) and a few non-finite logits, 10×8; a seed near 2⁶⁴."""
    w, h = 10, 8
    points = _plane_points(w, h, (-0.2, -0.5, -0.9), -1.4)
    for y in range(h):
        for x in range(w):
            i = y * w + x
            noise = (unit(0xA1, i) + unit(0xA2, i) + unit(0xA3, i) - 1.5) * 0.004
            _scale_rays(points, x, y, points[y, x, 2] + noise)
    holes = {(x, y) for y in range(h) for x in range(w) if (x * 7 + y * 3) % 11 == 0}
    holes |= {(x, y) for y in range(4) for x in range(4)}
    holes |= {(x, y) for y in range(4, 7) for x in range(6, w)}
    holes -= {(0, 0), (2, 1)}
    for x, y in holes:
        points[y, x] = np.nan
    row_z = 1.6
    for x in range(6, w):
        ray = ((x - (w - 1) / 2.0) / FOCAL_PX, (7 - (h - 1) / 2.0) / FOCAL_PX)
        points[7, x] = (ray[0] * row_z, ray[1] * row_z, row_z)
    logits = _logits(0xF3, w, h)
    logits[3, 4, 5] = np.nan
    logits[24, 4, 5] = np.inf
    logits[10, 3, 7] = -np.inf
    logits[40, 5, 2] = np.nan
    return points, logits, U64_MAX - 6


FRAMES = [
    ("tilted_plane", tilted_plane),
    ("step_edge", step_edge),
    ("holes_and_noise", holes_and_noise),
]


def _check_margins(name: str, x: int, y: int, px: dsac.PixelHypotheses, p: np.ndarray) -> None:
    """Refuses a pixel whose refit sits so close to one of serving's thresholds (the eigenvalue
    gap of a degenerate fit, the sign of n · p) that another eigen-solver could decide otherwise.
    Everything before the refit is exact, so it needs no margin."""
    fit = px.fit
    if fit is None:
        return
    if fit.gap is not None and abs(fit.gap - dsac.EIGEN_GAP) < 1e-9:
        raise RuntimeError(f"{name} ({x}, {y}): eigenvalue gap {fit.gap} too close to 1e-6")
    facing = 0.0 if fit.normal is None else float(np.dot(fit.normal, p) / np.linalg.norm(p))
    if fit.normal is not None and abs(facing) < 1e-6:
        raise RuntimeError(f"{name} ({x}, {y}): refit normal nearly perpendicular to the ray")


def frame_cases() -> list[dict[str, Any]]:
    out = []
    for name, make in FRAMES:
        points, logits, seed = make()
        h, w, _ = points.shape
        config = dsac.DsacConfig(seed=seed)
        rows = dsac.frame_hypotheses(points, logits, config)
        pixels: list[dict[str, Any] | None] = []
        for y, row in enumerate(rows):
            for x, px in enumerate(row):
                if px is None:
                    pixels.append(None)
                    continue
                _check_margins(name, x, y, px, points[y, x])
                pixels.append(
                    {
                        "x": x,
                        "y": y,
                        "triples": [None if t is None else list(t) for t in px.triples],
                        "scores": [f32s(s) for s in px.scores],
                        "best": px.best,
                        "normal": None if px.normal is None else vec_s(px.normal),
                    }
                )
        out.append(
            {
                "name": name,
                "width": w,
                "height": h,
                "seed": str(seed),
                "points": [[vec_s(points[y, x]) for x in range(w)] for y in range(h)],
                "logits": [[f32s(v) for v in logits[k].ravel()] for k in range(dsac.CANDIDATES)],
                "pixels": pixels,
            }
        )
    return out


# --- (e) Eq. 1 ------------------------------------------------------------------------------------


def eq1_cases() -> list[dict[str, Any]]:
    out = []
    for i in range(24):
        c = tuple((unit(0xD1, 3 * i + a) - 0.5) * 4.0 for a in range(3))
        raw = tuple(unit(0xD2, 3 * i + a) - 0.5 for a in range(3))
        length = math.sqrt((raw[0] * raw[0] + raw[1] * raw[1]) + raw[2] * raw[2])
        n = (raw[0] / length, raw[1] / length, raw[2] / length)
        on_plane = i % 4 == 0
        p = c if on_plane else tuple((unit(0xD3, 3 * i + a) - 0.5) * 4.0 for a in range(3))
        plane = dsac.Plane(centroid=c, normal=n)
        out.append(
            {
                "point": vec_s(p),
                "centroid": vec_s(c),
                "normal": vec_s(n),
                "distance": f64s(plane.distance(p)),
            }
        )
    return out


# --- output ---------------------------------------------------------------------------------------


def vectors() -> dict[str, Any]:
    """All test vectors."""
    return {
        "about": (
            "DSAC parity vectors written by models/training (python -m tre_training.make_vectors);"
            " checked by crates/tre-core/tests/core/dsac_parity.rs. Floats are decimal strings"
            " that round-trip"
            " exactly (float64: Python repr; float32: shortest float32 repr); u64 values are"
            " decimal strings. Frames: points[y][x] (NaN: invalid), logits[k] row-major H×W,"
            " pixels in row-major order (null: invalid point), pixel index i = y·W + x."
        ),
        "config": {
            "hypotheses": CONFIG.hypotheses,
            "inlier_threshold_m": f64s(CONFIG.inlier_threshold_m),
            "softness": f64s(CONFIG.softness),
        },
        "splitmix64": splitmix_cases(),
        "uniform": uniform_cases(),
        "fastmath": fastmath_cases(),
        "probabilities": probability_cases(),
        "sampler": sampler_cases(),
        "frames": frame_cases(),
        "eq1": eq1_cases(),
    }


EXPANDED = {"points", "logits", "pixels", "draws", "exp", "recip_one_plus_exp2"}
"""Lists written one element per line."""


def _pretty(value: Any, key: str | None = None, indent: int = 0) -> str:
    """JSON with one line per record: dicts holding records and the lists in `EXPANDED` or of
    dicts are expanded, everything else is written compactly."""
    pad, inner = " " * indent, " " * (indent + 1)
    if isinstance(value, dict) and any(_expands(v, k) for k, v in value.items()):
        items = [f"{inner}{json.dumps(k)}: {_pretty(v, k, indent + 1)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{pad}}}"
    if isinstance(value, list) and _expands(value, key):
        items = [f"{inner}{_pretty(v, None, indent + 1)}" for v in value]
        return "[\n" + ",\n".join(items) + f"\n{pad}]"
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def _expands(value: Any, key: str | None) -> bool:
    """Whether `value` (held under `key`) is written over several lines."""
    if isinstance(value, dict):
        return any(_expands(v, k) for k, v in value.items())
    if isinstance(value, list):
        return key in EXPANDED or any(isinstance(v, dict) for v in value)
    return False


def render() -> str:
    """The fixture's text."""
    return _pretty(vectors()) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="fixture to write")
    parser.add_argument(
        "--check", action="store_true", help="only check that the fixture is up to date"
    )
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        if not args.out.exists() or args.out.read_text(encoding="utf-8") != text:
            print(f"{args.out} is out of date: run python -m tre_training.make_vectors")
            return 1
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(f"wrote {args.out} ({len(text.encode('utf-8')) / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
