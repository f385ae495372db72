"""Tiny YOLO-layout ONNX models for the ONNX detector's tests, built deterministically.

    python3 yolo_models.py OUT_DIR

writes, for a 64 px input (84 anchors: 8x8 + 4x4 + 2x2):
- detect.onnx: `images [1,3,64,64]` -> `output0 [1, 4+2, 84]`. Class 0 (apple) of stride-8
  anchor (i, j) scores relu(2 * mean red of input cell (i, j) - 1): 1 for a cell that is wholly
  red, 0 for grey padding (114/255); its box is that 8 px cell. Class 1 (leaf) scores 0.1
  everywhere; stride-16/32 anchors score 0.
- segment.onnx: `output0 [1, 4+1+32, 84]` and `output1 [1, 32, 16, 16]`: the same apple scores
  with boxes of 24 px around each cell, coefficient 0 = 1 (the rest 0), and prototype 0 =
  20 * (mean red of each 4x4 input block) - 15 (+5 on red, -15 on black, -6 on padding).
- end2end.onnx: `output0 [1, 300, 6]` (an end-to-end head this decoder does not take).
The outputs are functions of the input computed by ONNX Runtime, so the tests check the
letterbox, the run and the decoding together.
"""

import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

SIZE = 64
GRID = SIZE // 8  # stride-8 cells per side
ANCHORS = GRID * GRID + (SIZE // 16) ** 2 + (SIZE // 32) ** 2


def const(name, array):
    return numpy_helper.from_array(np.asarray(array, dtype=np.float32), name)


def ints(name, values):
    return numpy_helper.from_array(np.asarray(values, dtype=np.int64), name)


def boxes(side):
    """[1, 4, ANCHORS]: stride-8 cells' centres with a `side` px box; other anchors empty."""
    out = np.zeros((1, 4, ANCHORS), dtype=np.float32)
    for j in range(GRID):
        for i in range(GRID):
            k = j * GRID + i
            out[0, :, k] = [(i + 0.5) * 8, (j + 0.5) * 8, side, side]
    return out


def apple_scores_nodes():
    """Nodes computing `apple [1, 1, ANCHORS]` from `images`."""
    return [
        helper.make_node("Slice", ["images", "red_start", "red_end", "channel_axis"], ["red"]),
        helper.make_node("AveragePool", ["red"], ["red8"], kernel_shape=[8, 8], strides=[8, 8]),
        helper.make_node("Reshape", ["red8", "flat_shape"], ["red8_flat"]),
        helper.make_node("Mul", ["red8_flat", "two"], ["red8_x2"]),
        helper.make_node("Sub", ["red8_x2", "one"], ["red8_shifted"]),
        helper.make_node("Relu", ["red8_shifted"], ["apple8"]),
        helper.make_node("Concat", ["apple8", "zero_tail"], ["apple"], axis=2),
    ]


def common_initializers():
    return [
        ints("red_start", [0]),
        ints("red_end", [1]),
        ints("channel_axis", [1]),
        ints("flat_shape", [1, 1, GRID * GRID]),
        const("two", 2.0),
        const("one", 1.0),
        const("zero_tail", np.zeros((1, 1, ANCHORS - GRID * GRID))),
    ]


def image_input():
    return helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, SIZE, SIZE])


def save(graph, path):
    model = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="harvest-tests"
    )
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, path)


def detect(path):
    nodes = apple_scores_nodes() + [
        helper.make_node("Concat", ["boxes", "apple", "leaf"], ["output0"], axis=1),
    ]
    inits = common_initializers() + [
        const("boxes", boxes(8.0)),
        const("leaf", np.full((1, 1, ANCHORS), 0.1)),
    ]
    out = helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 6, ANCHORS])
    save(helper.make_graph(nodes, "detect", [image_input()], [out], inits), path)


def segment(path):
    coefficients = np.zeros((1, 32, ANCHORS), dtype=np.float32)
    coefficients[0, 0, :] = 1.0
    nodes = apple_scores_nodes() + [
        helper.make_node("Concat", ["boxes", "apple", "coefficients"], ["output0"], axis=1),
        helper.make_node("AveragePool", ["red"], ["red4"], kernel_shape=[4, 4], strides=[4, 4]),
        helper.make_node("Mul", ["red4", "twenty"], ["red4_x20"]),
        helper.make_node("Sub", ["red4_x20", "fifteen"], ["proto0"]),
        helper.make_node("Concat", ["proto0", "zero_protos"], ["output1"], axis=1),
    ]
    inits = common_initializers() + [
        const("boxes", boxes(24.0)),
        const("coefficients", coefficients),
        const("twenty", 20.0),
        const("fifteen", 15.0),
        const("zero_protos", np.zeros((1, 31, SIZE // 4, SIZE // 4))),
    ]
    outputs = [
        helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 37, ANCHORS]),
        helper.make_tensor_value_info("output1", TensorProto.FLOAT, [1, 32, SIZE // 4, SIZE // 4]),
    ]
    save(helper.make_graph(nodes, "segment", [image_input()], outputs, inits), path)


def end2end(path):
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["mean"], axes=[1, 2, 3], keepdims=1),
        helper.make_node("Reshape", ["mean", "scalar_shape"], ["mean_flat"]),
        helper.make_node("Add", ["mean_flat", "rows"], ["output0"]),
    ]
    inits = [ints("scalar_shape", [1, 1, 1]), const("rows", np.zeros((1, 300, 6)))]
    out = helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 300, 6])
    save(helper.make_graph(nodes, "end2end", [image_input()], [out], inits), path)


def main():
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    detect(os.path.join(out_dir, "detect.onnx"))
    segment(os.path.join(out_dir, "segment.onnx"))
    end2end(os.path.join(out_dir, "end2end.onnx"))


if __name__ == "__main__":
    main()
