"""One training run of the detector: data, training, validation, ONNX export and the model card.

Everything is seeded (the data sets by :mod:`.dataset`, the weights' start, the batches and the
augmentations by ``TrainConfig.seed``) and PyTorch runs with deterministic algorithms, so the
same command on the same kind of machine writes the same weights; on another device (a GPU, a
different CPU) the weights differ in their last digits and the figures within their noise. The
card records the command's settings, the machine, the versions, the figures on the validation
scenes (a seed the training set never used) and the ONNX file's sha256.
"""

from __future__ import annotations

import math
import platform
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..detector.decode import decode
from ..detector.runtime import CARD_FILE, MODEL_FILE
from ..errors import require
from ..fileio import sha256_file, write_json_atomic
from .dataset import DataSet, build_dataset

#: the PyTorch weights (state dict) written beside the ONNX file
TORCH_FILE = "detector.pt"


@dataclass(frozen=True)
class TrainConfig:
    """Settings of a training run.

    Attributes
    ----------
    scenes, val_scenes : int
        Training and validation scenes (each gives ``crops`` crops).
    seed, val_seed : int
        Seeds of the training set (and of the weights, batches and augmentations) and of the
        validation set; they must differ.
    steps, batch : int
        Optimiser steps and crops per step.
    lr : float
        Adam's initial learning rate (cosine decay to 2 % of it).
    widths : (int, int, int)
        Channels of the network's three stages.
    crop, crops : int
        Crop side (working px) and crops per scene.
    workers, threads : int
        Processes making the data, threads PyTorch uses.
    device : str
        "cpu" or "cuda".
    """

    scenes: int = 5000
    val_scenes: int = 500
    seed: int = 1
    val_seed: int = 2
    steps: int = 5000
    batch: int = 32
    lr: float = 2e-3
    widths: tuple[int, int, int] = (24, 48, 72)
    crop: int = 128
    crops: int = 3
    workers: int = 2
    threads: int = 2
    device: str = "cpu"


def _augment(x, y, om, dm, rng: np.random.Generator):
    """A random flip, transpose and polarity per batch of tensors (the maps follow: offsets and the
    wire's (cos 2θ, sin 2θ) change sign as the geometry says). The draws come from ``rng`` so that a
    run is the same wherever the tensors live."""
    if rng.random() < 0.5:  # u → −u
        x, y, om, dm = x.flip(-1), y.flip(-1), om.flip(-1), dm.flip(-1)
        y[:, 1] = -y[:, 1]
        y[:, 5] = -y[:, 5]
        # a flipped cell grid is centred on the other half-pixel: (2c + ½) ↦ (2(w−1−c) + ½) mirrors
        # working px k to 2w − 1 − k, so the offset keeps its size
    if rng.random() < 0.5:  # v → −v
        x, y, om, dm = x.flip(-2), y.flip(-2), om.flip(-2), dm.flip(-2)
        y[:, 2] = -y[:, 2]
        y[:, 5] = -y[:, 5]
    if rng.random() < 0.5:  # u ↔ v
        x, y, om, dm = (a.transpose(-1, -2) for a in (x, y, om, dm))
        y = y[:, [0, 2, 1, 3, 4, 5]]
        y[:, 4] = -y[:, 4]
    if rng.random() < 0.5:  # dense-dark ↔ dense-bright
        x = -x
    return x, y, om, dm


def _losses(torch, out, y, om, dm):
    """(ball, offset, wire, direction) losses of a batch."""
    F = torch.nn.functional
    ball = (F.binary_cross_entropy_with_logits(out[:, 0], y[:, 0], reduction="none") * (1 + 30 * y[:, 0])).mean()
    off = ((out[:, 1:3] - y[:, 1:3]).abs().sum(1) * om).sum() / om.sum().clamp(min=1)
    wire = 2 * (F.binary_cross_entropy_with_logits(out[:, 3], y[:, 3], reduction="none") * (1 + 10 * y[:, 3])).mean()
    dirn = ((out[:, 4:6] - y[:, 4:6]).abs().sum(1) * dm).sum() / dm.sum().clamp(min=1)
    return ball, off, wire, dirn


