"""Fine-tunes a committed stage on the real frames of `models/real_splits.json`, every other batch
synthetic: `python -m tre_training.train_real STAGE --data DIR --minutes M`.

Stages:

- `depth`: the depth net. Synthetic batches keep the training loss of `train.py`
  (`losses.depth_loss` against the exact depth); real batches use, on the pixels with sensor
  depth only, `|δ| + SI(δ) + 0.5·G(δ)` with `δ = log d − log d*` (L1 on log depth, Eigen's
  scale-invariant term, the gradient-matching term; no SSIM: LiDAR depth is too sparse for
  windows). The prior of a real frame comes from its stated or floor-fitted mounting
  (`real.py`), jittered by ±3° of pitch and ±10 % of height; for the hand-held sets (no stated
  mounting), 30 % of the crops (`--p-default`) get serving's default prior instead (pitch 60°,
  height 1 m: what `tre infer` / `tre serve` use when a request gives no mounting). Real crops
  come half from the street sets, half from the indoor ones; random horizontal flips.
- `centroid`: the centroid net, L1 on the roughness `|n·(p − c)|` against annotation spec v1 on
  the same sensor depth (`tre annotate` at the working size, `real.py --annotate`; the Kinect
  sets only: annotated LiDAR depth is isolated points, not surfaces); points from
  the sensor depth, normals from the committed neighbour net + DSAC + refiner (`cache-n0`,
  `cache-n` of `train.py` on the real frames). Synthetic batches as `train.py --depth sensor`.
- `refiner`: the normal refiner, mean angle to the normals of annotation spec v1 on the sensor
  depth (least-squares over R = 5 cm windows, see `ls_normals`). Synthetic batches as
  `train.py --depth sensor`.

Every stage starts from `checkpoints/STAGE_committed.pt` (`from_onnx.py`), keeps its batch norms
in eval mode, Adam at `--lr` (halved at half and three quarters of the budget), and checks the
`val` split every `--val-every` seconds: the checkpoint kept (`checkpoints/STAGE.pt`) is the one
with the best validation score (depth: mean of three AbsRel figures, the Kinect group with its
fitted mounting and with serving's default, the street group with its stated mounting; centroid:
roughness L1; refiner: mean angle), the committed model itself when no step beats it. The
`test` split is never read.
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

import numpy as np
import torch

from . import eval_real, losses, nets, real
from .from_onnx import freeze_batch_norm
from .geometry import back_project, prior_depth
from .train import CHECKPOINTS, STAGE_NET, Data, cache_outputs, step_loss

REPO = Path(__file__).resolve().parents[3]
REAL = REPO / "data" / "real256"


class RealData(Data):
    """The real frames of a split in the shape of `train.Data`; crops stay inside each frame's
    working size where it is large enough."""

    def __init__(self, split: str, splits: Path, depth: str, annotations: bool) -> None:
        self.root = REAL
        self.cache = REAL / ".cache"
        self.cache.mkdir(parents=True, exist_ok=True)
        self.split_name = f"real_{split}"
        self.depth = depth
        self.suffix = "" if depth == "target" else "_sensor"
        self.s, self.meta = real.load_real(
            split, splits, REAL / f"{split}.npz", REAL / "annotations" if annotations else None
        )
        if depth == "sensor":
            self.s.depth_m = self.s.depth_sensor_m
        self.sizes = np.array([m["size"] for m in self.meta])
        self.stated = np.array([m["mounting_source"] == "stated" for m in self.meta])
        self.street = np.array([eval_real.group_of(m["sequence"]) == "street" for m in self.meta])
        self.extra = {}
        self.frames = np.arange(len(self.s))
        self.row = {int(i): int(i) for i in self.frames}
        for name in ("n0", "n"):
            path = self.cache / f"{self.split_name}_{name}{self.suffix}.npy"
            if path.exists():
                self.extra[name] = np.load(path, mmap_mode="r")
                self.frames = np.load(
                    self.cache / f"{self.split_name}_{name}{self.suffix}_index.npy"
                )
                self.row = {int(i): r for r, i in enumerate(self.frames)}
        # Half the real crops from the street sets (LiDAR), half from the indoor Kinect sets.
        street = self.street[self.frames]
        share = STREET_SHARE
        w = np.where(street, share / max(street.sum(), 1), (1 - share) / max((~street).sum(), 1))
        if depth == "sensor":
            # The geometric stages: the Kinect sets only. Annotating LiDAR depth (0.2-4.5 % of
            # the pixels) gives isolated points, not surfaces.
            w = np.where(street, 0.0, w)
        self.weights = w / w.sum()

    def random_batch(self, rng: np.random.Generator, n: int, crop: int) -> dict:
        idx = self.frames[rng.choice(len(self.frames), n, p=self.weights)]
        w, h = self.sizes[idx, 0], self.sizes[idx, 1]
        x0 = (rng.random(n) * np.maximum(w - crop + 1, 1)).astype(np.int64)
        y0 = (rng.random(n) * np.maximum(h - crop + 1, 1)).astype(np.int64)
        b = self.batch(idx, x0, y0, crop)
        b["stated"] = torch.from_numpy(self.stated[idx])
        return b


def real_depth_loss(pred_m: torch.Tensor, gt_m: torch.Tensor) -> torch.Tensor:
    valid = torch.isfinite(gt_m) & (gt_m > 0)
    lg = torch.log(torch.where(valid, gt_m, torch.ones_like(gt_m)))
    delta = torch.log(torch.clamp(pred_m, min=1e-3)) - lg
    return (
        losses.masked_mean(delta.abs(), valid)
        + losses.scale_invariant(delta, valid)
        + 0.5 * losses.gradient_match(delta, valid)
    )


def jitter_prior(
    b: dict, rng: np.random.Generator, p_default: float, pitch_deg: float, height: float
) -> None:
    """The prior from the frame's mounting jittered by ±`pitch_deg` and ±`height` (relative);
    for frames whose set states no mounting, with probability `p_default` serving's default one
    instead (what the net gets when a request gives none)."""
    n = b["mounting"].shape[0]
    m = b["mounting"].clone()
    m[:, 0] += torch.from_numpy(
        np.deg2rad(rng.uniform(-pitch_deg, pitch_deg, n)).astype(np.float32)
    )
    m[:, 1] *= torch.from_numpy((1.0 + rng.uniform(-height, height, n)).astype(np.float32))
    use_default = torch.from_numpy(rng.random(n) < p_default) & ~b["stated"]
    m[use_default] = torch.tensor(real.DEFAULT_MOUNTING, dtype=torch.float32)
    h, w = b["rgb"].shape[2:]
    b["prior_depth_m"] = prior_depth(b["intrinsics"], m, h, w)


def flip(b: dict, keys: tuple[str, ...]) -> None:
    """Mirror the batch left-right (points: x negated; normals and centroids alike)."""
    for k in keys:
        if k in b:
            b[k] = torch.flip(b[k], [3])
            if k in ("points_m", "normals_gt", "n0", "n"):
                b[k] = b[k].clone()
                b[k][:, 0] = -b[k][:, 0]
    w = b["rgb"].shape[3]
    b["intrinsics"] = b["intrinsics"].clone()
    b["intrinsics"][:, 2] = (w - 1) - b["intrinsics"][:, 2]


def ls_normals(points: torch.Tensor, valid: torch.Tensor, radius_m: float = 0.05) -> torch.Tensor:
    """Least-squares normals (facing the camera) over the valid points within `radius_m` of each
    pixel's point in its 7×7 window; 0 where fewer than 3 or no point."""
    from .geometry import unfold7

    c = unfold7(points)  # N×3×49×H×W
    cv = unfold7(valid)[:, 0]
    near = ((c - points.unsqueeze(2)).norm(dim=1) < radius_m).float() * cv * valid
    cnt = near.sum(1, keepdim=True)
    mean = (c * near.unsqueeze(1)).sum(2) / torch.clamp(cnt, min=1)
    d = (c - mean.unsqueeze(2)) * near.unsqueeze(1)
    cov = torch.einsum("nakhw,nbkhw->nhwab", d, d) + 1e-9 * torch.eye(3, device=d.device)
    n = torch.linalg.eigh(cov)[1][..., 0].permute(0, 3, 1, 2)
    facing = (n * points).sum(1, keepdim=True) > 0
    n = torch.where(facing, -n, n)
    ok = (cnt >= 3) & (valid > 0)
    return torch.where(ok, n, torch.full_like(n, float("nan")))


