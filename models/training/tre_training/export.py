"""Exports the trained stages to ONNX and writes `models/manifest.json`:
`python -m tre_training.export [--data DIR]`.

Each net is exported with opset 17 and dynamic N, H, W (H and W multiples of `nets.STRIDE`),
checked against PyTorch with ONNX Runtime on two input sizes, and described in the manifest: file,
SHA-256, input and output names and shapes, normalisation, opset, FLOPs per 256×256 frame,
parameters, the training log (data, steps, time, device) and the commit. Parity vectors for the
Rust side go to `tests/fixtures/onnx_parity/NAME.npz`-like folders of `.npy` files.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import torch

from . import nets
from .geometry import prior_depth
from .train import CHECKPOINTS, STAGE_NET

REPO = Path(__file__).resolve().parents[3]
MODELS = REPO / "models"
PARITY = REPO / "tests" / "fixtures" / "onnx_parity"
OPSET = 17
PARITY_TOLERANCE = 1e-4
"""Largest |ONNX Runtime − PyTorch| accepted per output element (relative to max(1, |y|))."""
NORMALISATION = {
    "rgb": "RGB in [0, 1] (8-bit / 255); (x − 0.45) / 0.25 is applied inside the graph",
    "prior_depth_m": "flat-ground depth in metres from intrinsics, pitch and height (20 m where"
    " the ray misses the ground); log taken inside the graph",
    "points_m": "camera-frame points in metres (OpenCV axes), 0 where invalid",
    "valid": "1 where the pixel has a point, else 0",
    "normals_init": "unit DSAC normals in the camera frame, facing the camera; 0 where none",
    "normals": "unit normals in the camera frame, facing the camera; 0 where none",
}
STAGE_OF = {v: k for k, v in STAGE_NET.items()}


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def load_net(name: str, allow_untrained: bool) -> tuple[torch.nn.Module, dict | None]:
    model = nets.NETS[name]()
    ckpt = CHECKPOINTS / f"{STAGE_OF[name]}.pt"
    log = None
    if ckpt.exists():
        model.load_state_dict(torch.load(ckpt, weights_only=True))
        log = json.loads((CHECKPOINTS / f"{STAGE_OF[name]}.json").read_text())
        if log.get("init"):
            # Fine-tuned: keep the log of the run it started from.
            base = CHECKPOINTS / Path(log["init"]).with_suffix(".json").name
            log["pretraining"] = json.loads(base.read_text())
    elif not allow_untrained:
        raise SystemExit(f"{name}: no checkpoint {ckpt}; train it first")
    return model.eval(), log


def export_one(name: str, model: torch.nn.Module, path: Path) -> None:
    cls = nets.NETS[name]
    dyn = {k: {0: "N", 2: "H", 3: "W"} for k in (*cls.input_names, *cls.output_names)}
    torch.onnx.export(
        model,
        tuple(nets.example_inputs(name, 1, 64, 64)),
        str(path),
        input_names=list(cls.input_names),
        output_names=list(cls.output_names),
        dynamic_axes=dyn,
        opset_version=OPSET,
        dynamo=False,
    )


def check_parity(name: str, model: torch.nn.Module, path: Path) -> float:
    """Largest relative difference between ONNX Runtime and PyTorch over two input sizes."""
    cls = nets.NETS[name]
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    worst = 0.0
    for n, h, w in ((1, 64, 64), (2, 48, 80)):
        inputs = nets.example_inputs(name, n, h, w, seed=h)
        with torch.no_grad():
            ref = model(*inputs).numpy()
        got = sess.run(None, {k: v.numpy() for k, v in zip(cls.input_names, inputs, strict=True)})[
            0
        ]
        worst = max(worst, float((np.abs(got - ref) / np.maximum(1.0, np.abs(ref))).max()))
    if worst > PARITY_TOLERANCE:
        raise SystemExit(f"{name}: ONNX Runtime differs from PyTorch by {worst:.2e}")
    return worst


def write_vectors(name: str, model: torch.nn.Module) -> None:
    """Inputs and PyTorch outputs at 1×·×32×48 for the Rust parity test."""
    cls = nets.NETS[name]
    out = PARITY / name
    out.mkdir(parents=True, exist_ok=True)
    inputs = nets.example_inputs(name, 1, 32, 48, seed=7)
    with torch.no_grad():
        y = model(*inputs)
    for k, v in zip(cls.input_names, inputs, strict=True):
        np.save(out / f"input_{k}.npy", v.numpy().astype(np.float32))
    np.save(out / f"output_{cls.output_names[0]}.npy", y.numpy().astype(np.float32))


def write_prior_vectors() -> None:
    """The flat-ground prior depth for two cameras (one looking above the horizon), for the Rust
    side's `prior_depth`; float32 maps, compared within 1e-5 relative."""
    cases = []
    for k, mount, (w, h) in (
        ([40.0, 42.0, 15.5, 9.5], (np.deg2rad(60.0), 1.0), (32, 20)),
        ([20.0, 20.0, 16.0, 12.0], (np.deg2rad(10.0), 0.4), (32, 24)),
    ):
        prior = prior_depth(torch.tensor([k]), torch.tensor([mount], dtype=torch.float32), h, w)[
            0, 0
        ]
        cases.append(
            {
                "intrinsics": k,
                "pitch_rad": float(mount[0]),
                "height_m": mount[1],
                "width": w,
                "height": h,
                "prior_depth_m": [round(float(v), 6) for v in prior.reshape(-1)],
            }
        )
    PARITY.mkdir(parents=True, exist_ok=True)
    (PARITY / "prior_depth.json").write_text(json.dumps({"cases": cases}) + "\n")


