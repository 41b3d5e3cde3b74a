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


def metrics(pred: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    ok = np.isfinite(gt) & (gt > 0) & (gt <= MAX_DEPTH_M)
    p, g = pred[ok], gt[ok]
    scaled = p * np.median(g) / np.median(p)
    ratio = np.maximum(p / g, g / p)
    return {
        "abs_rel": float(np.mean(np.abs(p - g) / g)),
        "rmse_m": float(np.sqrt(np.mean((p - g) ** 2))),
        "delta_1_25_pct": float(100 * np.mean(ratio < 1.25)),
        "abs_rel_median_scaled": float(np.mean(np.abs(scaled - g) / g)),
        "pixels": int(ok.sum()),
    }


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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--models", type=Path, default=REPO / "models")
    ap.add_argument("--real", type=Path, default=REPO.parent / "shared/data/real-rgbd")
    ap.add_argument("--json", type=Path, help="write the per-frame numbers here")
    args = ap.parse_args(argv)
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
