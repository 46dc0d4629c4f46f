"""Is the pixel-level bound converged in the renderer's sub-sampling?

The ROI renderer samples each pixel a wire, bead or body edge touches at s × s sub-samples
(``ImagingModel.supersample``, default 5), and the bound's derivative is a 0.15 px central
difference of that image. Here the bound (gain and a quadratic background unknown, ftrac_2005
with its body, default imaging model) is computed with 4 × 4 and with 8 × 8 sub-samples (float32
chords, as the default, and float64) at the first N poses of the 300-image workspace sample
of ``intensity_accuracy.py``; printed: σ(8 × 8) / σ(4 × 4) − 1 per axis, per pose and summarised.

Run: ``.venv/bin/python benchmarks/intensity_supersample_check.py [N]`` (default 20)
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
from _common import load, machine
from intensity_common import AXES
from tqdm import tqdm

from ftrac_design.intensity import pixel_information
from ftrac_design.pose.camera import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.xray import ImagingModel


def main(n: int = 20) -> None:
    features = load("ftrac_2005")
    cam = Camera()
    R, t = Workspace().sample(300, features.nominal_beam_direction, np.random.default_rng(1313))
    rel32, rel64 = [], []
    for k in tqdm(range(n), desc="poses", unit="pose"):
        std = [
            pixel_information(
                features,
                R[k],
                t[k],
                cam,
                replace(ImagingModel(), supersample=s, single_precision=sp),
                nuisance=True,
            ).std
            for s, sp in ((4, True), (8, True), (8, False))
        ]
        rel32.append(std[1] / std[0] - 1)
        rel64.append(std[2] / std[0] - 1)
    rel32, rel64 = 100 * np.array(rel32), 100 * np.array(rel64)
    print(f"\nftrac_2005, {n} workspace poses, bound with gain + quadratic unknown; machine: {machine()}")
    print("σ(8 × 8) / σ(4 × 4) − 1, %:")
    print(f"{'':22s}" + "".join(f"{a:>8s}" for a in AXES))
    for name, v in (
        ("8×8 float32: mean", rel32.mean(0)),
        ("             min", rel32.min(0)),
        ("             max", rel32.max(0)),
        ("8×8 float64: mean", rel64.mean(0)),
        ("             max |Δ| vs float32", np.abs(rel64 - rel32).max(0)),
    ):
        print(f"{name:22s}" + "".join(f"{x:+8.2f}" for x in v))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 20)