def train_steps(net, data: DataSet, config: TrainConfig, progress=None) -> list[float]:
    """Optimise ``net`` on ``data`` for ``config.steps`` steps; the loss of every step."""
    torch = require("torch", "train", "training the learned feature detector")
    rng = np.random.default_rng([config.seed, 17])
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda k: 0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * min(k / max(config.steps, 1), 1.0)))
    )
    dev = torch.device(config.device)
    net.to(dev).train()
    # the whole set moves to the device once (half precision, a few GB at most): a batch is then
    # gathered, converted and flipped there, where the host's copying would bound a GPU's step
    held = [torch.from_numpy(a).to(dev) for a in (data.x, data.y, data.offset_mask, data.direction_mask)]
    history = []
    for _ in range(config.steps):
        idx = np.sort(rng.choice(len(data), size=min(config.batch, len(data)), replace=False))
        pick = torch.from_numpy(idx).to(dev)
        t = [a.contiguous() for a in _augment(*(a.index_select(0, pick).float() for a in held), rng)]
        parts = _losses(torch, net(t[0]), *t[1:])
        loss = parts[0] + parts[1] + parts[2] + 0.5 * parts[3]
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        history.append(float(loss.detach().cpu()))
        if progress is not None:
            progress.update(1)
            progress.set_postfix(loss=f"{history[-1]:.3f}")
    return history


def _truth_balls(y: np.ndarray) -> np.ndarray:
    """Ball centres (n, 2) in working px from a target map (6, h, w): the cells that peak."""
    heat = y[0].astype(np.float32)
    import cv2

    peak = (heat >= cv2.dilate(heat, np.ones((3, 3), np.uint8))) & (heat >= 0.5)
    r, c = np.nonzero(peak)
    return np.stack([2 * c + 0.5 + y[1, r, c], 2 * r + 0.5 + y[2, r, c]], -1).astype(float)


def validate(maps_of, data: DataSet, batch: int = 64, threshold: float = 0.3) -> dict:
    """Figures of a network on ``data``: balls (recall and precision of candidates above
    ``threshold`` within 1.5 working px of a true centre, the RMS localisation error of those,
    working px) and wires (pixel recall and precision at probability ½), overall and per
    condition. ``maps_of`` maps a batch of inputs (n, 2, c, c) to outputs (n, 6, c/2, c/2)."""
    rows = []
    for k in range(0, len(data), batch):
        out = maps_of(data.x[k : k + batch].astype(np.float32))
        for i, m in enumerate(out):
            y = data.y[k + i].astype(np.float32)
            truth = _truth_balls(y)
            det = decode(m, 1, (10**6, 10**6), max_beads=64, min_score=threshold)
            found = det.beads_uv
            d = np.linalg.norm(found[:, None] - truth[None], axis=-1) if len(found) and len(truth) else None
            hit_t = (d.min(0) <= 1.5) if d is not None else np.zeros(len(truth), bool)
            hit_f = (d.min(1) <= 1.5) if d is not None else np.zeros(len(found), bool)
            err = d.min(0)[hit_t] if d is not None else np.zeros(0)
            wp, wt = det.wire >= 0.5, y[3] >= 0.5
            rows.append(
                (
                    data.condition[k + i],
                    len(truth),
                    hit_t.sum(),
                    len(found),
                    hit_f.sum(),
                    err,
                    wt.sum(),
                    (wp & wt).sum(),
                    wp.sum(),
                )
            )

    def figures(rs):
        nt, ht, nf, hf = (sum(r[j] for r in rs) for j in (1, 2, 3, 4))
        errs = np.concatenate([r[5] for r in rs]) if rs else np.zeros(0)
        wt, wtp, wp = (sum(int(r[j]) for r in rs) for j in (6, 7, 8))
        return {
            "ball_recall": ht / max(nt, 1),
            "ball_precision": hf / max(nf, 1),
            "ball_rms_px": float(np.sqrt(np.mean(errs**2))) if len(errs) else None,
            "balls": int(nt),
            "wire_recall": wtp / max(wt, 1),
            "wire_precision": wtp / max(wp, 1),
        }

    out = {"all": figures(rows)}
    for cond in sorted(set(r[0] for r in rows)):
        out[str(cond)] = figures([r for r in rows if r[0] == cond])
    return out


