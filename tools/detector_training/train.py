"""Trains harvest's own apple detector on the simulator's renders and exports it to ONNX in the
YOLOv8/YOLO11 detect layout perception's ONNX detector reads.

    python3 tools/detector_training/train.py --data DATASET_DIR --out models/apples_sim.onnx

DATASET_DIR is written by `harvest dataset detector` (images at the 640 input's scale, YOLO
labels, index.jsonl with every visible apple). See tools/detector_training/README.md for the
exact commands, the tools and why.

The model ("apple-net"): a small fully convolutional network with one stride-8 head, 43k
parameters, ReLU activations.
    3 -> 8 (3x3, /2) -> 16 (3x3, /4) -> 32 (3x3, /8) -> four residual 3x3 blocks of 32 channels
    (dilation 1, 2, 4, 1: a receptive field of about 100 input pixels, several apple diameters)
    -> 1x1 head: 4 box distances (left, top, right, bottom from the cell centre,
    exp(.) * 8 px) and 1 apple score (sigmoid).
The export appends the anchors of strides 16 and 32 with zero scores so the output is the
standard `[1, 5, 8400]` of a 640 YOLO detect export: apples are 10-70 px at 640, all within the
stride-8 head's range.

Training: crops of 256x256 from the letterboxed 640x640 canvas (the grey padding included, so
the model learns that padding is no apple), photometric augmentation (exposure gain with
clipping, gamma, channel gains, noise, horizontal flips), focal loss on the score with the
cells near each labelled apple's centre positive and cells of barely visible apples ignored,
GIoU loss on the boxes of positive cells, Adam with a cosine schedule. Deterministic for a
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
PRIOR = 0.01


def init_params(key):
    params = {}
    for name, cin, cout, k, _, _, residual in LAYERS + [HEAD]:
        key, sub = jax.random.split(key)
        fan_in = cin * k * k
        scale = math.sqrt(2.0 / fan_in) * (0.3 if residual else 1.0)
        if name == "head":
            scale = 0.01
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
    """images: [B, H, W, 3] in 0-1. Returns [B, H/8, W/8, 5] raw head outputs."""
    x = images
    for name, _, _, _, stride, dilation, residual in LAYERS:
        y = jax.nn.relu(conv(x, params[name], stride, dilation))
        x = x + y if residual else y
    return conv(x, params["head"], 1, 1)


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


def loss_fn(params, images, score_target, score_weight, box_target):
    raw = forward(params, images)
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
    return score_loss + 2.0 * box_loss, (score_loss, box_loss)


def load_dataset(data_dirs, limit):
    entries = []
    for data_dir in data_dirs:
        with open(os.path.join(data_dir, "index.jsonl")) as index:
            for line in index:
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:
                    break  # a data set still being written: its complete lines only
                entry["image"] = os.path.join(data_dir, entry["image"])
                entries.append(entry)
    if limit:
        entries = entries[:limit]
    images = []
    for entry in entries:
        with Image.open(entry["image"]) as im:
            images.append(np.asarray(im.convert("RGB"), dtype=np.uint8))
    return entries, images


def canvas_of(image):
    """The image letterboxed into the 640x640 canvas (grey padding), and its top-left offset."""
    h, w = image.shape[:2]
    canvas = np.full((INPUT, INPUT, 3), PAD, dtype=np.uint8)
    left = int(round((INPUT - w) / 2 - 0.1))
    top = int(round((INPUT - h) / 2 - 0.1))
    canvas[top : top + h, left : left + w] = image
    return canvas, left, top


def targets(boxes, ignores, grid):
    """Score target, score weight and box target on a grid x grid stride-8 map of one crop."""
    score = np.zeros((grid, grid), np.float32)
    weight = np.ones((grid, grid), np.float32)
    box_target = np.zeros((grid, grid, 4), np.float32)
    box_target[..., 2:] = 1.0  # a valid dummy box where the box loss is masked out
    centres = (np.arange(grid, dtype=np.float32) + 0.5) * STRIDE
    for x0, y0, x1, y1 in ignores:
        inside_x = (centres >= x0) & (centres <= x1)
        inside_y = (centres >= y0) & (centres <= y1)
        weight[np.ix_(inside_y, inside_x)] = 0.0
    # Larger boxes first, so a smaller apple's centre cells win where two overlap.
    order = sorted(boxes, key=lambda b: -(b[2] - b[0]) * (b[3] - b[1]))
    for x0, y0, x1, y1 in order:
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
    return score, weight, box_target


def sample_batch(rng, entries, canvases, batch):
    grid = CROP // STRIDE
    images = np.empty((batch, CROP, CROP, 3), np.float32)
    score = np.empty((batch, grid, grid), np.float32)
    weight = np.empty((batch, grid, grid), np.float32)
    box_target = np.empty((batch, grid, grid, 4), np.float32)
    for b in range(batch):
        k = rng.integers(len(entries))
        canvas, left, top = canvases[k]
        h, w = entries[k]["height_px"], entries[k]["width_px"]
        # Mostly inside the image, sometimes over the padding.
        ox = int(rng.integers(0, INPUT - CROP + 1))
        oy = int(rng.integers(max(top - 64, 0), min(top + h - CROP + 64, INPUT - CROP) + 1))
        crop = canvas[oy : oy + CROP, ox : ox + CROP].astype(np.float32) / 255.0
        flip = rng.random() < 0.5
        if flip:
            crop = crop[:, ::-1]
        # Exposure: gain with clipping (over- and under-exposure), gamma, white balance, noise.
        gain = math.exp(rng.uniform(math.log(0.55), math.log(1.8)))
        gamma = math.exp(rng.uniform(math.log(0.7), math.log(1.4)))
        channel = rng.uniform(0.88, 1.12, size=3).astype(np.float32)
        crop = np.clip(crop * gain * channel, 0.0, 1.0) ** gamma
        sigma = rng.uniform(0.0, 0.03)
        crop = np.clip(crop + rng.normal(0.0, sigma, crop.shape).astype(np.float32), 0.0, 1.0)
        boxes, ignores = [], []
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
            else:
                ignores.append((cx0, cy0, cx1, cy1))
        images[b] = crop
        score[b], weight[b], box_target[b] = targets(boxes, ignores, grid)
    return images, score, weight, box_target


def export_onnx(params, path, opset=17):
    """The trained network as a [1, 3, 640, 640] -> [1, 5, 8400] YOLO detect export."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    nodes, inits = [], []

    def const(name, value, dtype=np.float32):
        inits.append(numpy_helper.from_array(np.asarray(value, dtype=dtype), name))
        return name

    x = "images"
    for name, _, _, k, stride, dilation, residual in LAYERS + [HEAD]:
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
        if name == "head":
            x = out
            break
        nodes.append(helper.make_node("Relu", [out], [f"{name}.relu"]))
        if residual:
            nodes.append(helper.make_node("Add", [x, f"{name}.relu"], [f"{name}.out"]))
            x = f"{name}.out"
        else:
            x = f"{name}.relu"
    grid = INPUT // STRIDE
    n8 = grid * grid
    n_rest = (INPUT // 16) ** 2 + (INPUT // 32) ** 2
    # head [1, 5, 80, 80] -> [1, 5, 6400]; distances exp(.) * 8 px; score sigmoid.
    const("flat", [1, 5, n8], np.int64)
    nodes.append(helper.make_node("Reshape", [x, "flat"], ["head_flat"]))
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
    nodes.append(helper.make_node("Concat", ["centre", "size", "score8"], ["pred8"], axis=1))
    const("coarse", np.zeros((1, 5, n_rest)))
    nodes.append(helper.make_node("Concat", ["pred8", "coarse"], ["output0"], axis=2))
    graph = helper.make_graph(
        nodes,
        "apple-net",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, INPUT, INPUT])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 5, n8 + n_rest])],
        inits,
    )
    model = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", opset)], producer_name="harvest-detector-training"
    )
    model.ir_version = 8
    model.metadata_props.append(onnx.StringStringEntryProto(key="names", value="{0: 'apple'}"))
    model.metadata_props.append(onnx.StringStringEntryProto(key="stride", value="8"))
    onnx.checker.check_model(model)
    onnx.save(model, path)


