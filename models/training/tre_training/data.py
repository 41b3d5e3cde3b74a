"""Datasets for training: the layout `tre synth` writes, loaded whole into memory.

Layout (one folder per frame, listed in `dataset.json` with its split): `rgb.png` (8-bit RGB),
`depth.png` (16-bit, `depth_scale` units per metre, 0 = none), `normals.npy` (H×W×3 float16,
camera frame, NaN = none), `labels.png` (8-bit, 0 = void), `roughness.png` (16-bit grey + alpha,
0.1 mm per unit, alpha 0 = none), `boundary.png` (8-bit mask) and `camera.json` (fx, fy, cx, cy,
`pitch_deg`, `height_m`), and, where the dataset was made with a depth-sensor model,
`depth_sensor.png` (the sensor's depth, same units; the inputs of sensor-depth training, while
the ground truth stays on the exact depth).

Frames of different shapes (`tre synth --random-optics`) are padded at the right and bottom to
the largest shape of the split: no depth, no ground truth, black image.

Other datasets: RougE and Hypersim-R are not redistributable. A user who holds them converts each
frame to the files above (depth in mm, normals as float16 `.npy`, roughness from `tre annotate`)
and writes a `dataset.json` with the same `scenes[].split` / `scenes[].frames[].dir` fields;
nothing else here depends on where the frames came from.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import png
from numpy.typing import NDArray

ROUGHNESS_SCALE_M = 1e-4
"""Metres per unit of `roughness.png`."""


def read_png(path: Path) -> NDArray[np.uint16] | NDArray[np.uint8]:
    """A PNG as an H×W×C array in its own bit depth (pypng keeps 16-bit grey + alpha)."""
    width, height, rows, info = png.Reader(filename=str(path)).read()
    planes = info["planes"]
    dtype = np.uint16 if info["bitdepth"] > 8 else np.uint8
    arr = np.vstack([np.asarray(r, dtype=dtype) for r in rows])
    return arr.reshape(height, width, planes)


@dataclass
class Frame:
    """One frame's inputs and ground truth, in float32 metres (NaN = no data)."""

    rgb: NDArray[np.uint8]
    """H×W×3."""
    depth_m: NDArray[np.float32]
    """H×W, NaN where there is no depth."""
    depth_sensor_m: NDArray[np.float32]
    """H×W, the depth-sensor model's depth (`depth.png` again where there is none)."""
    normals: NDArray[np.float32]
    """H×W×3 unit normals in the camera frame, NaN where none."""
    roughness_m: NDArray[np.float32]
    """H×W, NaN where none."""
    boundary: NDArray[np.bool_]
    """H×W boundary mask (B of annotation spec v1)."""
    camera: dict
    """The frame's `camera.json`."""


def load_frame(folder: Path) -> Frame:
    """Reads one frame folder."""
    camera = json.loads((folder / "camera.json").read_text())
    rgb = read_png(folder / "rgb.png")[..., :3].astype(np.uint8)
    raw = read_png(folder / "depth.png")[..., 0].astype(np.float32)
    scale = np.float32(camera.get("depth_scale", 1000.0))
    depth = np.where(raw > 0, raw / scale, np.nan)
    sensor_png = folder / "depth_sensor.png"
    if sensor_png.exists():
        raw_s = read_png(sensor_png)[..., 0].astype(np.float32)
        sensor = np.where(raw_s > 0, raw_s / scale, np.nan)
    else:
        sensor = depth
    normals = np.load(folder / "normals.npy").astype(np.float32)
    la = read_png(folder / "roughness.png")
    rough = np.where(la[..., 1] > 0, la[..., 0] * np.float32(ROUGHNESS_SCALE_M), np.nan)
    boundary = read_png(folder / "boundary.png")[..., 0] > 0
    return Frame(
        rgb,
        depth.astype(np.float32),
        sensor.astype(np.float32),
        normals,
        rough.astype(np.float32),
        boundary,
        camera,
    )


def pad_to(a: np.ndarray, h: int, w: int, fill: float | bool) -> np.ndarray:
    """`a` (H×W or H×W×C) padded at the bottom and right to h×w with `fill`."""
    if a.shape[:2] == (h, w):
        return a
    out = np.full((h, w, *a.shape[2:]), fill, dtype=a.dtype)
    out[: a.shape[0], : a.shape[1]] = a
    return out


def frame_dirs(root: Path, split: str) -> list[Path]:
    """The frame folders of one split, in `dataset.json` order."""
    manifest = json.loads((root / "dataset.json").read_text())
    return [root / f["dir"] for s in manifest["scenes"] if s["split"] == split for f in s["frames"]]


@dataclass
class Split:
    """All frames of a split stacked: N×H×W(×C) arrays plus per-frame camera vectors."""

    rgb: NDArray[np.uint8]
    depth_m: NDArray[np.float32]
    depth_sensor_m: NDArray[np.float32]
    normals: NDArray[np.float32]
    roughness_m: NDArray[np.float32]
    boundary: NDArray[np.bool_]
    intrinsics: NDArray[np.float32]
    """N×4: fx, fy, cx, cy in pixels."""
    mounting: NDArray[np.float32]
    """N×2: pitch (radians, down), camera height (m)."""

    def __len__(self) -> int:
        return len(self.rgb)


def load_split(root: Path, split: str, cache: Path | None = None) -> Split:
    """Loads a split, from an `.npz` cache when one is given and present (written otherwise)."""
    if cache is not None and cache.exists():
        with np.load(cache) as z:
            return Split(**{k: z[k] for k in z.files})
    frames = [load_frame(d) for d in frame_dirs(root, split)]
    if not frames:
        raise ValueError(f"no frames in split {split!r} of {root}")
    h = max(f.depth_m.shape[0] for f in frames)
    w = max(f.depth_m.shape[1] for f in frames)

    def stack(key: str, fill: float | bool) -> np.ndarray:
        return np.stack([pad_to(getattr(f, key), h, w, fill) for f in frames])

    out = Split(
        rgb=stack("rgb", 0),
        depth_m=stack("depth_m", np.nan),
        depth_sensor_m=stack("depth_sensor_m", np.nan),
        normals=stack("normals", np.nan),
        roughness_m=stack("roughness_m", np.nan),
        boundary=stack("boundary", False),
        intrinsics=np.array(
            [[f.camera[k] for k in ("fx", "fy", "cx", "cy")] for f in frames], np.float32
        ),
        mounting=np.array(
            [
                [np.deg2rad(f.camera.get("pitch_deg", 60.0)), f.camera.get("height_m", 1.0)]
                for f in frames
            ],
            np.float32,
        ),
    )
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        np.savez(cache, **out.__dict__)
    return out
