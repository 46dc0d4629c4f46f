"""``make demo`` step: one radiograph of the default fiducial at a workspace pose."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np


def demo_step(out_dir: Path, seed: int = 2005) -> str:
    """Render ``ftrac_2005`` at one workspace pose (default imaging model, anatomy-like
    background) into ``out_dir``: ``radiograph.png`` (log image, 16-bit, dense = bright) and
    ``radiograph.truth.json``. Returns the lines the demo prints."""
    from ..design import load_design
    from ..design.presets import preset_path
    from ..features import compute_features
    from ..images import write_image
    from ..pose.simulate import Workspace
    from ..xray.background import anatomy
    from ..xray.render import render
    from ..xray.truth import write_truth

    out_dir = Path(out_dir)
    features = compute_features(load_design(preset_path("ftrac_2005")))
    rng = np.random.default_rng(seed)
    R, t = Workspace().sample(1, features.nominal_beam_direction, rng)
    bg = anatomy(seed=seed)
    t0 = time.perf_counter()
    img = render(features, R[0], t[0], rng=rng, background=bg, image_name="radiograph.png")
    ms = (time.perf_counter() - t0) * 1e3
    img.truth["background"] = f"anatomy seed {seed}"
    png = write_image(
        out_dir / "radiograph.png",
        img.log_image,
        img.camera,
        polarity="dense_bright",
        bit_depth=16,
        value_range=(0.0, 6.0),
        quantity="log",
    )
    write_truth(out_dir / "radiograph.truth.json", img.truth)
    beam = R[0][2]
    tilt = np.degrees(np.arccos(np.clip(beam @ features.nominal_beam_direction, -1, 1)))
    return (
        f"radiograph: ftrac_2005 at a workspace pose ({tilt:.1f}° from AP, t = "
        f"({t[0][0]:.1f}, {t[0][1]:.1f}, {t[0][2]:.1f}) mm), 1024×1024, rendered in {ms:.0f} ms "
        f"→ {png} (+ radiograph.truth.json)"
    )
