"""Trains one stage: `python -m tre_training.train STAGE --data DIR [--minutes M]`.

Stages, in the order they depend on each other:

- `depth`: depth net, L1 + 0.5·SSIM on log depth.
- `neighbour`: neighbour net, DSAC loss (expected normal error over the K = 12 hypotheses drawn by
  the serving sampler, score-function gradient to ρ) plus a cross-entropy pulling ρ towards the
  candidates on the true tangent plane, which makes CPU training converge in minutes.
- `cache-n0`: DSAC normals of every frame from the trained neighbour net (the refiner's input).
- `refiner`: normal refiner, mean angle to the true normal.
- `cache-n`: refined normals of every frame (the centroid net's input).
- `centroid`: centroid net, L1 on the roughness `|n·(p − c)|` (Eq. 1) against annotation v1.
- `e2e`: the end-to-end baseline, L1 on roughness.

The geometric stages train on points from the true depth, or with `--depth sensor` from the
depth-sensor model's depth of each frame (`depth_sensor.png`: the `rgbd` input as a real camera
gives it), always against the ground truth on the exact depth; in the `rgb` mode they see the
depth net's output (`--mix-pred` alternates it with the `--depth` source). Adam (β = 0.9,
0.999, ε = 1e-8), learning rate 1e-3 halved at half and three quarters of the time budget,
random crops. Checkpoints and logs go to
`checkpoints/STAGE.pt` and `checkpoints/STAGE.json` beside this package.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch
from torch import Tensor
from torch.nn import functional as F

from . import dsac_torch, losses, nets
from .data import Split, load_split
from .geometry import back_project, prior_depth, unfold7

ROOT = Path(__file__).resolve().parent.parent
CHECKPOINTS = ROOT / "checkpoints"
STAGE_NET = {
    "depth": "depth_net",
    "neighbour": "neighbour_net",
    "refiner": "normal_refiner",
    "centroid": "centroid_net",
    "e2e": "end_to_end",
}
DEFAULTS = {  # batch, crop
    "depth": (12, 128),
    "neighbour": (8, 64),
    "refiner": (12, 128),
    "centroid": (12, 128),
    "e2e": (12, 128),
}


class Data:
    """A split in memory plus the cached stage outputs, cut into batches of crops."""

    def __init__(self, root: Path, split: str, depth: str = "gt") -> None:
        """`depth="pred"` swaps the true depth for the depth net's (cached by `cache-depth`), so
        the geometric stages see what they see in the `rgb` mode; `depth="sensor"` swaps it for
        the depth-sensor model's. The caches of stage outputs then carry a `_pred` or `_sensor`
        suffix. Only the network inputs change: ground truth stays on the exact depth."""
        self.root = root
        self.cache = root / ".cache"
        self.split_name = split
        self.depth = depth
        self.suffix = "" if depth == "gt" else f"_{depth}"
        self.s: Split = load_split(root, split, self.cache / f"{split}.npz")
        if depth == "pred":
            self.s.depth_m = np.load(self.cache / f"{split}_pred_depth.npy")
        elif depth == "sensor":
            self.s.depth_m = self.s.depth_sensor_m
        self.extra: dict[str, np.ndarray] = {}
        self.frames = np.arange(len(self.s))
        """Frames batches are drawn from: all, or those the cached stage outputs cover."""
        self.row = {int(i): int(i) for i in self.frames}
        for name in ("n0", "n"):
            path = self.cache / f"{split}_{name}{self.suffix}.npy"
            if path.exists():
                self.extra[name] = np.load(path, mmap_mode="r")
                self.frames = np.load(self.cache / f"{split}_{name}{self.suffix}_index.npy")
                self.row = {int(i): r for r, i in enumerate(self.frames)}

    def __len__(self) -> int:
        return len(self.s)

    def batch(
        self, idx: np.ndarray, x0: np.ndarray, y0: np.ndarray, crop: int | tuple[int, int]
    ) -> dict:
        """Tensors for frames `idx` cropped at (x0, y0) to crop×crop, or to (height, width)."""
        s = self.s
        ch, cw = (crop, crop) if isinstance(crop, int) else crop

        def cut(a: np.ndarray) -> np.ndarray:
            return np.stack(
                [a[i, y : y + ch, x : x + cw] for i, x, y in zip(idx, x0, y0, strict=False)]
            )

        rgb = torch.from_numpy(cut(s.rgb)).permute(0, 3, 1, 2).float() / 255.0
        depth = torch.from_numpy(cut(s.depth_m)).unsqueeze(1)
        intr = torch.from_numpy(s.intrinsics[idx].copy())
        intr[:, 2] -= torch.from_numpy(x0.astype(np.float32))
        intr[:, 3] -= torch.from_numpy(y0.astype(np.float32))
        mount = torch.from_numpy(s.mounting[idx].copy())
        points, valid = back_project(depth, intr)
        out = {
            "rgb": rgb,
            "depth_m": depth,
            "normals_gt": torch.from_numpy(cut(s.normals)).permute(0, 3, 1, 2),
            "roughness_gt": torch.from_numpy(cut(s.roughness_m)).unsqueeze(1),
            "boundary": torch.from_numpy(cut(s.boundary)).unsqueeze(1),
            "intrinsics": intr,
            "mounting": mount,
            "prior_depth_m": prior_depth(intr, mount, ch, cw),
            "points_m": points,
            "valid": valid,
        }
        for name, arr in self.extra.items():
            c = np.stack(
                [
                    arr[self.row[int(i)], :, y : y + ch, x : x + cw]
                    for i, x, y in zip(idx, x0, y0, strict=False)
                ]
            )
            out[name] = torch.from_numpy(c.astype(np.float32))
        return out

    def random_batch(self, rng: np.random.Generator, n: int, crop: int) -> dict:
        h, w = self.s.depth_m.shape[1:]
        idx = self.frames[rng.integers(0, len(self.frames), n)]
        return self.batch(
            idx, rng.integers(0, w - crop + 1, n), rng.integers(0, h - crop + 1, n), crop
        )

    def whole(self, idx: np.ndarray) -> dict:
        z = np.zeros(len(idx), dtype=np.int64)
        return self.batch(idx, z, z, self.s.depth_m.shape[1:])


def inlier_target(points_m: Tensor, valid: Tensor, normals_gt: Tensor, tau: float) -> Tensor:
    """N×49×H×W distribution over the candidates on the true tangent plane of each pixel (within
    τ of it); all zero where there is no ground-truth normal."""
    cands = unfold7(points_m)
    cvalid = unfold7(valid)[:, 0]
    g = torch.nan_to_num(normals_gt)
    dist = ((cands - points_m.unsqueeze(2)) * g.unsqueeze(2)).sum(1).abs()
    on = (dist < tau).float() * cvalid * valid
    return on / torch.clamp(on.sum(1, keepdim=True), min=1e-6)


def step_loss(stage: str, model: torch.nn.Module, b: dict, step: int) -> tuple[Tensor, dict]:
    """The training loss of one batch and the numbers to log."""
    if stage == "depth":
        pred = model(b["rgb"], b["prior_depth_m"])
        loss = losses.depth_loss(pred, b["depth_m"])
        return loss, {"loss": loss.item()}
    if stage == "neighbour":
        logits = model(b["rgb"], b["points_m"], b["valid"])
        dsac, angle = dsac_torch.dsac_loss(
            logits, b["points_m"], b["valid"], b["normals_gt"], seed=step, max_pixels=4096
        )
        target = inlier_target(b["points_m"], b["valid"], b["normals_gt"], 0.01)
        ce = -(target * F.log_softmax(logits, 1)).sum(1).mean()
        return dsac + ce, {"dsac": dsac.item(), "ce": ce.item(), "angle_deg": angle.item()}
    if stage == "refiner":
        n = model(b["rgb"], b["points_m"], b["valid"], b["n0"])
        loss = losses.normal_loss(n, b["normals_gt"], b["valid"])
        return loss, {"angle_deg": float(np.rad2deg(loss.item()))}
    if stage == "centroid":
        c = model(b["rgb"], b["points_m"], b["valid"], b["n"])
        r = ((b["points_m"] - c) * b["n"]).sum(1, keepdim=True).abs()
        loss = losses.roughness_l1(r, b["roughness_gt"], b["valid"])
        return loss, {"l1_cm": loss.item()}
    if stage == "e2e":
        r = model(b["rgb"], b["prior_depth_m"])
        ok = torch.isfinite(b["roughness_gt"]).float()
        loss = losses.roughness_l1(r, b["roughness_gt"], ok)
        return loss, {"l1_cm": loss.item()}
    raise ValueError(stage)


def train(
    stage: str,
    data: Data,
    minutes: float,
    batch: int,
    crop: int,
    seed: int,
    pred: Data | None = None,
    init: Path | None = None,
) -> dict:
    """Trains `stage` for `minutes` of wall time and saves its checkpoint; returns the log.
    With `pred`, every other batch comes from it (points from the depth net's depth); `init`
    starts from a checkpoint (fine-tuning)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    model = nets.NETS[STAGE_NET[stage]]()
    if init is not None:
        model.load_state_dict(torch.load(init, weights_only=True))
    opt = torch.optim.Adam(model.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=1e-8)
    start, step, history = time.time(), 0, []
    budget = minutes * 60.0
    model.train()
    while (elapsed := time.time() - start) < budget:
        lr = (
            1e-3
            * (0.5 if elapsed > 0.5 * budget else 1.0)
            * (0.5 if elapsed > 0.75 * budget else 1.0)
        )
        for g in opt.param_groups:
            g["lr"] = lr
        source = pred if pred is not None and step % 2 == 1 else data
        b = source.random_batch(rng, batch, crop)
        loss, logs = step_loss(stage, model, b, step)
        opt.zero_grad()
        loss.backward()
        opt.step()
        history.append(logs)
        if step % 50 == 0:
            recent = {k: float(np.mean([h[k] for h in history[-50:]])) for k in logs}
            print(f"{stage} step {step} {elapsed:.0f}s lr {lr:g} {recent}", flush=True)
        step += 1
    final = {k: float(np.mean([h[k] for h in history[-100:]])) for k in history[-1]}
    log = {
        "stage": stage,
        "net": STAGE_NET[stage],
        "steps": step,
        "seconds": round(time.time() - start, 1),
        "batch": batch,
        "crop": crop,
        "device": "cpu",
        "threads": torch.get_num_threads(),
        "train_frames": len(data),
        "input_depth": data.depth,
        "mixed_predicted_depth": pred is not None,
        "init": None if init is None else init.name,
        "final_train": final,
        "seed": seed,
    }
    CHECKPOINTS.mkdir(exist_ok=True)
    torch.save(model.state_dict(), CHECKPOINTS / f"{stage}.pt")
    (CHECKPOINTS / f"{stage}.json").write_text(json.dumps(log, indent=2) + "\n")
    return log


def load(stage: str) -> torch.nn.Module:
    """A trained stage from its checkpoint, in eval mode."""
    model = nets.NETS[STAGE_NET[stage]]()
    model.load_state_dict(torch.load(CHECKPOINTS / f"{stage}.pt", weights_only=True))
    return model.eval()


def cache_outputs(kind: str, data: Data, seed: int, frames: int) -> None:
    """Writes `n0` (DSAC normals from the neighbour net, for `frames` frames spread evenly over
    the split) or `n` (refined normals, for the frames `n0` covers), float16, F×3×H×W, and the
    frame indices beside them."""
    model = load("neighbour" if kind == "n0" else "refiner")
    # Only the inputs of the stage being cached: outputs of an earlier run are rewritten.
    if kind == "n0":
        data.extra = {}
        data.frames = np.arange(len(data))
    else:
        data.extra.pop("n", None)
        data.frames = np.load(data.cache / f"{data.split_name}_n0{data.suffix}_index.npy")
    data.row = {int(i): r for r, i in enumerate(data.frames)}
    h, w = data.s.depth_m.shape[1:]
    if kind == "n0":
        index = np.unique(np.linspace(0, len(data) - 1, min(frames, len(data))).astype(np.int64))
    else:
        index = data.frames
    out = np.zeros((len(index), 3, h, w), np.float16)
    start = time.time()
    with torch.no_grad():
        for r, i in enumerate(index):
            b = data.whole(np.array([i]))
            if kind == "n0":
                logits = model(b["rgb"], b["points_m"], b["valid"])
                n = dsac_torch.dsac_normals(logits, b["points_m"], b["valid"], seed=seed)
            else:
                n = model(b["rgb"], b["points_m"], b["valid"], b["n0"]) * b["valid"]
            out[r] = n[0].numpy().astype(np.float16)
            if r % 50 == 0:
                print(f"cache {kind} {r}/{len(index)} {time.time() - start:.0f}s", flush=True)
    np.save(data.cache / f"{data.split_name}_{kind}{data.suffix}.npy", out)
    np.save(data.cache / f"{data.split_name}_{kind}{data.suffix}_index.npy", index)


def cache_depth(data: Data) -> None:
    """Writes the depth net's depth for every frame of the split (float32 metres, N×H×W)."""
    model = load("depth")
    data.extra = {}
    out = np.zeros(data.s.depth_m.shape, np.float32)
    with torch.no_grad():
        for lo in range(0, len(data), 16):
            b = data.whole(np.arange(lo, min(lo + 16, len(data))))
            out[lo : lo + 16] = model(b["rgb"], b["prior_depth_m"])[:, 0].numpy()
    np.save(data.cache / f"{data.split_name}_pred_depth.npy", out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("stage", choices=[*STAGE_NET, "cache-depth", "cache-n0", "cache-n"])
    ap.add_argument("--data", type=Path, required=True, help="dataset folder from `tre synth`")
    ap.add_argument("--minutes", type=float, default=15.0, help="wall-time budget")
    ap.add_argument("--batch", type=int, help="batch size (default per stage)")
    ap.add_argument("--crop", type=int, help="crop side, a multiple of 16 (default per stage)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--split", default="train", help="split for the cache-* stages")
    ap.add_argument("--frames", type=int, default=480, help="frames cache-n0 covers")
    ap.add_argument(
        "--depth",
        choices=["gt", "sensor", "pred"],
        default="gt",
        help="points from the true, the depth-sensor model's or the predicted depth",
    )
    ap.add_argument("--mix-pred", action="store_true", help="alternate true and predicted depth")
    ap.add_argument("--init", type=Path, help="start from this checkpoint")
    args = ap.parse_args(argv)
    if args.stage == "cache-depth":
        cache_depth(Data(args.data, args.split))
        return 0
    if args.stage.startswith("cache-"):
        data = Data(args.data, args.split, args.depth)
        cache_outputs(args.stage.removeprefix("cache-"), data, args.seed, args.frames)
        return 0
    batch, crop = DEFAULTS[args.stage]
    log = train(
        args.stage,
        Data(args.data, "train", args.depth),
        args.minutes,
        args.batch or batch,
        args.crop or crop,
        args.seed,
        pred=Data(args.data, "train", "pred") if args.mix_pred else None,
        init=args.init,
    )
    print(json.dumps(log, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
