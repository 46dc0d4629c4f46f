"""``ftrac-design train-detector``: train the learned feature detector on the simulator and write
its ONNX weights and model card (:mod:`ftrac_design.training.run`)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import click

from ..errors import InputError
from .options import shown_option


@click.command("train-detector")
@shown_option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs/detector"),
    help="folder for detector.onnx and detector.json (the shipped ones: ftrac_design/detector/models)",
)
@shown_option("--scenes", type=click.IntRange(1), default=5000, help="training scenes")
@shown_option("--val-scenes", type=click.IntRange(1), default=500, help="validation scenes")
@shown_option("--seed", type=int, default=1, help="seed of the training scenes and the weights")
@shown_option("--val-seed", type=int, default=2, help="seed of the validation scenes")
@shown_option("--steps", type=click.IntRange(1), default=5000, help="optimiser steps")
@shown_option("--batch", type=click.IntRange(1), default=32, help="crops per step")
@click.option("--lr", type=click.FloatRange(min=0, min_open=True), default=2e-3, show_default=True)
@shown_option("--workers", type=click.IntRange(1), default=2, help="processes making scenes")
@shown_option("--threads", type=click.IntRange(1), default=2, help="PyTorch threads")
@click.option("--device", type=click.Choice(["cpu", "cuda"]), default="cpu", show_default=True)
def command(output, scenes, val_scenes, seed, val_seed, steps, batch, lr, workers, threads, device) -> int:
    """Train the learned ball and wire detector on this package's own simulator.

    Scenes are drawn with their seeds (random designs in every preset's design space, random
    poses, every image condition of the simulator); the same command on the same kind of
    machine writes the same weights. Writes OUTPUT/detector.onnx and OUTPUT/detector.json
    (the model card: settings, data seeds, validation figures, machine, sha256).
    """
    from ..training.run import TrainConfig, train

    if seed == val_seed:
        raise InputError(None, "val_seed", f"a seed other than --seed ({seed})", parameter="val_seed")
    config = TrainConfig(
        scenes=scenes,
        val_scenes=val_scenes,
        seed=seed,
        val_seed=val_seed,
        steps=steps,
        batch=batch,
        lr=lr,
        workers=workers,
        threads=threads,
        device=device,
    )
    card = train(config, output, command="ftrac-design " + shlex.join(sys.argv[1:]))
    v = card["validation"]["all"]
    click.echo(
        f"detector written to {output}/ ({card['weights']} weights): balls recall {v['ball_recall']:.3f}, "
        f"precision {v['ball_precision']:.3f}, RMS {v['ball_rms_px'] or float('nan'):.2f} working px; "
        f"wires recall {v['wire_recall']:.3f}, precision {v['wire_precision']:.3f}"
    )
    return 0
