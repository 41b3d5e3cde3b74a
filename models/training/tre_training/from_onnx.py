"""Checkpoints from exported models: `python -m tre_training.from_onnx [--models DIR]`.

The export folds every batch norm into the convolution before it (ONNX Runtime sees `Conv` with
a bias only), so the PyTorch weights are recovered as: each `Conv` node, in graph order, gives
its weight to the net's convolutions in the order they run; a fused bias goes to the
convolution's own bias where it has one, else to the batch norm after it, which is set to the
identity (mean 0, variance 1 − ε, scale 1). The result computes what the ONNX file computes
(checked here against ONNX Runtime). Fine-tuning from it must keep the batch norms in eval mode
(`freeze_batch_norm`): their statistics are folded away.

Writes `checkpoints/STAGE_committed.pt` and `.json` (the manifest's training entry of that
model, so a fine-tuned model's manifest keeps its pretraining log) and, where no checkpoint of
the stage exists yet, `checkpoints/STAGE.pt` / `.json` as copies.
"""

from __future__ import annotations

import argparse
import itertools
import json
import shutil
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import torch
from onnx import numpy_helper
from torch import nn

from . import nets
from .train import CHECKPOINTS, STAGE_NET

REPO = Path(__file__).resolve().parents[3]
STAGE_OF = {v: k for k, v in STAGE_NET.items()}


def execution_order(model: nn.Module, name: str) -> list[nn.Conv2d]:
    order: list[nn.Conv2d] = []
    hooks = [
        m.register_forward_hook(lambda mod, _i, _o: order.append(mod))
        for m in model.modules()
        if isinstance(m, nn.Conv2d)
    ]
    with torch.no_grad():
        model.eval()
        model(*nets.example_inputs(name, 1, 32, 32))
    for h in hooks:
        h.remove()
    return order


def following_bn(model: nn.Module) -> dict[nn.Conv2d, nn.BatchNorm2d]:
    """Each convolution without a bias → the batch norm that follows it in its Sequential."""
    out = {}
    for m in model.modules():
        if isinstance(m, nn.Sequential):
            kids = list(m.children())
            for a, b in itertools.pairwise(kids):
                if isinstance(a, nn.Conv2d) and isinstance(b, nn.BatchNorm2d):
                    out[a] = b
    return out


def from_onnx(name: str, path: Path) -> nn.Module:
    g = onnx.load(str(path)).graph
    inits = {t.name: numpy_helper.to_array(t) for t in g.initializer}
    convs = [n for n in g.node if n.op_type == "Conv"]
    model = nets.NETS[name]()
    order = execution_order(model, name)
    bns = following_bn(model)
    if len(convs) != len(order):
        raise SystemExit(f"{name}: {len(convs)} Conv nodes, {len(order)} convolutions")
    with torch.no_grad():
        for node, conv in zip(convs, order, strict=True):
            w = inits[node.input[1]]
            if tuple(w.shape) != tuple(conv.weight.shape):
                raise SystemExit(f"{name}: shape {w.shape} vs {tuple(conv.weight.shape)}")
            conv.weight.copy_(torch.from_numpy(w.copy()))
            b = inits[node.input[2]] if len(node.input) > 2 else np.zeros(w.shape[0], np.float32)
            if conv.bias is not None:
                conv.bias.copy_(torch.from_numpy(b.copy()))
            else:
                bn = bns[conv]
                bn.weight.fill_(1.0)
                bn.bias.copy_(torch.from_numpy(b.copy()))
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
    model.eval()
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    cls = nets.NETS[name]
    inputs = nets.example_inputs(name, 2, 48, 64, seed=3)
    with torch.no_grad():
        ref = model(*inputs).numpy()
    got = sess.run(None, {k: v.numpy() for k, v in zip(cls.input_names, inputs, strict=True)})[0]
    err = float((np.abs(got - ref) / np.maximum(1.0, np.abs(ref))).max())
    if err > 1e-4:
        raise SystemExit(f"{name}: recovered weights differ from ONNX Runtime by {err:.1e}")
    print(f"{name}: weights recovered, max rel difference {err:.1e}")
    return model


def freeze_batch_norm(model: nn.Module) -> None:
    """Batch norms in eval mode (their statistics fixed) while the rest trains."""
    for m in model.modules():
        if isinstance(m, nn.BatchNorm2d):
            m.eval()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--models", type=Path, default=REPO / "models")
    args = ap.parse_args(argv)
    manifest = json.loads((args.models / "manifest.json").read_text())
    CHECKPOINTS.mkdir(exist_ok=True)
    for name, entry in manifest["models"].items():
        stage = STAGE_OF[name]
        model = from_onnx(name, args.models / entry["file"])
        torch.save(model.state_dict(), CHECKPOINTS / f"{stage}_committed.pt")
        log = {**entry.get("training", {}), "sha256": entry["sha256"]}
        log.pop("data", None)
        log["committed_data"] = entry.get("training", {}).get("data")
        (CHECKPOINTS / f"{stage}_committed.json").write_text(json.dumps(log, indent=2) + "\n")
        if not (CHECKPOINTS / f"{stage}.pt").exists():
            shutil.copy(CHECKPOINTS / f"{stage}_committed.pt", CHECKPOINTS / f"{stage}.pt")
            shutil.copy(CHECKPOINTS / f"{stage}_committed.json", CHECKPOINTS / f"{stage}.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
