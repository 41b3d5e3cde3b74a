"""Depth net on the real RGB-D frames of `../shared/data/real-rgbd`: AbsRel, RMSE and δ < 1.25.

`python -m tre_training.eval_real [--models DIR] [--real DIR]` runs the exported `depth_net.onnx`
(through ONNX Runtime, as serving does) on each frame resized to 256×192 and compares it with the
sensor depth at that size (nearest, valid pixels up to 10 m). The net needs the camera's pitch
and height above the ground; the frames are hand-held indoor views with no mounting given, so two
settings are reported:

- `default`: the serving defaults (pitch 60°, height 1 m), i.e. a robot that never calibrated;
- `calibrated`: pitch and height from a least-squares plane fitted to the sensor depth of the
  floor region of `tests/fixtures/real_floor.json`, i.e. what a robot's extrinsic calibration
  gives. (Roll is ignored; the prior models pitch only.)

Median-scaled AbsRel (prediction scaled by the ratio of medians) is printed beside, as monocular
depth papers do, to separate scale from shape.

With `--split NAME` (and `--splits FILE`, default `models/real_splits.json`) the frames are those
of that split of the real corpora instead (`real.load_real`: serving's working size, long side
256), and the two settings are `mounting` (the stated mounting of the vehicle sets, else the
floor fit of `real.py`) and `default` (pitch 60°, height 1 m: what serving uses when a request
gives none). Depth up to 10 m (Kinect sets) or 80 m (LiDAR sets) is scored, per sequence and
pooled per group (`kinect`: the hand-held indoor sets; `street`: KITTI and nuScenes).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch
from PIL import Image

from .data import read_png
from .geometry import back_project, prior_depth

REPO = Path(__file__).resolve().parents[3]
SIZE = (256, 192)
MAX_DEPTH_M = 10.0


def floor_mounting(depth_m: np.ndarray, k: np.ndarray, box: list[int]) -> tuple[float, float]:
    """(pitch rad, height m) of the camera over the LS plane of the floor box's points."""
    d = torch.from_numpy(depth_m).view(1, 1, *depth_m.shape)
    pts, valid = back_project(d, torch.from_numpy(k).view(1, 4))
    x0, y0, x1, y1 = box
    p = pts[0, :, y0:y1, x0:x1].reshape(3, -1).T.double()
    p = p[valid[0, 0, y0:y1, x0:x1].reshape(-1) > 0]
    c = p.mean(0)
    n = torch.linalg.eigh((p - c).T @ (p - c))[1][:, 0]
    if float(n @ c) > 0:
        n = -n  # facing the camera: up
    down = -n
    return float(torch.asin(down[2].clamp(-1, 1))), float(abs(n @ c))


def scores(p: np.ndarray, g: np.ndarray) -> dict[str, float]:
    """AbsRel, RMSE, δ < 1.25 and median-scaled AbsRel of predicted `p` against sensor `g`."""
    scaled = p * np.median(g) / np.median(p)
    ratio = np.maximum(p / g, g / p)
    return {
        "abs_rel": float(np.mean(np.abs(p - g) / g)),
        "rmse_m": float(np.sqrt(np.mean((p - g) ** 2))),
        "delta_1_25_pct": float(100 * np.mean(ratio < 1.25)),
        "abs_rel_median_scaled": float(np.mean(np.abs(scaled - g) / g)),
        "pixels": int(p.size),
    }


