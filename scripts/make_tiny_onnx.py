#!/usr/bin/env python3
"""Write tests/fixtures/tiny_conv.onnx, the model the ONNX Runtime integration test runs.

    python3 scripts/make_tiny_onnx.py [--out PATH]

y = relu(conv3x3(x, W, padding=1) + b), x and y float32 [N, 1, H, W] with N, H, W dynamic,
opset 17. The weights are fixed, non-symmetric and of both signs so that a transposed or
flipped kernel, a missing bias or a missing ReLU all change the output;
crates/tre-model/tests/model/ort_runtime.rs holds the same numbers. The output file is
committed, so only regenerating it needs the `onnx` package (`pip install onnx`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import onnx
from onnx import TensorProto, helper

# Row-major 3x3 kernel (cross-correlation, as ONNX Conv defines it) and bias.
# Keep in step with WEIGHTS and BIAS in crates/tre-model/tests/model/ort_runtime.rs.
WEIGHTS = [0.5, -1.0, 0.25, 1.5, 2.0, -0.75, -0.5, 0.125, 1.0]
BIAS = -0.1
OPSET = 17
IR_VERSION = 8  # the IR version that goes with opset 17; older runtimes read it too
DEFAULT_OUT = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "tiny_conv.onnx"


def build_model() -> onnx.ModelProto:
    """The conv + relu graph with dynamic N, H, W."""
    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", 1, "H", "W"])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", 1, "H", "W"])
    weight = helper.make_tensor("weight", TensorProto.FLOAT, [1, 1, 3, 3], WEIGHTS)
    bias = helper.make_tensor("bias", TensorProto.FLOAT, [1], [BIAS])
    conv = helper.make_node(
        "Conv",
        ["x", "weight", "bias"],
        ["conv"],
        name="conv",
        kernel_shape=[3, 3],
        pads=[1, 1, 1, 1],
    )
    relu = helper.make_node("Relu", ["conv"], ["y"], name="relu")
    graph = helper.make_graph([conv, relu], "tiny_conv", [x], [y], initializer=[weight, bias])
    model = helper.make_model(
        graph,
        producer_name="tre-tests",
        opset_imports=[helper.make_opsetid("", OPSET)],
        ir_version=IR_VERSION,
    )
    model.doc_string = (
        "3x3 conv (padding 1) + bias + relu;"
        " fixture for crates/tre-model/tests/model/ort_runtime.rs"
    )
    onnx.checker.check_model(model, full_check=True)
    return model


def main() -> None:
    """Build, check and write the model."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output .onnx path")
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save_model(build_model(), args.out)
    print(args.out)


if __name__ == "__main__":
    main()
