"""Real RGB-D frames for training and evaluation, split by `models/real_splits.json`.

`../shared/data/real-rgbd`, `real-rgbd-2` and `real-rgbd-3` hold one folder per sequence with
`intrinsics.json` (fx, fy, cx, cy, `depth_scale` in PNG units per metre, optional `pitch_deg` and
`height_m`, the `frames` list of `[rgb, depth]` pairs). Folders without a `frames` list are read
as `tre eval --real` reads them: `color/NAME` with `depth/NAME`, or `NAME.png` with
`NAME_depth.png`. `models/real_splits.json` gives each sequence's frames `[from, to)` a split
(`train`, `val`, `test`); frames no entry covers are used nowhere.

Every frame is brought to the size serving runs the nets at: the longer side 256, the other
keeping the aspect ratio rounded to a multiple of 16 (`fit_aspect` in
`crates/tre-pipeline/src/run.rs`), the RGB resized bilinear (antialiased, as serving's Triangle
filter), the sensor depth nearest-neighbour (what serving feeds the `rgbd` stages), the
intrinsics scaled as `Intrinsics::scaled` does (`(c + 0.5)·s − 0.5`). Frames are then padded at
the right and bottom to 256×256 (black image, no depth), as `data.load_split` pads synthetic
frames of different shapes, so both stack into one `Split`.

Depth targets: the sensor depth resized nearest-neighbour (0 / NaN = invalid, the mask of every
loss); for the sparse LiDAR sets the nearest valid point of each pixel's source block (the
smallest depth in the block) instead, which keeps their few points (nearest-neighbour sampling
would drop four in five of them).

Mounting (pitch below the horizon, height above the ground), for the flat-ground prior:

- `stated`: the set's `pitch_deg`/`height_m` (KITTI, nuScenes);
- `floor`: a plane fitted by RANSAC to the 3-D points of the lowest quarter of the image rows of
  the sensor depth (3 cm band, at least 30 % inliers, the plane facing up: pitch within
  −15°…89°), as the corpus README's ground check; for 7-Scenes the plane's normal must lie within
  10° of the gravity of `gravity.json` seen through the frame's pose;
- `sequence`: 7-Scenes frames with no such plane: pitch from gravity and the pose, height from
  the floor level of the sequence (median over the frames with a plane, in the world frame of
  the poses); other sets: the median mounting of the sequence's frames with a plane;
- `default`: none of the above: serving's defaults when no mounting is given (pitch 60°,
  height 1 m).

Roll is ignored: the prior models pitch only, as serving's `prior_depth` does.
"""

from __future__ import annotations

import json
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from torch.nn import functional as F

from .data import Split, read_png

REPO = Path(__file__).resolve().parents[3]
SPLITS = REPO / "models" / "real_splits.json"
ROOTS = (
    REPO.parent / "shared/data/real-rgbd",
    REPO.parent / "shared/data/real-rgbd-2",
    REPO.parent / "shared/data/real-rgbd-3",
)
WORKING = 256
STRIDE = 16
DEFAULT_MOUNTING = (float(np.deg2rad(60.0)), 1.0)
"""Serving's mounting when a request gives none (`Mounting::default()`)."""
MAX_DEPTH_M = 80.0
"""Sensor depth beyond this is not a target."""


@dataclass
class RealFrame:
    """One real frame at its stored size."""

    sequence: str
    index: int
    split: str
    rgb_path: Path
    depth_path: Path
    camera: dict
    folder: Path
    meta: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        return f"{self.sequence}/{self.depth_path.relative_to(self.folder)}"


def fit_aspect(w0: int, h0: int, working: int = WORKING, stride: int = STRIDE) -> tuple[int, int]:
    """Serving's working size (width, height) for a w0×h0 frame."""

    def rnd(v: float) -> int:
        return max(int(np.floor(v / stride + 0.5)), 1) * stride

    if w0 >= h0:
        return working, rnd(working * h0 / max(w0, 1))
    return rnd(working * w0 / max(h0, 1)), working