def _plain(d):
    """``d`` with NumPy numbers as plain ones (for JSON)."""
    if isinstance(d, dict):
        return {k: _plain(v) for k, v in d.items()}
    return float(d) if isinstance(d, (np.floating, np.integer)) else d


def export_onnx(net, path: Path, crop: int) -> None:
    """Write ``net`` as ONNX (opset 17, input ``image`` (n, 2, h, w) with any n, h, w)."""
    torch = require("torch", "train", "training the learned feature detector")
    net = net.to("cpu").eval()
    x = torch.zeros(1, 2, crop, crop)
    torch.onnx.export(
        net,
        x,
        str(path),
        input_names=["image"],
        output_names=["maps"],
        dynamic_axes={"image": {0: "n", 2: "h", 3: "w"}, "maps": {0: "n", 2: "h2", 3: "w2"}},
        opset_version=17,
        dynamo=False,
    )


def train(config: TrainConfig, out_dir: str | Path, command: str = "", progress: bool = True) -> dict:
    """Make the data, train, validate, export ``detector.onnx`` and write ``detector.json`` into
    ``out_dir``; returns the card."""
    torch = require("torch", "train", "training the learned feature detector")
    ort = require("onnxruntime", "detect", "checking the exported detector")
    from tqdm import tqdm

    from .net import DetectorNet

    if config.seed == config.val_seed:
        raise ValueError("the validation seed must differ from the training seed")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    with tqdm(total=config.scenes + config.val_scenes, desc="scenes", disable=not progress) as bar:
        data = build_dataset(config.scenes, config.seed, config.workers, config.crop, config.crops, bar)
        val = build_dataset(config.val_scenes, config.val_seed, config.workers, config.crop, config.crops, bar)
    t_data = time.time() - t0
    torch.manual_seed(config.seed)
    # on a GPU some kernels (nearest upsampling's gradient) have no deterministic variant: they
    # warn there, and the weights then differ from run to run in their last digits
    torch.use_deterministic_algorithms(True, warn_only=config.device != "cpu")
    torch.set_num_threads(config.threads)
    net = DetectorNet(tuple(config.widths))
    with tqdm(total=config.steps, desc="train", disable=not progress) as bar:
        history = train_steps(net, data, config, bar)
    t_train = time.time() - t0 - t_data
    net.to("cpu").eval()
    onnx_path = out_dir / MODEL_FILE
    export_onnx(net, onnx_path, config.crop)
    # the PyTorch weights beside the ONNX file: a test runs both on one input
    torch.save(net.state_dict(), out_dir / TORCH_FILE)
    so = ort.SessionOptions()
    so.intra_op_num_threads = config.threads
    session = ort.InferenceSession(str(onnx_path), so, providers=["CPUExecutionProvider"])
    with torch.no_grad():
        probe = val.x[:4].astype(np.float32)
        gap = float(np.abs(session.run(None, {"image": probe})[0] - net(torch.from_numpy(probe)).numpy()).max())
    figures = validate(lambda b: session.run(None, {"image": b})[0], val)
    card = {
        "format": "ftrac-detector-card",
        "version": 1,
        "command": command,
        "config": asdict(config),
        "data": {
            "training_scenes": config.scenes,
            "training_crops": len(data),
            "validation_scenes": config.val_scenes,
            "validation_crops": len(val),
            "scene_seeds": f"scene k of seed S is make_scene(S * 1000003 + k); training S = {config.seed}, "
            f"validation S = {config.val_seed}",
        },
        "loss": {
            "steps_averaged": (k := max(1, min(100, len(history) // 4))),
            "first": float(np.mean(history[:k])),
            "last": float(np.mean(history[-k:])),
        },
        "validation": _plain(figures),
        "onnx_vs_torch_max_abs": gap,
        "weights": int(sum(p.numel() for p in net.parameters())),
        "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine()},
        "versions": {"torch": torch.__version__, "onnxruntime": ort.__version__, "numpy": np.__version__},
        "seconds": {"data": round(t_data, 1), "training": round(t_train, 1)},
        "sha256": sha256_file(onnx_path),
        "torch_sha256": sha256_file(out_dir / TORCH_FILE),
    }
    write_json_atomic(out_dir / CARD_FILE, card)
    return card