def check_export(params, path, image):
    """ONNX Runtime's output of the exported file against the JAX network on one image."""
    import onnxruntime as ort

    canvas, _, _ = canvas_of(image)
    x = canvas.astype(np.float32)[None] / 255.0
    raw = np.asarray(forward(params, jnp.asarray(x)))[0]  # [80, 80, 5]
    boxes = np.asarray(decode_boxes(jnp.asarray(raw[None])))[0]
    session = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    out = session.run(None, {"images": np.transpose(x, (0, 3, 1, 2))})[0][0]  # [5, 8400]
    grid = INPUT // STRIDE
    n8 = grid * grid
    score_jax = 1 / (1 + np.exp(-raw[..., 4].ravel()))
    cx = ((boxes[..., 0] + boxes[..., 2]) / 2).ravel()
    w = (boxes[..., 2] - boxes[..., 0]).ravel()
    score_err = np.abs(out[4, :n8] - score_jax).max()
    box_err = max(np.abs(out[0, :n8] - cx).max(), np.abs(out[2, :n8] - w).max())
    return score_err, box_err, int((out[4, :n8] >= 0.25).sum())


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
    parser.add_argument("--init", default="", help="start from these weights (a --checkpoint file)")
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    start = time.time()
    entries, images = load_dataset(args.data, args.limit)
    canvases = [canvas_of(im) for im in images]
    apples = sum(a["labelled"] for e in entries for a in e["apples"])
    print(f"{len(entries)} images, {apples} labelled apples, loaded in {time.time() - start:.0f} s",
          flush=True)

    params = init_params(jax.random.PRNGKey(args.seed))
    if args.init:
        saved = np.load(args.init)
        params = {k: {n: jnp.asarray(saved[f"{k}.{n}"]) for n in layer} for k, layer in params.items()}
        print(f"weights from {args.init}", flush=True)
    count = sum(int(np.prod(p.shape)) for layer in params.values() for p in layer.values())
    print(f"{count} parameters", flush=True)
    optimizer = optax.chain(
        optax.clip_by_global_norm(5.0),
        optax.inject_hyperparams(optax.adamw)(learning_rate=0.0, weight_decay=1e-4),
    )
    state = optimizer.init(params)

    @jax.jit
    def step(params, state, lr, images, score, weight, box_target):
        (loss, parts), grads = jax.value_and_grad(loss_fn, has_aux=True)(
            params, images, score, weight, box_target
        )
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
        batch = sample_batch(rng, entries, canvases, args.batch)
        lr = jnp.float32(learning_rate(i, total))
        params, state, loss, (score_loss, box_loss) = step(
            params, state, lr, *map(jnp.asarray, batch)
        )
        history.append((float(score_loss), float(box_loss)))
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
                  f"{elapsed / i:.2f} s/step  {elapsed / 60:.1f} min", flush=True)
        if args.checkpoint and i % 250 == 0:
            np.savez(args.checkpoint, **{f"{k}.{n}": np.asarray(v) for k, layer in params.items()
                                         for n, v in layer.items()})
    if args.checkpoint:
        np.savez(args.checkpoint, **{f"{k}.{n}": np.asarray(v) for k, layer in params.items()
                                     for n, v in layer.items()})
    export_onnx(params, args.out)
    score_err, box_err, hits = check_export(params, args.out, images[0])
    print(f"exported {args.out} ({os.path.getsize(args.out) / 1e3:.0f} kB); ONNX Runtime vs JAX on "
          f"image 0: max score diff {score_err:.2e}, max box diff {box_err:.2e} px, "
          f"{hits} cells >= 0.25", flush=True)
    if score_err > 1e-3 or box_err > 0.05:
        print("export check failed", file=sys.stderr)
        return 1
    print(f"total {(time.time() - start) / 60:.1f} min", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