def validate(stage: str, model: torch.nn.Module, val: RealData) -> tuple[float, dict]:
    """Lower is better."""
    model.eval()
    with torch.no_grad():
        if stage == "depth":

            def predict(rgb: np.ndarray, prior: np.ndarray) -> np.ndarray:
                x, p = torch.from_numpy(rgb).to(DEVICE), torch.from_numpy(prior).to(DEVICE)
                return model(x, p).cpu().numpy()

            res = eval_real.eval_split(predict, "val", VAL_SPLITS, REAL)["summary"]
            # The indoor sets with their fitted mounting and with serving's default; the
            # street sets with their stated one.
            groups = [
                res["all kinect"]["mounting"]["abs_rel"],
                res["all kinect"]["default"]["abs_rel"],
                res["all street"]["mounting"]["abs_rel"],
            ]
            out = {
                g: {s: round(res[g][s]["abs_rel"], 4) for s in ("mounting", "default")}
                for g in res
                if g.startswith("all")
            }
            score = float(np.mean(groups))
        else:
            vals = []
            for i in val.frames[val.weights > 0]:
                b = to_device(val.whole(np.array([i])))
                if stage == "refiner":
                    b["normals_gt"] = ls_normals(b["points_m"], b["valid"])
                _loss, logs = step_loss(stage, model, b, 0)
                vals.append(next(iter(logs.values())))
            score = float(np.mean(vals))
            out = {"val": round(score, 4)}
    model.train()
    freeze_batch_norm(model)
    return score, out