def scaled_intrinsics(k: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """`Intrinsics::scaled`: pixel centres at integer coordinates."""
    return np.array(
        [k[0] * sx, k[1] * sy, (k[2] + 0.5) * sx - 0.5, (k[3] + 0.5) * sy - 0.5], np.float32
    )


def find_folder(sequence: str, roots: tuple[Path, ...] = ROOTS) -> Path:
    for r in roots:
        if (r / sequence / "intrinsics.json").exists():
            return r / sequence
    raise FileNotFoundError(f"sequence {sequence} in none of {roots}")


def frame_pairs(folder: Path, camera: dict) -> list[tuple[Path, Path]]:
    """The `[rgb, depth]` pairs of a sequence folder, in the order `tre eval --real` finds them."""
    if camera.get("frames"):
        return [(folder / a, folder / b) for a, b in camera["frames"]]
    out = []
    if (folder / "color").is_dir():
        for rgb in sorted((folder / "color").iterdir()):
            depth = folder / "depth" / (rgb.stem + ".png")
            if depth.exists():
                out.append((rgb, depth))
        return out
    for depth in sorted(folder.glob("*_depth.png")):
        stem = depth.name.removesuffix("_depth.png")
        for ext in (".png", ".jpg"):
            if (folder / (stem + ext)).exists():
                out.append((folder / (stem + ext), depth))
                break
    return out


def real_frames(
    split: str | None, splits: Path = SPLITS, roots: tuple[Path, ...] = ROOTS
) -> list[RealFrame]:
    """The frames of `split` (all splits with None), in the order of the splits file."""
    spec = json.loads(splits.read_text())["sequences"]
    out = []
    for seq, parts in spec.items():
        folder = find_folder(seq, roots)
        cam = json.loads((folder / "intrinsics.json").read_text())
        pairs = frame_pairs(folder, cam)
        for part in parts:
            if split is not None and part["split"] != split:
                continue
            lo, hi = part.get("from", 0), part.get("to", len(pairs))
            for i in range(lo, min(hi, len(pairs))):
                rgb, depth = pairs[i]
                out.append(RealFrame(seq, i, part["split"], rgb, depth, cam, folder))
    return out


def read_depth(frame: RealFrame) -> np.ndarray:
    """Sensor depth in metres at the stored size, NaN where invalid."""
    raw = read_png(frame.depth_path)[..., 0].astype(np.float32)
    scale = np.float32(frame.camera.get("depth_scale", 1000.0))
    d = raw / scale
    return np.where((raw > 0) & (d <= MAX_DEPTH_M), d, np.nan).astype(np.float32)


def back_project_np(depth: np.ndarray, k: np.ndarray) -> np.ndarray:
    """H×W×3 camera-frame points (NaN where no depth)."""
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    return np.stack([(u - k[2]) / k[0] * depth, (v - k[3]) / k[1] * depth, depth], -1)


def ransac_floor(
    points: np.ndarray,
    rng: np.random.Generator,
    gravity: np.ndarray | None = None,
    band_m: float = 0.03,
    iters: int = 300,
    min_inliers: float = 0.3,
) -> tuple[float, float] | None:
    """(pitch rad, height m) from the plane of the most inliers among `points` (P×3), refined by
    least squares on its inliers; None without a plausible ground plane."""
    if len(points) < 100:
        return None
    if len(points) > 6000:
        points = points[rng.choice(len(points), 6000, replace=False)]
    best, best_count = None, 0
    for _ in range(iters):
        a, b, c = points[rng.choice(len(points), 3, replace=False)]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n)
        if norm < 1e-9:
            continue
        n = n / norm
        if n @ a > 0:
            n = -n  # facing the camera: up
        if gravity is not None and -n @ gravity < np.cos(np.deg2rad(10.0)):
            continue
        count = int((np.abs((points - a) @ n) < band_m).sum())
        if count > best_count:
            best, best_count = (n, a), count
    if best is None or best_count < min_inliers * len(points):
        return None
    n, a = best
    inl = points[np.abs((points - a) @ n) < band_m]
    c = inl.mean(0)
    n2 = np.linalg.eigh((inl - c).T @ (inl - c))[1][:, 0]
    if n2 @ c > 0:
        n2 = -n2
    down = -n2
    pitch = float(np.arcsin(np.clip(down[2], -1, 1)))
    height = float(abs(n2 @ c))
    # The prior's down direction is (0, cos β, sin β): a floor must lie below the camera.
    if down[1] < 0 or not (np.deg2rad(-15.0) <= pitch <= np.deg2rad(89.0)) or height < 0.05:
        return None
    return pitch, height


def seven_scenes_gravity(frame: RealFrame) -> tuple[np.ndarray, np.ndarray] | None:
    """(gravity-down in the camera frame, camera centre in the world frame) from `gravity.json`
    and the frame's pose, where the set has them."""
    gpath = frame.folder / "gravity.json"
    pose = frame.folder / "poses" / (frame.depth_path.stem + ".txt")
    if not gpath.exists():
        return None
    if not pose.exists():
        cands = list((frame.folder / "poses").glob(frame.depth_path.stem.split(".")[0] + "*"))
        if not cands:
            return None
        pose = cands[0]
    g = np.array(json.loads(gpath.read_text())["gravity"], np.float64)
    t = np.loadtxt(pose).reshape(4, 4)
    return t[:3, :3].T @ g, t[:3, 3]


