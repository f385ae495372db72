"""A random-weight ONNX graph of YOLO11n's size, for `harvest bench detector` when no real model is
at hand (nothing is downloaded: the weights are drawn from a fixed seed).

    python3 tools/bench/models/yolo_sized.py OUT.onnx --size 640

YOLO11n (detect, 80 classes) has 2.6 M parameters and 6.5 GFLOPs at 640 (Ultralytics' figures).
This graph has the same export layout (`images [1, 3, S, S]` -> `output0 [1, 84, N]`, strides 8,
16 and 32) and about the same cost: 3x3 convolutions with SiLU (stride-2 down-sampling to 16, 32,
64, 128, 256 channels, 2-3 convolutions per level), 1x1 heads per level, ~2.2 M parameters and
~5.9 GFLOPs at 640 (printed). It is a cost model, not a detector: its outputs are meaningless.
"""

import argparse

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

# (out channels, stride, repeats of the stride-1 3x3 conv after the down-sampling one)
STAGES = [(16, 2, 0), (32, 2, 2), (64, 2, 3), (128, 2, 3), (256, 2, 2)]
CLASSES = 80


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("--size", type=int, default=640)
    args = parser.parse_args()
    rng = np.random.default_rng(11)
    nodes, inits = [], []
    macs = 0
    params = 0

    def conv(x, cin, cout, k, stride, hw, act=True):
        nonlocal macs, params
        name = f"c{len(nodes)}"
        w = (rng.standard_normal((cout, cin, k, k)) * np.sqrt(2.0 / (cin * k * k))).astype(np.float32)
        b = np.zeros(cout, dtype=np.float32)
        inits.append(numpy_helper.from_array(w, name + "_w"))
        inits.append(numpy_helper.from_array(b, name + "_b"))
        pad = k // 2
        out_hw = hw // stride
        nodes.append(helper.make_node("Conv", [x, name + "_w", name + "_b"], [name], kernel_shape=[k, k],
                                      strides=[stride, stride], pads=[pad] * 4))
        macs += out_hw * out_hw * cin * cout * k * k
        params += w.size + b.size
        if not act:
            return name, out_hw
        nodes.append(helper.make_node("Sigmoid", [name], [name + "_s"]))
        nodes.append(helper.make_node("Mul", [name, name + "_s"], [name + "_a"]))
        return name + "_a", out_hw

    x, cin, hw = "images", 3, args.size
    levels = []
    for cout, stride, repeats in STAGES:
        x, hw = conv(x, cin, cout, 3, stride, hw)
        cin = cout
        for _ in range(repeats):
            x, hw = conv(x, cin, cout, 3, 1, hw)
        if hw in (args.size // 8, args.size // 16, args.size // 32):
            levels.append((x, cin, hw))
    heads = []
    for k, (feature, channels, side) in enumerate(levels):
        head, _ = conv(feature, channels, 4 + CLASSES, 1, 1, side, act=False)
        shape = f"shape{k}"
        inits.append(numpy_helper.from_array(np.array([1, 4 + CLASSES, side * side], dtype=np.int64), shape))
        nodes.append(helper.make_node("Reshape", [head, shape], [head + "_flat"]))
        heads.append(head + "_flat")
    nodes.append(helper.make_node("Concat", heads, ["raw"], axis=2))
    nodes.append(helper.make_node("Sigmoid", ["raw"], ["output0"]))
    anchors = sum((args.size // s) ** 2 for s in (8, 16, 32))
    graph = helper.make_graph(
        nodes,
        "yolo11n_sized",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, args.size, args.size])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 4 + CLASSES, anchors])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="harvest-bench")
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, args.out)
    print(f"{args.out}: {params / 1e6:.2f} M parameters, {2 * macs / 1e9:.2f} GFLOPs at {args.size}")


if __name__ == "__main__":
    main()
