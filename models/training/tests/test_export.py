"""Export: each net goes to ONNX with opset 17 and dynamic N, H, W, and ONNX Runtime agrees
with PyTorch on sizes other than the one traced."""

from __future__ import annotations

import numpy as np
import onnx
import onnxruntime as ort
import pytest

torch = pytest.importorskip(
    "torch", reason="PyTorch is not installed (never in CI); pip install -r requirements.txt"
)
# Imported after the skip: they import torch themselves.
from tre_training import export, nets  # noqa: E402


@pytest.mark.parametrize("name", ["depth_net", "neighbour_net", "centroid_net"])
def test_export_is_dynamic_and_matches_pytorch(name, tmp_path):
    torch.manual_seed(0)
    model = nets.NETS[name]().eval()
    path = tmp_path / f"{name}.onnx"
    export.export_one(name, model, path)
    graph = onnx.load(str(path))
    assert max(o.version for o in graph.opset_import if o.domain in ("", "ai.onnx")) == 17
    dims = graph.graph.input[0].type.tensor_type.shape.dim
    assert [d.dim_param or d.dim_value for d in dims] == ["N", 3, "H", "W"]
    assert export.check_parity(name, model, path) <= export.PARITY_TOLERANCE
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    inputs = nets.example_inputs(name, 3, 32, 96, seed=1)
    feed = {k: v.numpy() for k, v in zip(nets.NETS[name].input_names, inputs, strict=True)}
    got = sess.run(None, feed)[0]
    with torch.no_grad():
        ref = model(*inputs).numpy()
    assert got.shape == ref.shape
    assert np.abs(got - ref).max() <= 1e-4 * max(1.0, float(np.abs(ref).max()))


def test_conv_flops_counts_every_convolution():
    m = torch.nn.Conv2d(4, 8, 3, padding=1)
    assert nets.conv_flops(m, [torch.zeros(1, 4, 16, 16)]) == 2 * 16 * 16 * 8 * 4 * 9
