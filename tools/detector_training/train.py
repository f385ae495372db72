"""Trains harvest's own apple segmenter on the simulator's renders and exports it to ONNX in the
YOLOv8/YOLO11 segment layout perception's ONNX detector reads.

    python3 tools/detector_training/train.py --data DATASET_DIR --out models/apples_sim.onnx

DATASET_DIR is written by `harvest dataset detector` (images at the 640 input's scale, YOLO
labels, instance masks, index.jsonl with every visible apple). See
tools/detector_training/README.md for the exact commands, the tools and why.

The model ("apple-net"): a small fully convolutional network with one stride-8 head and a
stride-4 prototype branch, ReLU activations.
    3 -> 8 (3x3, /2) -> 16 (3x3, /4) -> 32 (3x3, /8) -> four residual 3x3 blocks of 32 channels
    (dilation 1, 2, 4, 1: a receptive field of about 100 input pixels, several apple diameters)
    -> 1x1 head: 4 box distances (left, top, right, bottom from the cell centre,
    exp(.) * 8 px) and 1 apple score (sigmoid); 1x1: 32 mask coefficients.
    Prototypes: 3x3 on the stride-8 features, upsampled x2 (nearest), joined with the stride-4
    features (16 channels), 3x3 -> 16, 1x1 -> 32 prototypes at a quarter of the input.
The export appends the anchors of strides 16 and 32 with zero scores so the output is the
standard `[1, 4 + 1 + 32, 8400]` of a 640 YOLO segment export (plus prototypes `[1, 32, 160,
160]`): apples are 10-70 px at 640, all within the stride-8 head's range. An apple's mask is
`sigmoid(coefficients . prototypes)` inside its box, as Ultralytics' segment heads.

Training: crops of 256x256 from the letterboxed 640x640 canvas (the grey padding included, so
the model learns that padding is no apple), photometric augmentation (exposure gain with
clipping, gamma, channel gains, noise, horizontal flips), focal loss on the score with the
cells near each labelled apple's centre positive and cells of barely visible apples ignored,
GIoU loss on the boxes of positive cells, binary cross-entropy of the masks of (up to 24 per
crop) positive cells against their apple's visible pixels inside its box (the renderer's label
image, `masks/`), Adam with a cosine schedule. Deterministic for a
given --seed on one machine (numpy's generator draws the crops and augmentations; XLA on CPU).
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=true")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import optax  # noqa: E402
from PIL import Image  # noqa: E402

STRIDE = 8
INPUT = 640
PAD = 114
CROP = 256
# (name, in, out, kernel, stride, dilation, residual)
LAYERS = [
    ("c1", 3, 8, 3, 2, 1, False),
    ("c2", 8, 16, 3, 2, 1, False),
    ("c3", 16, 32, 3, 2, 1, False),
    ("r1", 32, 32, 3, 1, 1, True),
    ("r2", 32, 32, 3, 1, 2, True),
    ("r3", 32, 32, 3, 1, 4, True),
    ("r4", 32, 32, 3, 1, 1, True),
]
HEAD = ("head", 32, 5, 1, 1, 1, False)
# The segment head: mask coefficients at stride 8, prototypes at stride 4 from the stride-8
# features (upsampled) joined with c2's stride-4 features.
COEF = ("coef", 32, 32, 1, 1, 1, False)
PROTO = [
    ("p1", 32, 32, 3, 1, 1, False),
    ("p2", 48, 16, 3, 1, 1, False),
    ("p3", 16, 32, 1, 1, 1, False),
]
MASKS = 32
PROTO_STRIDE = 4
MASK_CELLS = 24  # positive cells per crop whose masks are trained
PRIOR = 0.01


def init_params(key):
    params = {}
    for name, cin, cout, k, _, _, residual in LAYERS + [HEAD, COEF] + PROTO:
        key, sub = jax.random.split(key)
        fan_in = cin * k * k
        scale = math.sqrt(2.0 / fan_in) * (0.3 if residual else 1.0)
        if name in ("head", "coef"):
            scale = 0.01  # scores at the prior, masks at 0.5: small first gradients
        w = jax.random.normal(sub, (k, k, cin, cout), jnp.float32) * scale
        b = jnp.zeros((cout,), jnp.float32)
        if name == "head":
            # Box distances start at 1.5 cells (an apple of 24 px), scores at the prior.
            b = b.at[:4].set(math.log(1.5)).at[4].set(math.log(PRIOR / (1 - PRIOR)))
        params[name] = {"w": w, "b": b}
    return params


def conv(x, p, stride, dilation):
    k = p["w"].shape[0]
    pad = dilation * (k // 2)
    y = jax.lax.conv_general_dilated(
        x,
        p["w"],
        window_strides=(stride, stride),
        padding=((pad, pad), (pad, pad)),
        rhs_dilation=(dilation, dilation),
        dimension_numbers=("NHWC", "HWIO", "NHWC"),
    )
    return y + p["b"]


def forward(params, images):
    """images: [B, H, W, 3] in 0-1. Returns the raw head [B, H/8, W/8, 5], the mask
    coefficients [B, H/8, W/8, 32] and the prototypes [B, H/4, W/4, 32]."""
    x = images
    stride4 = None
    for name, _, _, _, stride, dilation, residual in LAYERS:
        y = jax.nn.relu(conv(x, params[name], stride, dilation))
        x = x + y if residual else y
        if name == "c2":
            stride4 = x
    head = conv(x, params["head"], 1, 1)
    coefficients = conv(x, params["coef"], 1, 1)
    up = jax.nn.relu(conv(x, params["p1"], 1, 1))
    up = jnp.repeat(jnp.repeat(up, 2, axis=1), 2, axis=2)
    p = jax.nn.relu(conv(jnp.concatenate([stride4, up], axis=-1), params["p2"], 1, 1))
    protos = conv(p, params["p3"], 1, 1)
    return head, coefficients, protos


def decode_boxes(raw):
    """Raw head [B, gh, gw, 5] -> boxes x0, y0, x1, y1 in input pixels [B, gh, gw, 4]."""
    gh, gw = raw.shape[1], raw.shape[2]
    cx = (jnp.arange(gw, dtype=jnp.float32) + 0.5) * STRIDE
    cy = (jnp.arange(gh, dtype=jnp.float32) + 0.5) * STRIDE
    d = jnp.exp(jnp.clip(raw[..., :4], -4.0, 4.0)) * STRIDE
    x0 = cx[None, None, :] - d[..., 0]
    y0 = cy[None, :, None] - d[..., 1]
    x1 = cx[None, None, :] + d[..., 2]
    y1 = cy[None, :, None] + d[..., 3]
    return jnp.stack([x0, y0, x1, y1], axis=-1)


def giou(a, b):
    ix0 = jnp.maximum(a[..., 0], b[..., 0])
    iy0 = jnp.maximum(a[..., 1], b[..., 1])
    ix1 = jnp.minimum(a[..., 2], b[..., 2])
    iy1 = jnp.minimum(a[..., 3], b[..., 3])
    inter = jnp.clip(ix1 - ix0, 0) * jnp.clip(iy1 - iy0, 0)
    area_a = (a[..., 2] - a[..., 0]) * (a[..., 3] - a[..., 1])
    area_b = (b[..., 2] - b[..., 0]) * (b[..., 3] - b[..., 1])
    union = area_a + area_b - inter + 1e-6
    iou = inter / union
    cx0 = jnp.minimum(a[..., 0], b[..., 0])
    cy0 = jnp.minimum(a[..., 1], b[..., 1])
    cx1 = jnp.maximum(a[..., 2], b[..., 2])
    cy1 = jnp.maximum(a[..., 3], b[..., 3])
    hull = (cx1 - cx0) * (cy1 - cy0) + 1e-6
    return iou - (hull - union) / hull


def loss_fn(params, images, score_target, score_weight, box_target, mask_cell, mask_target,
            mask_region):
    raw, coefficients, protos = forward(params, images)
    logits = raw[..., 4]
    p = jax.nn.sigmoid(logits)
    # Focal loss (gamma 2, alpha 0.25), normalised by the positive cells.
    bce = optax.sigmoid_binary_cross_entropy(logits, score_target)
    pt = score_target * p + (1 - score_target) * (1 - p)
    alpha = score_target * 0.25 + (1 - score_target) * 0.75
    focal = alpha * (1 - pt) ** 2 * bce * score_weight
    positives = jnp.maximum(jnp.sum(score_target), 1.0)
    score_loss = jnp.sum(focal) / positives
    boxes = decode_boxes(raw)
    g = giou(boxes, box_target)
    box_loss = jnp.sum((1.0 - g) * score_target) / positives
    # Masks: the coefficients of the chosen cells (mask_cell: flat cell index, -1 for none)
    # against the prototypes, BCE with the apple's visible share of each prototype cell inside
    # its (widened) box, each mask normalised by its region's area.
    batch, gh, gw, _ = coefficients.shape
    flat = coefficients.reshape(batch, gh * gw, MASKS)
    chosen = jnp.take_along_axis(flat, jnp.maximum(mask_cell, 0)[..., None], axis=1)  # [B,P,32]
    logits_mask = jnp.einsum("bpc,bhwc->bphw", chosen, protos)
    valid = (mask_cell >= 0).astype(jnp.float32)
    bce_mask = optax.sigmoid_binary_cross_entropy(logits_mask, mask_target) * mask_region
    per_mask = jnp.sum(bce_mask, axis=(2, 3)) / jnp.maximum(jnp.sum(mask_region, axis=(2, 3)), 1.0)
    mask_loss = jnp.sum(per_mask * valid) / jnp.maximum(jnp.sum(valid), 1.0)
    return score_loss + 2.0 * box_loss + mask_loss, (score_loss, box_loss, mask_loss)


def load_dataset(data_dirs, limit):
    entries = []
    for data_dir in data_dirs:
        with open(os.path.join(data_dir, "index.jsonl")) as index:
            for line in index:
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:
                    break  # a data set still being written: its complete lines only
                if max(entry["width_px"], entry["height_px"]) != INPUT:
                    raise SystemExit(f"{data_dir}: image {entry['image']} is {entry['width_px']}x"
                                     f"{entry['height_px']}; this network's input is {INPUT} "
                                     f"(render with --input-size {INPUT})")
                entry["image"] = os.path.join(data_dir, entry["image"])
                entries.append(entry)
    if limit:
        entries = entries[:limit]
    images, masks = [], []
    for entry in entries:
        with Image.open(entry["image"]) as im:
            images.append(np.asarray(im.convert("RGB"), dtype=np.uint8))
        mask_path = os.path.join(os.path.dirname(os.path.dirname(entry["image"])), "masks",
                                 os.path.basename(entry["image"]))
        if not os.path.exists(mask_path):
            raise SystemExit(f"{mask_path}: missing (data sets need masks/: render them again "
                             "with this build's `harvest dataset detector`)")
        with Image.open(mask_path) as im:
            mask = np.asarray(im, dtype=np.uint16)
        if mask.shape != images[-1].shape[:2]:
            raise SystemExit(f"{mask_path}: {mask.shape} differs from its image's "
                             f"{images[-1].shape[:2]}")
        masks.append(mask)
    return entries, images, masks


def canvas_of(image, fill=PAD):
    """The image letterboxed into the 640x640 canvas (`fill` around it), and its top-left
    offset."""
    h, w = image.shape[:2]
    canvas = np.full((INPUT, INPUT) + image.shape[2:], fill, dtype=image.dtype)
    left = int(round((INPUT - w) / 2 - 0.1))
    top = int(round((INPUT - h) / 2 - 0.1))
    canvas[top : top + h, left : left + w] = image
    return canvas, left, top


def targets(boxes, ignores, grid):
    """Score target, score weight, box target and owner (index into `boxes`, -1 for none) on a
    grid x grid stride-8 map of one crop."""
    score = np.zeros((grid, grid), np.float32)
    weight = np.ones((grid, grid), np.float32)
    owner = np.full((grid, grid), -1, np.int32)
    box_target = np.zeros((grid, grid, 4), np.float32)
    box_target[..., 2:] = 1.0  # a valid dummy box where the box loss is masked out
    centres = (np.arange(grid, dtype=np.float32) + 0.5) * STRIDE
    for x0, y0, x1, y1 in ignores:
        inside_x = (centres >= x0) & (centres <= x1)
        inside_y = (centres >= y0) & (centres <= y1)
        weight[np.ix_(inside_y, inside_x)] = 0.0
    # Larger boxes first, so a smaller apple's centre cells win where two overlap.
    order = sorted(range(len(boxes)), key=lambda i: -(boxes[i][2] - boxes[i][0]) * (boxes[i][3] - boxes[i][1]))
    for index in order:
        x0, y0, x1, y1 = boxes[index]
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        rx = max(0.25 * (x1 - x0), 0.6 * STRIDE)
        ry = max(0.25 * (y1 - y0), 0.6 * STRIDE)
        in_x = (np.abs(centres - cx) <= rx) & (centres > x0) & (centres < x1)
        in_y = (np.abs(centres - cy) <= ry) & (centres > y0) & (centres < y1)
        if not in_x.any():
            in_x[np.clip(int(cx // STRIDE), 0, grid - 1)] = True
        if not in_y.any():
            in_y[np.clip(int(cy // STRIDE), 0, grid - 1)] = True
        cells = np.ix_(in_y, in_x)
        score[cells] = 1.0
        weight[cells] = 1.0
        box_target[cells] = (x0, y0, x1, y1)
        owner[cells] = index
    return score, weight, box_target, owner


def mask_targets(rng, owner, boxes, instance_masks):
    """Up to MASK_CELLS positive cells of one crop (flat indices, -1 padding), each with its
    apple's visible share of every prototype cell and the region its loss counts in (the box,
    one prototype cell wider)."""
    side = CROP // PROTO_STRIDE
    cells = np.full((MASK_CELLS,), -1, np.int32)
    target = np.zeros((MASK_CELLS, side, side), np.float32)
    region = np.zeros((MASK_CELLS, side, side), np.float32)
    positives = np.flatnonzero(owner.ravel() >= 0)
    if len(positives) > MASK_CELLS:
        positives = rng.choice(positives, MASK_CELLS, replace=False)
    for slot, cell in enumerate(positives):
        index = owner.ravel()[cell]
        x0, y0, x1, y1 = boxes[index]
        cells[slot] = cell
        target[slot] = instance_masks[index]
        gx0 = max(int(math.floor(x0 / PROTO_STRIDE)) - 1, 0)
        gy0 = max(int(math.floor(y0 / PROTO_STRIDE)) - 1, 0)
        gx1 = min(int(math.ceil(x1 / PROTO_STRIDE)) + 1, side)
        gy1 = min(int(math.ceil(y1 / PROTO_STRIDE)) + 1, side)
        region[slot, gy0:gy1, gx0:gx1] = 1.0
    return cells, target, region


def visible_share(mask_crop):
    """A crop's boolean apple mask -> its share of each prototype cell (block mean)."""
    side = CROP // PROTO_STRIDE
    return mask_crop.reshape(side, PROTO_STRIDE, side, PROTO_STRIDE).mean(axis=(1, 3), dtype=np.float32)