def io_spec(names: tuple[str, ...], channels: dict[str, int]) -> list[dict]:
    return [{"name": k, "shape": ["N", channels[k], "H", "W"], "dtype": "float32"} for k in names]


def dataset_info(data: Path | None) -> dict | None:
    if data is None:
        return None
    m = json.loads((data / "dataset.json").read_text())
    keep = {k: v for k, v in m.items() if k not in ("scenes", "labels")}
    return {"generator": "tre synth", "folder": data.name, **keep}


def real_data_info(sequences: list[str]) -> dict:
    """Which real sets a model was trained on, and their licences (from each set's
    `intrinsics.json`): the restriction a model trained on them carries."""
    from . import real

    sets = {}
    for seq in sequences:
        cam = json.loads((real.find_folder(seq) / "intrinsics.json").read_text())
        sets[seq] = {"source": cam.get("source"), "licence": cam.get("licence")}
    named = {
        "kitti": "KITTI (CC BY-NC-SA 3.0)",
        "nuscenes": "nuScenes (CC BY-NC-SA 4.0 and its terms of use)",
        "sevenscenes": "Microsoft 7-Scenes (non-commercial research use)",
    }
    used = [v for k, v in named.items() if any(q.startswith(k) for q in sequences)]
    return {
        "splits": "models/real_splits.json, split train (val chose the checkpoint; test unused)",
        "sets": sets,
        "restriction": f"trained on frames of {', '.join(used)}: licensed for non-commercial"
        " research use only; this model carries that restriction",
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", type=Path, help="the training dataset, described in the manifest")
    ap.add_argument("--metrics", type=Path, help="JSON of test metrics per model (tre eval)")
    ap.add_argument("--allow-untrained", action="store_true", help="export random weights")
    ap.add_argument(
        "--nets",
        nargs="+",
        choices=list(nets.NETS),
        help="export only these; the others keep their files, parity vectors and manifest entries",
    )
    args = ap.parse_args(argv)
    previous = (
        json.loads((MODELS / "manifest.json").read_text())["models"]
        if (MODELS / "manifest.json").exists()
        else {}
    )
    commit = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True, check=False
    ).stdout.strip()
    metrics = json.loads(args.metrics.read_text()) if args.metrics else {}
    manifest: dict = {
        "format": 1,
        "stride": nets.STRIDE,
        "working_size": [256, 256],
        "layout": "NCHW float32; N, H and W dynamic; H and W multiples of stride",
        "models": {},
    }
    data = dataset_info(args.data)
    write_prior_vectors()
    for name, cls in nets.NETS.items():
        if args.nets and name not in args.nets and name in previous:
            manifest["models"][name] = previous[name]
            print(f"{name}: kept as it was ({previous[name]['sha256'][:12]})")
            continue
        model, log = load_net(name, args.allow_untrained)
        if log is not None and log.get("real_sets"):
            log["real_data"] = real_data_info(log["real_sets"])
        path = MODELS / f"{name}.onnx"
        export_one(name, model, path)
        opset = max(
            o.version for o in onnx.load(str(path)).opset_import if o.domain in ("", "ai.onnx")
        )
        worst = check_parity(name, model, path)
        write_vectors(name, model)
        flops = nets.conv_flops(model, nets.example_inputs(name, 1, 256, 256))
        manifest["models"][name] = {
            "file": path.name,
            "sha256": sha256(path),
            "opset": opset,
            "inputs": io_spec(cls.input_names, nets.INPUT_CHANNELS),
            "outputs": io_spec(cls.output_names, nets.OUTPUT_CHANNELS),
            "normalisation": {k: NORMALISATION[k] for k in cls.input_names},
            "flops_256x256": flops,
            "parameters": sum(p.numel() for p in model.parameters()),
            "onnx_vs_pytorch_max_rel_error": worst,
            "trained": log is not None,
            "training": {**(log or {}), "data": data, "commit": commit},
            "metrics": metrics.get(name, {}),
        }
        print(f"{name}: {flops / 1e9:.2f} GFLOP/256², parity {worst:.1e}, {path.stat().st_size} B")
    pipeline = sum(m["flops_256x256"] for k, m in manifest["models"].items() if k != "end_to_end")
    manifest["pipeline_flops_256x256"] = pipeline
    (MODELS / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    print(f"four stages together: {pipeline / 1e9:.2f} GFLOP per 256×256 frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