VAL_SPLITS = real.SPLITS
STREET_SHARE = 0.5
DEVICE = torch.device("cpu")


def to_device(b: dict) -> dict:
    """The batch's tensors on the training device."""
    return {k: v.to(DEVICE) if isinstance(v, torch.Tensor) else v for k, v in b.items()}


def pick_device(name: str) -> torch.device:
    """`auto`: the first CUDA device where PyTorch sees one, else the CPU."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(name)


def device_name(dev: torch.device) -> str:
    if dev.type == "cuda":
        return f"cuda: {torch.cuda.get_device_name(dev)}"
    return f"cpu: {torch.get_num_threads()} threads"


def save_progress(
    stage: str,
    model: torch.nn.Module,
    best_state: dict,
    best_step: int,
    step: int,
    val_history: list,
    hist: dict,
) -> None:
    """At every validation: the best checkpoint so far (`STAGE.pt`), the latest weights
    (`STAGE_last.pt`, to go on from with `--init`) and the curve so far (`STAGE_progress.json`), so
    that a run cut short leaves what it reached."""
    torch.save({k: v.cpu() for k, v in best_state.items()}, CHECKPOINTS / f"{stage}.pt")
    torch.save(
        {k: v.cpu() for k, v in model.state_dict().items()}, CHECKPOINTS / f"{stage}_last.pt"
    )
    progress = {
        "stage": stage,
        "steps": step,
        "kept_step": best_step,
        "device": device_name(DEVICE),
        "validation": val_history,
        "train_loss_last_50": {k: float(np.mean(v[-50:])) if v else None for k, v in hist.items()},
    }
    (CHECKPOINTS / f"{stage}_progress.json").write_text(json.dumps(progress, indent=1) + "\n")


def run(args: argparse.Namespace) -> dict:
    global VAL_SPLITS, STREET_SHARE, DEVICE
    VAL_SPLITS = args.splits
    STREET_SHARE = args.street_share
    DEVICE = pick_device(args.device)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    stage = args.stage
    synth = Data(args.data, "train", "gt" if stage == "depth" else "sensor")
    annotations = stage == "centroid"
    depth_kind = "target" if stage == "depth" else "sensor"
    train_real = RealData("train", args.splits, depth_kind, annotations)
    val_real = RealData("val", args.splits, depth_kind, annotations)
    model = nets.NETS[STAGE_NET[stage]]()
    init = args.init or CHECKPOINTS / f"{stage}_committed.pt"
    model.load_state_dict(torch.load(init, weights_only=True))
    model.to(DEVICE)
    print(f"{stage}: training on {device_name(DEVICE)}", flush=True)
    model.train()
    freeze_batch_norm(model)
    opt = torch.optim.Adam(model.parameters(), lr=args.lr, betas=(0.9, 0.999), eps=1e-8)
    best_score, best_logs = validate(stage, model, val_real)
    print(f"{stage} committed: val {best_logs}", flush=True)
    best_state, best_step = copy.deepcopy(model.state_dict()), 0
    val_history = [{"step": 0, "seconds": 0.0, "score": best_score, **best_logs}]
    start, step, hist = time.time(), 0, {"synthetic": [], "real": []}
    budget, last_val = args.minutes * 60.0, time.time()
    batch, crop = args.batch, args.crop
    stop = CHECKPOINTS / f"{stage}.stop"
    stop.unlink(missing_ok=True)
    # The budget, or `touch checkpoints/STAGE.stop` to end early (a last validation, then the log).
    while (elapsed := time.time() - start) < budget and not stop.exists():
        lr = (
            args.lr
            * (0.5 if elapsed > 0.5 * budget else 1.0)
            * (0.5 if elapsed > 0.75 * budget else 1.0)
        )
        for g in opt.param_groups:
            g["lr"] = lr
        is_real = step % 2 == 1
        if is_real:
            b = train_real.random_batch(rng, batch, crop)
            if rng.random() < 0.5:
                flip(b, ("rgb", "depth_m", "points_m", "valid", "n0", "n", "roughness_gt"))
                if stage != "depth":
                    b["points_m"], b["valid"] = back_project(b["depth_m"], b["intrinsics"])
            if stage == "depth":
                jitter_prior(b, rng, args.p_default, args.jitter_pitch_deg, args.jitter_height)
                b = to_device(b)
                loss = real_depth_loss(model(b["rgb"], b["prior_depth_m"]), b["depth_m"])
                logs = {"loss": loss.item()}
            else:
                b = to_device(b)
                if stage == "refiner":
                    b["normals_gt"] = ls_normals(b["points_m"], b["valid"])
                loss, logs = step_loss(stage, model, b, step)
        else:
            b = to_device(synth.random_batch(rng, batch, crop))
            loss, logs = step_loss(stage, model, b, step)
        opt.zero_grad()
        loss.backward()
        opt.step()
        hist["real" if is_real else "synthetic"].append(next(iter(logs.values())))
        if step % 50 == 0:
            r = np.mean(hist["real"][-25:]) if hist["real"] else float("nan")
            sy = np.mean(hist["synthetic"][-25:])
            print(
                f"{stage} step {step} {elapsed:.0f}s lr {lr:g} synthetic {sy:.4f} real {r:.4f}",
                flush=True,
            )
        step += 1
        ending = time.time() - start >= budget or stop.exists()
        if time.time() - last_val > args.val_every or ending:
            score, logs_v = validate(stage, model, val_real)
            last_val = time.time()
            val_history.append(
                {"step": step, "seconds": round(time.time() - start, 1), "score": score, **logs_v}
            )
            better = score < best_score or (best_step < args.min_step <= step)
            print(f"{stage} val at step {step}: {logs_v}{' (best)' if better else ''}", flush=True)
            if better:
                best_score, best_state, best_step = score, copy.deepcopy(model.state_dict()), step
            save_progress(stage, model, best_state, best_step, step, val_history, hist)
    log = {
        "stage": stage,
        "net": STAGE_NET[stage],
        "fine_tuned_on_real": best_step > 0,
        "min_step": args.min_step,
        "steps": step,
        "kept_step": best_step,
        "seconds": round(time.time() - start, 1),
        "batch": batch,
        "crop": crop,
        "lr": args.lr,
        "device": device_name(DEVICE),
        "threads": torch.get_num_threads(),
        "batches": "alternating: synthetic (even steps), real (odd steps)",
        "synthetic_train_frames": len(synth.frames),
        "real_train_frames": int((train_real.weights > 0).sum()),
        "real_val_frames": int((val_real.weights > 0).sum()),
        "real_sets": sorted(
            {
                train_real.meta[int(i)]["sequence"]
                for i, w in zip(train_real.frames, train_real.weights, strict=True)
                if w > 0
            }
        ),
        "real_splits": "models/real_splits.json (train; val for choosing the checkpoint)",
        "real_depth_target": "sensor depth at the working size (LiDAR: nearest point per block)"
        if stage == "depth"
        else "annotation spec v1 on the sensor depth at the working size",
        "synthetic_input_depth": synth.depth,
        "final_train": {
            "synthetic": float(np.mean(hist["synthetic"][-100:])),
            "real": float(np.mean(hist["real"][-100:])),
        },
        "validation": val_history,
        "init": f"{stage}_committed.pt",
        "started_from": init.name,
        "prior_jitter": {
            "pitch_deg": args.jitter_pitch_deg,
            "height_share": args.jitter_height,
            "p_default": args.p_default,
        },
        "street_share": args.street_share,
        "seed": args.seed,
    }
    if best_step == 0:
        print(f"{stage}: no step beat the committed model on val; it stays", flush=True)
    best_state = {k: v.cpu() for k, v in best_state.items()}
    torch.save(best_state, CHECKPOINTS / f"{stage}.pt")
    (CHECKPOINTS / f"{stage}.json").write_text(json.dumps(log, indent=2) + "\n")
    return log


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("stage", choices=["depth", "centroid", "refiner", "cache-n0", "cache-n"])
    ap.add_argument("--data", type=Path, required=True, help="the synthetic set (tre synth)")
    ap.add_argument("--splits", type=Path, default=real.SPLITS)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--batch", type=int, default=12)
    ap.add_argument("--crop", type=int, default=128)
    ap.add_argument("--lr", type=float, default=2e-4)
    ap.add_argument(
        "--p-default",
        type=float,
        default=0.3,
        help="share of hand-held real crops given serving's default prior (60°, 1 m)",
    )
    ap.add_argument("--jitter-pitch-deg", type=float, default=3.0, help="prior: pitch ± this")
    ap.add_argument("--jitter-height", type=float, default=0.1, help="prior: height ± this share")
    ap.add_argument(
        "--street-share", type=float, default=0.5, help="share of real crops from street sets"
    )
    ap.add_argument("--init", type=Path, help="start from this checkpoint (default: committed)")
    ap.add_argument(
        "--min-step",
        type=int,
        default=0,
        help="keep no checkpoint from before this step (with --init: move away from it)",
    )
    ap.add_argument("--val-every", type=float, default=90.0, help="seconds")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument(
        "--device", default="auto", help="cpu, cuda, cuda:N or auto (CUDA where PyTorch sees it)"
    )
    ap.add_argument("--threads", type=int, default=2, help="PyTorch's CPU threads")
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    if args.stage.startswith("cache-"):
        for split in ("train", "val"):
            d = RealData(split, args.splits, "sensor", False)
            cache_outputs(args.stage.removeprefix("cache-"), d, args.seed, len(d))
        return 0
    log = run(args)
    print(json.dumps({k: v for k, v in log.items() if k != "validation"}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