def sample_batch(rng, entries, canvases, mask_canvases, batch):
    grid = CROP // STRIDE
    side = CROP // PROTO_STRIDE
    images = np.empty((batch, CROP, CROP, 3), np.float32)
    score = np.empty((batch, grid, grid), np.float32)
    weight = np.empty((batch, grid, grid), np.float32)
    box_target = np.empty((batch, grid, grid, 4), np.float32)
    mask_cell = np.empty((batch, MASK_CELLS), np.int32)
    mask_target = np.empty((batch, MASK_CELLS, side, side), np.float32)
    mask_region = np.empty((batch, MASK_CELLS, side, side), np.float32)
    for b in range(batch):
        k = rng.integers(len(entries))
        canvas, left, top = canvases[k]
        mask_canvas = mask_canvases[k]
        h, w = entries[k]["height_px"], entries[k]["width_px"]
        # Mostly inside the image, sometimes over the padding.
        ox = int(rng.integers(0, INPUT - CROP + 1))
        oy = int(rng.integers(max(top - 64, 0), min(top + h - CROP + 64, INPUT - CROP) + 1))
        crop = canvas[oy : oy + CROP, ox : ox + CROP].astype(np.float32) / 255.0
        mask_crop = mask_canvas[oy : oy + CROP, ox : ox + CROP]
        flip = rng.random() < 0.5
        if flip:
            crop = crop[:, ::-1]
            mask_crop = mask_crop[:, ::-1]
        # Exposure: gain with clipping (over- and under-exposure), gamma, white balance, noise.
        gain = math.exp(rng.uniform(math.log(0.55), math.log(1.8)))
        gamma = math.exp(rng.uniform(math.log(0.7), math.log(1.4)))
        channel = rng.uniform(0.88, 1.12, size=3).astype(np.float32)
        crop = np.clip(crop * gain * channel, 0.0, 1.0) ** gamma
        sigma = rng.uniform(0.0, 0.03)
        crop = np.clip(crop + rng.normal(0.0, sigma, crop.shape).astype(np.float32), 0.0, 1.0)
        boxes, ignores, instance_masks = [], [], []
        for apple in entries[k]["apples"]:
            x0, y0, x1, y1 = apple["box_px"]
            x0, x1 = x0 + left - ox, x1 + left - ox
            y0, y1 = y0 + top - oy, y1 + top - oy
            if flip:
                x0, x1 = CROP - x1, CROP - x0
            # Apples cut by the crop: labelled if most of their box stays in it.
            cx0, cy0 = max(x0, 0.0), max(y0, 0.0)
            cx1, cy1 = min(x1, float(CROP)), min(y1, float(CROP))
            if cx1 <= cx0 or cy1 <= cy0:
                continue
            kept = (cx1 - cx0) * (cy1 - cy0) / max((x1 - x0) * (y1 - y0), 1e-6)
            if apple["labelled"] and kept >= 0.6:
                boxes.append((cx0, cy0, cx1, cy1))
                instance_masks.append(visible_share(mask_crop == apple["mask_value"]))
            else:
                ignores.append((cx0, cy0, cx1, cy1))
        images[b] = crop
        score[b], weight[b], box_target[b], owner = targets(boxes, ignores, grid)
        mask_cell[b], mask_target[b], mask_region[b] = mask_targets(rng, owner, boxes, instance_masks)
    return images, score, weight, box_target, mask_cell, mask_target, mask_region