def metrics(pred: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    ok = np.isfinite(gt) & (gt > 0) & (gt <= MAX_DEPTH_M)
    return scores(pred[ok], gt[ok])


def frames(real: Path) -> list[tuple[str, Path, Path, dict, list[int]]]:
    floors = json.loads((REPO / "tests/fixtures/real_floor.json").read_text())["frames"]
    out = []
    for f in floors:
        folder = real / f["dir"]
        cam = json.loads((folder / "intrinsics.json").read_text())
        depth = folder / f["depth"]
        name = depth.name
        if f["dir"] == "metric3d_nyu":
            rgb = folder / "rgb" / name.replace("sync_depth", "rgb").replace(".png", ".jpg")
        elif f["dir"] == "slambook2_ch5":
            rgb = folder / "color" / name
        else:
            rgb = folder / name.replace("_depth", "")
        out.append((f"{f['dir']}/{f['depth']}", rgb, depth, cam, f["floor"]))
    return out


def metrics_capped(pred: np.ndarray, gt: np.ndarray, cap: float) -> dict[str, float] | None:
    ok = np.isfinite(gt) & (gt > 0) & (gt <= cap)
    if ok.sum() < 10:
        return None
    return scores(pred[ok], gt[ok])


def group_of(sequence: str) -> str:
    return "street" if sequence.startswith(("kitti", "nuscenes")) else "kinect"


def eval_split(predict, split: str, splits: Path, cache_dir: Path | None = None) -> dict:
    """Depth figures of `predict(rgb N×3×H×W in [0, 1], prior N×1×H×W) → depth` on the frames
    of `split`, per frame, per sequence and per group, for both mountings."""
    from . import real

    cache = None if cache_dir is None else cache_dir / f"{split}.npz"
    s, meta = real.load_real(split, splits, cache)
    rows = []
    for i, m in enumerate(meta):
        w, h = m["size"]
        rgb = s.rgb[i, :h, :w].astype(np.float32).transpose(2, 0, 1)[None] / 255.0
        gt = s.depth_m[i, :h, :w]
        k = torch.from_numpy(s.intrinsics[i].copy()).view(1, 4)
        cap = 80.0 if m["sensor"] == "lidar" else MAX_DEPTH_M
        row = {**m}
        for setting, mount in (
            ("mounting", tuple(float(v) for v in s.mounting[i])),
            ("default", real.DEFAULT_MOUNTING),
        ):
            prior = prior_depth(k, torch.tensor([mount], dtype=torch.float32), h, w).numpy()
            pred = predict(rgb, prior)[0, 0]
            row[setting] = metrics_capped(pred, gt, cap)
        if row["mounting"] is not None:
            rows.append(row)
    summary: dict[str, dict] = {}
    keys = sorted({r["sequence"] for r in rows}, key=lambda q: (group_of(q), q))
    for label, sel in [(q, lambda r, q=q: r["sequence"] == q) for q in keys] + [
        (f"all {g}", lambda r, g=g: group_of(r["sequence"]) == g) for g in ("kinect", "street")
    ]:
        rs = [r for r in rows if sel(r)]
        if not rs:
            continue
        summary[label] = {"frames": len(rs)}
        for setting in ("mounting", "default"):
            summary[label][setting] = {
                k: float(np.mean([r[setting][k] for r in rs]))
                for k in ("abs_rel", "delta_1_25_pct", "abs_rel_median_scaled", "rmse_m")
            }
    return {"split": split, "frames": rows, "summary": summary}


def print_summary(result: dict) -> None:
    print(f"split {result['split']}: depth net, mean over frames")
    print(
        f"{'set':28s} {'n':>3s} | {'mounting: AbsRel':>16s} {'δ<1.25':>7s} {'med-sc':>6s} |"
        f" {'default: AbsRel':>15s} {'δ<1.25':>7s} {'med-sc':>6s}"
    )
    for label, v in result["summary"].items():
        a, b = v["mounting"], v["default"]
        print(
            f"{label:28s} {v['frames']:3d} | {a['abs_rel']:16.3f} {a['delta_1_25_pct']:6.1f}%"
            f" {a['abs_rel_median_scaled']:6.3f} | {b['abs_rel']:15.3f}"
            f" {b['delta_1_25_pct']:6.1f}% {b['abs_rel_median_scaled']:6.3f}"
        )


def onnx_predict(models: Path):
    sess = ort.InferenceSession(str(models / "depth_net.onnx"), providers=["CPUExecutionProvider"])
    return lambda rgb, prior: sess.run(None, {"rgb": rgb, "prior_depth_m": prior})[0]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--models", type=Path, default=REPO / "models")
    ap.add_argument("--real", type=Path, default=REPO.parent / "shared/data/real-rgbd")
    ap.add_argument("--json", type=Path, help="write the per-frame numbers here")
    ap.add_argument("--split", choices=["train", "val", "test"], help="frames of this split")
    ap.add_argument("--splits", type=Path, default=REPO / "models" / "real_splits.json")
    ap.add_argument("--cache", type=Path, default=REPO / "data" / "real256")
    args = ap.parse_args(argv)
    if args.split:
        result = eval_split(onnx_predict(args.models), args.split, args.splits, args.cache)
        print_summary(result)
        if args.json:
            args.json.write_text(json.dumps(result, indent=2) + "\n")
        return 0
    sess = ort.InferenceSession(
        str(args.models / "depth_net.onnx"), providers=["CPUExecutionProvider"]
    )
    rows, totals = [], {"default": [], "calibrated": []}
    for name, rgb_path, depth_path, cam, box in frames(args.real):
        rgb = Image.open(rgb_path).convert("RGB")
        w0, h0 = rgb.size
        raw = read_png(depth_path)[..., 0].astype(np.float32)
        depth = np.where(raw > 0, raw / np.float32(cam.get("depth_scale", 1000.0)), np.nan)
        k = np.array([cam["fx"], cam["fy"], cam["cx"], cam["cy"]], np.float32)
        pitch, height = floor_mounting(depth, k, box)
        sx, sy = SIZE[0] / w0, SIZE[1] / h0
        ks = np.array([k[0] * sx, k[1] * sy, (k[2] + 0.5) * sx - 0.5, (k[3] + 0.5) * sy - 0.5])
        small = np.asarray(rgb.resize(SIZE, Image.BILINEAR), np.float32) / 255.0
        ys = ((np.arange(SIZE[1]) + 0.5) / sy).astype(int)
        xs = ((np.arange(SIZE[0]) + 0.5) / sx).astype(int)
        gt = depth[ys][:, xs]
        row = {"frame": name, "pitch_deg": np.rad2deg(pitch), "height_m": height}
        for setting, mount in (
            ("default", (np.deg2rad(60.0), 1.0)),
            ("calibrated", (pitch, height)),
        ):
            prior = prior_depth(
                torch.from_numpy(ks).float().view(1, 4),
                torch.tensor([mount], dtype=torch.float32),
                SIZE[1],
                SIZE[0],
            ).numpy()
            x = {"rgb": small.transpose(2, 0, 1)[None].copy(), "prior_depth_m": prior}
            pred = sess.run(None, x)[0][0, 0]
            m = metrics(pred, gt)
            row[setting] = m
            totals[setting].append(m)
        rows.append(row)
        print(
            f"{name:40s} pitch {row['pitch_deg']:5.1f}° h {height:4.2f} m | "
            + " | ".join(
                f"{s}: AbsRel {row[s]['abs_rel']:.3f} δ {row[s]['delta_1_25_pct']:5.1f}%"
                f" (med-scaled {row[s]['abs_rel_median_scaled']:.3f})"
                for s in ("default", "calibrated")
            )
        )
    for s, ms in totals.items():
        print(
            f"mean over {len(ms)} frames, {s}: AbsRel {np.mean([m['abs_rel'] for m in ms]):.3f}, "
            f"RMSE {np.mean([m['rmse_m'] for m in ms]):.3f} m, "
            f"δ<1.25 {np.mean([m['delta_1_25_pct'] for m in ms]):.1f}%, "
            f"median-scaled AbsRel {np.mean([m['abs_rel_median_scaled'] for m in ms]):.3f}"
        )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
