"""Times the pipeline's four nets with PyTorch on CUDA (FP32 and FP16) and on the CPU, and with
ONNX Runtime on the CPU: batch 1, 8 and 32, at 256×256, 256×192 (the working size of a 640×480
frame) and 640×480 (a frame run at its own size). Writes `nets.json` and `nets.md` into `--out`.

    PYTHONPATH=models/training python scripts/gpu_nets.py --out DIR [--quick]

The weights are the committed models' (`models/*.onnx` through `tre_training.from_onnx`'s
checkpoints, made when missing); timing does not depend on them. CUDA times are CUDA-event
medians after warm-up; CPU times are wall-clock medians. Each row gives ms per batch and per
frame. The ONNX Runtime CUDA provider is not timed here: its `onnxruntime-gpu` wheel (about
250 MB) is larger than what a call to the lent GPU can carry (64 MiB), so PyTorch stands in for
it on the GPU.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from tre_training import nets
from tre_training.train import CHECKPOINTS, STAGE_NET

REPO = Path(__file__).resolve().parents[1]
PIPELINE = ("depth_net", "neighbour_net", "normal_refiner", "centroid_net")
SIZES = {"256x256": (256, 256), "256x192": (192, 256), "640x480": (480, 640)}
BATCHES = (1, 8, 32)


def load(name: str) -> torch.nn.Module:
    stage = {v: k for k, v in STAGE_NET.items()}[name]
    path = CHECKPOINTS / f"{stage}_committed.pt"
    if not path.exists():
        from tre_training import from_onnx

        from_onnx.main([])
    model = nets.NETS[name]()
    model.load_state_dict(torch.load(path, weights_only=True, map_location="cpu"))
    return model.eval()


def time_torch(model, inputs, device: str, reps: int, warm: int) -> list[float]:
    """Milliseconds per forward pass."""
    out = []
    with torch.inference_mode():
        for _ in range(warm):
            model(*inputs)
        if device == "cuda":
            torch.cuda.synchronize()
            for _ in range(reps):
                a, b = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
                a.record()
                model(*inputs)
                b.record()
                b.synchronize()
                out.append(a.elapsed_time(b))
        else:
            for _ in range(reps):
                t = time.perf_counter()
                model(*inputs)
                out.append(1e3 * (time.perf_counter() - t))
    return out


def ort_session(name: str):
    import onnxruntime as ort

    path = str(REPO / "models" / f"{name}.onnx")
    return ort.InferenceSession(path, providers=["CPUExecutionProvider"])


def time_ort(sess, name: str, inputs, reps: int) -> list[float]:
    feed = {k: v.numpy() for k, v in zip(nets.NETS[name].input_names, inputs, strict=True)}
    sess.run(None, feed)
    out = []
    for _ in range(reps):
        t = time.perf_counter()
        sess.run(None, feed)
        out.append(1e3 * (time.perf_counter() - t))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--quick", action="store_true", help="one size and batch 1 and 8 (a dry run)")
    ap.add_argument("--cpu-threads", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(args.cpu_threads)
    cuda = torch.cuda.is_available()
    sizes = {"256x192": SIZES["256x192"]} if args.quick else SIZES
    batches = (1, 8) if args.quick else BATCHES
    rows = []
    info = {
        "torch": torch.__version__,
        "cuda": torch.version.cuda if cuda else None,
        "gpu": torch.cuda.get_device_name(0) if cuda else None,
        "cpu": platform.processor() or platform.machine(),
        "cpu_threads": args.cpu_threads,
    }
    print(json.dumps(info), flush=True)
    for name in PIPELINE:
        # Each net loaded once, moved once per device and precision; one ONNX Runtime session.
        base, sess = load(name), ort_session(name)
        placed: dict[tuple, torch.nn.Module] = {}
        for size, (h, w) in sizes.items():
            for n in batches:
                x = nets.example_inputs(name, n, h, w, seed=1)
                big = n * h * w > 8 * 256 * 256
                settings = []
                if cuda:
                    settings += [("torch cuda fp32", "cuda", torch.float32)]
                    settings += [("torch cuda fp16", "cuda", torch.float16)]
                # The CPU only at batch 1 and 8, and at 640×480 at batch 1: the rest takes
                # minutes of a call that must end within ten.
                if n == 1 or (n == 8 and not big):
                    settings += [("torch cpu fp32", "cpu", torch.float32)]
                    settings += [("ort cpu fp32", None, None)]
                for label, device, dtype in settings:
                    if device is None:
                        ms = time_ort(sess, name, x, 3 if big else 5)
                    else:
                        key = (device, dtype)
                        if key not in placed:
                            placed[key] = copy.deepcopy(base).to(device=device, dtype=dtype)
                        m = placed[key]
                        xs = [t.to(device=device, dtype=dtype) for t in x]
                        reps, warm = (20, 5) if device == "cuda" else ((3, 1) if big else (5, 1))
                        ms = time_torch(m, xs, device, reps, warm)
                    med = statistics.median(ms)
                    row = {
                        "net": name,
                        "size": size,
                        "batch": n,
                        "runtime": label,
                        "ms_per_batch": round(med, 3),
                        "ms_per_frame": round(med / n, 3),
                        "reps": len(ms),
                    }
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    (args.out / "nets.json").write_text(json.dumps({"info": info, "rows": rows}, indent=1) + "\n")
    lines = [
        f"GPU: {info['gpu']}; PyTorch {info['torch']}; CPU threads {args.cpu_threads}",
        "",
        "| net | size | batch | runtime | ms / batch | ms / frame |",
        "| --- | --- | ---: | --- | ---: | ---: |",
    ]
    lines += [
        f"| {r['net']} | {r['size']} | {r['batch']} | {r['runtime']} | {r['ms_per_batch']} | "
        f"{r['ms_per_frame']} |"
        for r in rows
    ]
    # The four nets of one frame, summed, per runtime, size and batch.
    sums: dict[tuple, float] = {}
    for r in rows:
        k = (r["runtime"], r["size"], r["batch"])
        sums[k] = sums.get(k, 0.0) + r["ms_per_frame"]
    counts = {k: sum(1 for r in rows if (r["runtime"], r["size"], r["batch"]) == k) for k in sums}
    lines += [
        "",
        "| runtime | size | batch | four nets, ms / frame |",
        "| --- | --- | ---: | ---: |",
    ]
    lines += [
        f"| {k[0]} | {k[1]} | {k[2]} | {np.round(v, 2)} |"
        for k, v in sorted(sums.items())
        if counts[k] == len(PIPELINE)
    ]
    (args.out / "nets.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