def export_onnx(params, path, opset=17):
    """The trained network as a [1, 3, 640, 640] -> [1, 37, 8400] + [1, 32, 160, 160] YOLO
    segment export."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    nodes, inits = [], []

    def const(name, value, dtype=np.float32):
        inits.append(numpy_helper.from_array(np.asarray(value, dtype=dtype), name))
        return name

    def conv_node(layer, x, relu):
        name, _, _, k, stride, dilation, _ = layer
        w = np.transpose(np.asarray(params[name]["w"]), (3, 2, 0, 1))  # HWIO -> OIHW
        const(f"{name}.w", w)
        const(f"{name}.b", np.asarray(params[name]["b"]))
        pad = dilation * (k // 2)
        out = f"{name}.conv"
        nodes.append(
            helper.make_node(
                "Conv",
                [x, f"{name}.w", f"{name}.b"],
                [out],
                kernel_shape=[k, k],
                strides=[stride, stride],
                dilations=[dilation, dilation],
                pads=[pad, pad, pad, pad],
            )
        )
        if not relu:
            return out
        nodes.append(helper.make_node("Relu", [out], [f"{name}.relu"]))
        return f"{name}.relu"

    x = "images"
    stride4 = None
    for layer in LAYERS:
        name, residual = layer[0], layer[6]
        y = conv_node(layer, x, relu=True)
        if residual:
            nodes.append(helper.make_node("Add", [x, y], [f"{name}.out"]))
            x = f"{name}.out"
        else:
            x = y
        if name == "c2":
            stride4 = x
    head = conv_node(HEAD, x, relu=False)
    coefficients = conv_node(COEF, x, relu=False)
    up = conv_node(PROTO[0], x, relu=True)
    const("up.scales", [1.0, 1.0, 2.0, 2.0])
    nodes.append(
        helper.make_node(
            "Resize",
            [up, "", "up.scales"],
            ["up.x2"],
            mode="nearest",
            coordinate_transformation_mode="asymmetric",
            nearest_mode="floor",
        )
    )
    nodes.append(helper.make_node("Concat", [stride4, "up.x2"], ["p.in"], axis=1))
    p = conv_node(PROTO[1], "p.in", relu=True)
    protos = conv_node(PROTO[2], p, relu=False)
    nodes.append(helper.make_node("Identity", [protos], ["output1"]))

    grid = INPUT // STRIDE
    n8 = grid * grid
    n_rest = (INPUT // 16) ** 2 + (INPUT // 32) ** 2
    channels = 5 + MASKS
    # head [1, 5, 80, 80] -> [1, 5, 6400]; distances exp(.) * 8 px; score sigmoid.
    const("flat", [1, 5, n8], np.int64)
    nodes.append(helper.make_node("Reshape", [head, "flat"], ["head_flat"]))
    const("coef.flat", [1, MASKS, n8], np.int64)
    nodes.append(helper.make_node("Reshape", [coefficients, "coef.flat"], ["coef8"]))
    const("split", [4, 1], np.int64)
    nodes.append(helper.make_node("Split", ["head_flat", "split"], ["dist_raw", "score_raw"], axis=1))
    nodes.append(helper.make_node("Exp", ["dist_raw"], ["dist_exp"]))
    const("stride", float(STRIDE))
    nodes.append(helper.make_node("Mul", ["dist_exp", "stride"], ["dist"]))
    nodes.append(helper.make_node("Sigmoid", ["score_raw"], ["score8"]))
    const("split2", [2, 2], np.int64)
    nodes.append(helper.make_node("Split", ["dist", "split2"], ["lt", "rb"], axis=1))
    centres = (np.arange(grid, dtype=np.float32) + 0.5) * STRIDE
    gx, gy = np.meshgrid(centres, centres)
    const("anchors", np.stack([gx.ravel(), gy.ravel()])[None])  # [1, 2, 6400]
    const("half", 0.5)
    # cx, cy = anchor + (rb - lt) / 2 ; w, h = lt + rb
    nodes.append(helper.make_node("Sub", ["rb", "lt"], ["rb_minus_lt"]))
    nodes.append(helper.make_node("Mul", ["rb_minus_lt", "half"], ["offset"]))
    nodes.append(helper.make_node("Add", ["anchors", "offset"], ["centre"]))
    nodes.append(helper.make_node("Add", ["lt", "rb"], ["size"]))
    nodes.append(helper.make_node("Concat", ["centre", "size", "score8", "coef8"], ["pred8"], axis=1))
    const("coarse", np.zeros((1, channels, n_rest)))
    nodes.append(helper.make_node("Concat", ["pred8", "coarse"], ["output0"], axis=2))
    side = INPUT // PROTO_STRIDE
    graph = helper.make_graph(
        nodes,
        "apple-net",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, INPUT, INPUT])],
        [
            helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, channels, n8 + n_rest]),
            helper.make_tensor_value_info("output1", TensorProto.FLOAT, [1, MASKS, side, side]),
        ],
        inits,
    )
    model = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", opset)], producer_name="harvest-detector-training"
    )
    model.ir_version = 8
    model.metadata_props.append(onnx.StringStringEntryProto(key="names", value="{0: 'apple'}"))
    model.metadata_props.append(onnx.StringStringEntryProto(key="stride", value="8"))
    model.metadata_props.append(onnx.StringStringEntryProto(key="task", value="segment"))
    onnx.checker.check_model(model)
    onnx.save(model, path)


def check_export(params, path, image):
    """ONNX Runtime's output of the exported file against the JAX network on one image: the
    largest differences of the scores, boxes (px), mask coefficients and prototypes."""
    import onnxruntime as ort

    canvas, _, _ = canvas_of(image)
    x = canvas.astype(np.float32)[None] / 255.0
    raw, coefficients, protos = (np.asarray(t)[0] for t in forward(params, jnp.asarray(x)))
    boxes = np.asarray(decode_boxes(jnp.asarray(raw[None])))[0]
    session = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    out, out_protos = session.run(None, {"images": np.transpose(x, (0, 3, 1, 2))})
    out, out_protos = out[0], out_protos[0]  # [37, 8400], [32, 160, 160]
    grid = INPUT // STRIDE
    n8 = grid * grid
    score_jax = 1 / (1 + np.exp(-raw[..., 4].ravel()))
    centre_size = [
        (boxes[..., 0] + boxes[..., 2]) / 2,
        (boxes[..., 1] + boxes[..., 3]) / 2,
        boxes[..., 2] - boxes[..., 0],
        boxes[..., 3] - boxes[..., 1],
    ]
    errors = {
        "score": np.abs(out[4, :n8] - score_jax).max(),
        "box": max(np.abs(out[i, :n8] - v.ravel()).max() for i, v in enumerate(centre_size)),
        "coefficient": np.abs(out[5:, :n8] - coefficients.reshape(n8, MASKS).T).max(),
        "prototype": np.abs(out_protos - np.transpose(protos, (2, 0, 1))).max(),
    }
    return errors, int((out[4, :n8] >= 0.25).sum())


def load_weights(params, path):
    """Weights from a --checkpoint file (.npz) or an exported model (.onnx, OIHW); layers the
    file lacks keep their initial values (a detect model's backbone and head start a segment
    model)."""
    if path.endswith(".onnx"):
        import onnx
        from onnx import numpy_helper

        saved = {t.name: numpy_helper.to_array(t) for t in onnx.load(path).graph.initializer}
        saved = {k: np.transpose(v, (2, 3, 1, 0)) if k.endswith(".w") else v for k, v in saved.items()}
    else:
        saved = dict(np.load(path))
    loaded, kept = [], []
    for name, layer in params.items():
        if all(f"{name}.{n}" in saved and saved[f"{name}.{n}"].shape == layer[n].shape for n in layer):
            params[name] = {n: jnp.asarray(saved[f"{name}.{n}"]) for n in layer}
            loaded.append(name)
        else:
            kept.append(name)
    print(f"weights from {path}: {', '.join(loaded)}; initial: {', '.join(kept) or 'none'}", flush=True)
    backbone = [layer[0] for layer in LAYERS]
    if not all(name in loaded for name in backbone):
        raise SystemExit(f"{path}: no weights of this network's backbone ({', '.join(backbone)}) "
                         "with matching shapes")
    return params


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", required=True, nargs="+", help="data set directories")
    parser.add_argument("--out", required=True)
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--lr", type=float, default=3e-3)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--limit", type=int, default=0, help="use only the first N images")
    parser.add_argument("--minutes", type=float, default=0.0,
                        help="choose --steps to fill this wall time (measured over the first 20 steps)")
    parser.add_argument("--checkpoint", default="", help="save the weights here (npz) as it goes")
    parser.add_argument("--init", default="",
                        help="start from these weights (a --checkpoint .npz or an exported .onnx)")
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    start = time.time()
    entries, images, masks = load_dataset(args.data, args.limit)
    canvases = [canvas_of(im) for im in images]
    mask_canvases = [canvas_of(m, fill=0)[0] for m in masks]
    apples = sum(a["labelled"] for e in entries for a in e["apples"])
    print(f"{len(entries)} images, {apples} labelled apples, loaded in {time.time() - start:.0f} s",
          flush=True)

    params = init_params(jax.random.PRNGKey(args.seed))
    if args.init:
        params = load_weights(params, args.init)
    count = sum(int(np.prod(p.shape)) for layer in params.values() for p in layer.values())
    print(f"{count} parameters", flush=True)
    optimizer = optax.chain(
        optax.clip_by_global_norm(5.0),
        optax.inject_hyperparams(optax.adamw)(learning_rate=0.0, weight_decay=1e-4),
    )
    state = optimizer.init(params)

    @jax.jit
    def step(params, state, lr, *batch):
        (loss, parts), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, *batch)
        state[1].hyperparams["learning_rate"] = lr
        updates, state = optimizer.update(grads, state, params)
        return optax.apply_updates(params, updates), state, loss, parts

    def learning_rate(i, total):
        warmup = min(100, total // 10)
        if i < warmup:
            return args.lr * (i + 1) / warmup
        t = (i - warmup) / max(total - warmup, 1)
        return args.lr * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * min(t, 1.0))))

    # --minutes: the step count is fixed after 20 timed steps (printed, so --steps N repeats the
    # run exactly); the schedule then anneals over those steps.
    total = args.steps
    train_start = time.time()
    history = []
    i = 0
    while i < total:
        batch = sample_batch(rng, entries, canvases, mask_canvases, args.batch)
        lr = jnp.float32(learning_rate(i, total))
        params, state, loss, parts = step(params, state, lr, *map(jnp.asarray, batch))
        history.append(tuple(float(part) for part in parts))
        i += 1
        if args.minutes and i == 20:
            per_step = (time.time() - train_start) / 20
            total = max(100, int(args.minutes * 60 / per_step))
            print(f"--minutes {args.minutes}: {per_step:.2f} s/step, training {total} steps "
                  f"(repeat with --steps {total})", flush=True)
        if i % 50 == 0 or i == 1:
            recent = np.mean(history[-50:], axis=0)
            elapsed = time.time() - train_start
            print(f"step {i}/{total}  lr {float(lr):.2e}  score {recent[0]:.4f}  box {recent[1]:.4f}  "
                  f"mask {recent[2]:.4f}  "
                  f"{elapsed / i:.2f} s/step  {elapsed / 60:.1f} min", flush=True)
        if args.checkpoint and i % 250 == 0:
            np.savez(args.checkpoint, **{f"{k}.{n}": np.asarray(v) for k, layer in params.items()
                                         for n, v in layer.items()})
    if args.checkpoint:
        np.savez(args.checkpoint, **{f"{k}.{n}": np.asarray(v) for k, layer in params.items()
                                     for n, v in layer.items()})
    export_onnx(params, args.out)
    errors, hits = check_export(params, args.out, images[0])
    diffs = ", ".join(f"max {name} diff {error:.2e}" for name, error in errors.items())
    print(f"exported {args.out} ({os.path.getsize(args.out) / 1e3:.0f} kB); ONNX Runtime vs JAX on "
          f"image 0: {diffs}, {hits} cells >= 0.25", flush=True)
    if errors["score"] > 1e-3 or errors["box"] > 0.05 or max(errors["coefficient"], errors["prototype"]) > 1e-2:
        print("export check failed", file=sys.stderr)
        return 1
    print(f"total {(time.time() - start) / 60:.1f} min", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