def mountings(frames: list[RealFrame], seed: int = 0) -> None:
    """Fills `meta["mounting"]` (pitch rad, height m) and `meta["mounting_source"]` per frame."""
    rng = np.random.default_rng(seed)
    by_seq: dict[str, list[RealFrame]] = {}
    for f in frames:
        by_seq.setdefault(f.sequence, []).append(f)
    for seq_frames in by_seq.values():
        cam = seq_frames[0].camera
        if "pitch_deg" in cam and "height_m" in cam:
            for f in seq_frames:
                f.meta["mounting"] = (float(np.deg2rad(cam["pitch_deg"])), float(cam["height_m"]))
                f.meta["mounting_source"] = "stated"
            continue
        k = np.array([cam["fx"], cam["fy"], cam["cx"], cam["cy"]], np.float64)
        levels = []
        for f in seq_frames:
            depth = read_depth(f)
            h = depth.shape[0]
            pts = back_project_np(depth, k)[h - h // 4 :].reshape(-1, 3)
            pts = pts[np.isfinite(pts).all(1)].astype(np.float64)
            grav = seven_scenes_gravity(f)
            f.meta["gravity"] = grav
            fit = ransac_floor(pts, rng, None if grav is None else grav[0])
            if fit is not None:
                f.meta["mounting"], f.meta["mounting_source"] = fit, "floor"
                if grav is not None:
                    levels.append(float(_world_down(f) @ grav[1]) + fit[1])
        fitted = [f.meta["mounting"] for f in seq_frames if "mounting" in f.meta]
        level = float(np.median(levels)) if levels else None
        for f in seq_frames:
            if "mounting" in f.meta:
                continue
            grav = f.meta.get("gravity")
            if grav is not None and level is not None:
                pitch = float(np.arcsin(np.clip(grav[0][2], -1, 1)))
                height = level - _world_down(f) @ grav[1]
                if height > 0.05:
                    f.meta["mounting"], f.meta["mounting_source"] = (pitch, height), "sequence"
                    continue
            if fitted:
                med = tuple(float(v) for v in np.median(np.array(fitted), 0))
                f.meta["mounting"], f.meta["mounting_source"] = med, "sequence"
            else:
                f.meta["mounting"], f.meta["mounting_source"] = DEFAULT_MOUNTING, "default"


def _world_down(frame: RealFrame) -> np.ndarray:
    return np.array(json.loads((frame.folder / "gravity.json").read_text())["gravity"], np.float64)


def block_min(depth: np.ndarray, w: int, h: int) -> np.ndarray:
    """The smallest valid depth of each output pixel's source block (NaN where none)."""
    d = torch.from_numpy(np.where(np.isfinite(depth), depth, np.inf)).view(1, 1, *depth.shape)
    out = -F.adaptive_max_pool2d(-d, (h, w))[0, 0].numpy()
    return np.where(np.isfinite(out), out, np.nan).astype(np.float32)


def nearest(a: np.ndarray, w: int, h: int) -> np.ndarray:
    """Nearest-neighbour resize with pixel centres (serving's `resize_nearest`)."""
    h0, w0 = a.shape[:2]
    ys = np.minimum(((np.arange(h) + 0.5) * h0 / h).astype(int), h0 - 1)
    xs = np.minimum(((np.arange(w) + 0.5) * w0 / w).astype(int), w0 - 1)
    return a[ys][:, xs]


@dataclass
class Working:
    """One frame at serving's working size."""

    rgb: np.ndarray  # h×w×3 uint8
    depth_in: np.ndarray  # h×w float32, nearest (the rgbd input)
    depth_target: np.ndarray  # h×w float32, the depth net's target
    k: np.ndarray  # 4
    size: tuple[int, int]  # (w, h)


def to_working(frame: RealFrame) -> Working:
    rgb = Image.open(frame.rgb_path).convert("RGB")
    depth = read_depth(frame)
    w0, h0 = rgb.size
    if depth.shape != (h0, w0):
        raise ValueError(f"{frame.name}: depth {depth.shape} vs rgb {(h0, w0)}")
    w, h = fit_aspect(w0, h0)
    k0 = np.array([frame.camera[c] for c in ("fx", "fy", "cx", "cy")], np.float32)
    k = scaled_intrinsics(k0, w / w0, h / h0)
    small = np.asarray(rgb.resize((w, h), Image.BILINEAR), np.uint8)
    d_in = nearest(depth, w, h)
    sparse = frame.camera.get("sensor") == "lidar"
    target = block_min(depth, w, h) if sparse else d_in
    return Working(small, d_in, target, k, (w, h))


def load_real(
    split: str,
    splits: Path = SPLITS,
    cache: Path | None = None,
    annotations: Path | None = None,
) -> tuple[Split, list[dict]]:
    """The frames of `split` at the working size padded to 256×256, as a `Split`: `depth_m` is
    the depth net's target, `depth_sensor_m` the `rgbd` input (nearest), `roughness_m` the spec
    on that input where `annotations` holds it (NaN otherwise), `normals` NaN, `mounting` the
    fitted or stated one. Also per-frame metadata (name, set, size, mounting source)."""
    if cache is not None and cache.exists():
        with np.load(cache, allow_pickle=False) as z:
            s = Split(**{k: z[k] for k in z.files if k != "meta"})
            meta = json.loads(str(z["meta"]))
    else:
        frames = real_frames(split, splits)
        mountings(frames)
        n = len(frames)
        s = Split(
            rgb=np.zeros((n, WORKING, WORKING, 3), np.uint8),
            depth_m=np.full((n, WORKING, WORKING), np.nan, np.float32),
            depth_sensor_m=np.full((n, WORKING, WORKING), np.nan, np.float32),
            normals=np.full((n, WORKING, WORKING, 3), np.nan, np.float16),
            roughness_m=np.full((n, WORKING, WORKING), np.nan, np.float32),
            boundary=np.zeros((n, WORKING, WORKING), bool),
            intrinsics=np.zeros((n, 4), np.float32),
            mounting=np.zeros((n, 2), np.float32),
        )
        meta = []
        for i, f in enumerate(frames):
            wk = to_working(f)
            w, h = wk.size
            s.rgb[i, :h, :w] = wk.rgb
            s.depth_m[i, :h, :w] = wk.depth_target
            s.depth_sensor_m[i, :h, :w] = wk.depth_in
            s.intrinsics[i] = wk.k
            s.mounting[i] = f.meta["mounting"]
            meta.append(
                {
                    "name": f.name,
                    "sequence": f.sequence,
                    "index": f.index,
                    "size": [w, h],
                    "sensor": f.camera.get("sensor", "kinect_v1"),
                    "mounting_source": f.meta["mounting_source"],
                    "pitch_deg": float(np.rad2deg(f.meta["mounting"][0])),
                    "height_m": float(f.meta["mounting"][1]),
                }
            )
        if cache is not None:
            cache.parent.mkdir(parents=True, exist_ok=True)
            np.savez(cache, meta=json.dumps(meta), **s.__dict__)
    if annotations is not None:
        for i, m in enumerate(meta):
            p = annotation_dir(annotations, m) / "roughness.npy"
            if p.exists():
                r = np.load(p).astype(np.float32)
                s.roughness_m[i, : r.shape[0], : r.shape[1]] = r
    return s, meta


def annotation_dir(root: Path, m: dict) -> Path:
    return root / m["sequence"] / f"{m['index']:05d}"


def annotate(s: Split, meta: list[dict], root: Path, tre: Path) -> None:
    """Annotation spec v1 (`tre annotate`) on each frame's `rgbd` input at the working size,
    into `root/SEQUENCE/INDEX/`."""
    for i, m in enumerate(meta):
        out = annotation_dir(root, m)
        if (out / "roughness.npy").exists():
            continue
        w, h = m["size"]
        with tempfile.TemporaryDirectory() as tmp:
            d = s.depth_sensor_m[i, :h, :w]
            np.save(Path(tmp) / "depth.npy", np.nan_to_num(d, nan=0.0).astype(np.float32))
            k = s.intrinsics[i]
            cam = {"fx": float(k[0]), "fy": float(k[1]), "cx": float(k[2]), "cy": float(k[3])}
            cam.update({"width": w, "height": h})
            (Path(tmp) / "camera.json").write_text(json.dumps(cam))
            out.parent.mkdir(parents=True, exist_ok=True)
            subprocess.run(
                [
                    str(tre),
                    "annotate",
                    "--depth",
                    str(Path(tmp) / "depth.npy"),
                    "--camera",
                    str(Path(tmp) / "camera.json"),
                    "--out",
                    str(out),
                ],
                check=True,
                capture_output=True,
            )


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description="cache the real frames of a split; annotate them")
    ap.add_argument("split", choices=["train", "val", "test"])
    ap.add_argument("--out", type=Path, default=REPO / "data" / "real256")
    ap.add_argument("--splits", type=Path, default=SPLITS)
    ap.add_argument("--annotate", type=Path, help="the tre executable: annotate every frame")
    args = ap.parse_args(argv)
    s, meta = load_real(args.split, args.splits, args.out / f"{args.split}.npz")
    from collections import Counter

    print(f"{args.split}: {len(meta)} frames;", dict(Counter(m["sequence"] for m in meta)))
    print("mounting sources:", dict(Counter(m["mounting_source"] for m in meta)))
    for m in meta[:: max(1, len(meta) // 12)]:
        print(
            f"  {m['name']:55s} {m['size']} {m['mounting_source']:8s} "
            f"pitch {m['pitch_deg']:5.1f} h {m['height_m']:.2f}"
        )
    if args.annotate:
        annotate(s, meta, args.out / "annotations", args.annotate)
        print("annotated into", args.out / "annotations")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
