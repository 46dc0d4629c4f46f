"""Why the intensity refinement's depth efficiency is below 1: the checks, one by one.

Two checks on ftrac_2005 workspace images (default imaging model, with its body; the same
poses, noise seeds and perturbed starts as ``intensity_accuracy.py N plain perturbed``):

- ``noisefree``: images without quantum noise (the log image), refined with uniform weights
  from the perturbed start. Errors in units of the pixel bound at the default dose: any
  model mismatch between the refinement's model and the renderer shows here.
- ``paired``: noisy images refined twice from the same start — LM steps on forward
  differences (the default) and on central differences (``central_steps=True``). If the
  forward-difference Jacobian cost efficiency, the central one would have the smaller
  mean z²; the paired difference of mean z² comes with its standard error.
- ``stopping``: the stopping rule of the default refinement (spline background, Huber;
  steps stop below ``step_sigma`` = 0.01 σ) against the same refinement run to the exact
  minimum of its objective (central-difference steps, ``step_sigma`` 1e-4, up to 40
  iterations), on the same noisy images and starts: the RMS difference of their z is what
  stopping early and the forward-difference fixed point add (in units of the spline bound).

Run: ``.venv/bin/python benchmarks/intensity_depth_check.py noisefree|paired|stopping [N] [FIRST]``
(N images from FIRST of the 300-image sample; defaults 12 and 300 from 0).
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
from _common import load, machine
from scipy.stats import chi2
from tqdm import tqdm

from ftrac_design.intensity import perturb, pixel_information, refine_intensity
from ftrac_design.pose import so3
from ftrac_design.pose.camera import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.xray import ImagingModel, render

AXES = ("rx", "ry", "rz", "tx", "ty", "tz")
SAMPLE = 300


def main(mode: str, n: int, first: int = 0) -> None:
    features = load("ftrac_2005")
    cam, imaging = Camera(), ImagingModel()
    R, t = Workspace().sample(SAMPLE, features.nominal_beam_direction, np.random.default_rng(1313))
    # the starts of intensity_accuracy.py's ``perturbed`` mode (the same generator, drawn in order)
    X = np.random.default_rng(7).standard_normal((SAMPLE, 6)) * np.array([np.radians(0.05)] * 3 + [0.02, 0.02, 0.4])
    plain = {"scales": (0.0,), "background": "polynomial", "robust": None}
    if mode == "stopping":
        plain = {"scales": (0.0,), "background": "spline"}
    za, zb = [], []
    for k in tqdm(range(first, min(first + n, SAMPLE)), desc=mode, unit="image"):
        bound = pixel_information(
            features,
            R[k],
            t[k],
            cam,
            imaging,
            nuisance=True,
            background_spline_px=12.0 if mode == "stopping" else None,
        )
        Rs, ts = perturb(R[k], t[k], X[k])

        def z(res):
            return np.concatenate([so3.log(res.rotation @ R[k].T), res.translation_mm - t[k]]) / bound.std

        if mode == "noisefree":
            clean = replace(imaging, photons_per_px=None)
            img = render(features, R[k], t[k], cam, clean)
            za.append(z(refine_intensity(features, img.log_image, cam, Rs, ts, clean, **plain)))
        else:
            img = render(features, R[k], t[k], cam, imaging, rng=np.random.default_rng(k))
            kw = dict(plain, polarity="dense_dark")
            za.append(z(refine_intensity(features, img.raw, cam, Rs, ts, imaging, **kw)))
            exact = (
                {"central_steps": True}
                if mode == "paired"
                else {
                    "central_steps": True,
                    "step_sigma": 1e-4,
                    "max_iterations": 40,
                    "tolerance": 0.0,
                    "polish": False,
                }
            )
            zb.append(z(refine_intensity(features, img.raw, cam, Rs, ts, imaging, **exact, **kw)))
    za = np.array(za)
    m = len(za)
    print(
        f"\nftrac_2005, images {first}–{first + m - 1} of the {SAMPLE}-image sample, "
        + (
            "default (spline) refinement vs the same run to its exact minimum"
            if mode == "stopping"
            else "plain refinement"
        )
        + f"; machine: {machine()} (shared with other jobs)"
    )
    if mode == "noisefree":
        print("noise-free images: error / pixel bound at the default dose")
        print(f"{'axis':6s} {'RMS z':>8s} {'mean z':>8s} {'max |z|':>8s}")
        for j, a in enumerate(AXES):
            print(f"{a:6s} {np.sqrt(np.mean(za[:, j] ** 2)):8.3f} {za[:, j].mean():8.3f} {np.abs(za[:, j]).max():8.3f}")
        return
    zb = np.array(zb)
    what = ("default", "exact") if mode == "stopping" else ("forward", "central")
    print(
        f"{'axis':6s} {'eff. ' + what[0]:>13s} {'95 % interval':>14s} {'eff. ' + what[1]:>13s} "
        f"{'Δ mean z² (' + what[0][:3] + ' − ' + what[1][:3] + ')':>22s} {'RMS z diff':>11s}"
    )
    for j, a in enumerate(AXES):
        mf, mc = np.mean(za[:, j] ** 2), np.mean(zb[:, j] ** 2)
        dz2 = za[:, j] ** 2 - zb[:, j] ** 2
        print(
            f"{a:6s} {1 / mf:13.3f} {chi2.ppf(0.025, m) / (m * mf):8.2f}–{chi2.ppf(0.975, m) / (m * mf):4.2f} "
            f"{1 / mc:13.3f} {dz2.mean():13.3f} ± {dz2.std() / np.sqrt(m):5.3f} "
            f"{np.sqrt(np.mean((za[:, j] - zb[:, j]) ** 2)):11.3f}"
        )


if __name__ == "__main__":
    args = sys.argv[1:]
    if not args or args[0] not in ("noisefree", "paired", "stopping"):
        sys.exit(__doc__)
    main(
        args[0],
        int(args[1]) if len(args) > 1 else (12 if args[0] == "noisefree" else SAMPLE),
        int(args[2]) if len(args) > 2 else 0,
    )
