"""Intensity refinement vs the pixel-level Cramér–Rao bound (target efficiency ≥ 0.9 per axis).

Rendered workspace images of ftrac_2005 (with its body) at the default imaging model (60 keV,
0.6 mm focal spot, σ 0.7 px detector blur, 10⁴ quanta/px, 16-bit raw counts). For each
image: the feature path (``ftrac_design.segment.track_image``, no initial guess) gives the
start; ``refine_intensity`` refines it on the raw image. Errors are taken in the solver's
parametrisation — rotation vector ``log(R_est R_trueᵀ)`` (camera axes, rad) and
``t_est − t_true`` (mm) — and divided per axis by the pixel-level bound at the true pose
with the nuisance parameters the refinement fitted unknown (gain and the 12 px spline
background for the spline model; gain and a quadratic background otherwise, also for the
high-pass). Efficiency per axis = 1 / mean(z²) (1 = the estimator attains the bound); the
start's (feature path's) efficiency against the same bound says what segmentation loses.

Refinement (third argument): ``default`` (``background="auto"``: spline background, the
high-pass where the image is cluttered, Huber 3σ — what ``track --refine intensity`` uses),
``plain`` (gain + quadratic, no Huber), ``highpass`` (the earlier default: 8 px high-pass +
Huber), ``spline`` (the spline always).

With ``anatomy`` every image is rendered over its own anatomy-like background
(``xray.anatomy``); the bound then includes the background's attenuation (but takes the
background as known), so errors are also given against the quadratic-background bound
(RMS z, the figure compared over anatomy).

With ``perturbed`` the start is the true pose moved by a random error of the feature path's
size (1σ 0.05° per rotation, 0.02 mm lateral, 0.4 mm depth) instead of the feature path
itself — this skips segmentation, so that a thousand images fit in a run. Efficiencies are
printed with a 95 % interval: if the z are Gaussian with variance 1/E, n·mean(z²)·E ~ χ²ₙ.

Run: ``.venv/bin/python benchmarks/intensity_accuracy.py [N] [anatomy] [default|plain|highpass|spline] [perturbed]``
(default 30 images, default refinement)
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from types import SimpleNamespace

import numpy as np
from _common import load, machine
from intensity_common import AXES, MODES, Judge, efficiency
from tqdm import tqdm

from ftrac_design.intensity import RoiModel, perturb
from ftrac_design.pose.camera import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment.pipeline import track_image
from ftrac_design.xray import ImagingModel, anatomy, render


def main(n: int = 30, background: bool = False, mode: str = "default", perturbed: bool = False) -> None:
    features = load("ftrac_2005")
    cam = Camera()
    imaging = ImagingModel()
    R, t = Workspace().sample(n, features.nominal_beam_direction, np.random.default_rng(1313))
    z_int, z_q, z_feat, times, skipped, worse = [], [], [], [], 0, 0
    rng_start = np.random.default_rng(7)
    render_cpu, models, std_q, std_s = [], Counter(), [], []
    for k in tqdm(range(n), desc="intensity", unit="image", mininterval=10):
        bg = anatomy(seed=k) if background else None
        img = render(features, R[k], t[k], cam, imaging, rng=np.random.default_rng(k), background=bg)
        if perturbed:
            x = rng_start.standard_normal(6) * np.array([np.radians(0.05)] * 3 + [0.02, 0.02, 0.4])
            R_s, t_s = perturb(R[k], t[k], x)
            tr = SimpleNamespace(pose=SimpleNamespace(converged=True, rotation=R_s, translation_mm=t_s))
        else:
            tr = track_image(img.raw.astype(float), features, cam, polarity_hint="dense_dark")
        if not tr.pose.converged:
            skipped += 1
            continue
        judge = Judge(features, cam, imaging, R[k], t[k], background=bg)
        res, z, zq, dt = judge.refine(img.raw, tr.pose.rotation, tr.pose.translation_mm, mode, scales=(0.0,))
        times.append(dt)
        models[res.background_model] += 1
        # baseline in the same run: one noise-free render of the refinement's region of interest
        roi_model = RoiModel(features, cam, imaging, res.roi)
        c1 = time.process_time()
        roi_model.log_image(tr.pose.rotation, tr.pose.translation_mm)
        render_cpu.append(time.process_time() - c1)
        worse += res.cost_end > res.cost_start
        z_int.append(z)
        z_q.append(zq)
        z_feat.append(judge.z(tr.pose.rotation, tr.pose.translation_mm, res.background_model))
        std_q.append(judge.quad.std)
        std_s.append(judge.spline.std if res.background_model == "spline" else judge.quad.std)
        if len(z_int) % 100 == 0:  # interim figures of a long run
            tqdm.write(f"after {len(z_int)}: efficiency " + " ".join(f"{x:.2f}" for x in efficiency(z_int)[0]))
    z_int, z_q, z_feat = np.array(z_int), np.array(z_q), np.array(z_feat)
    eff_int, lo, hi = efficiency(z_int)
    eff_feat = efficiency(z_feat)[0]
    sq, ss = np.median(std_q, 0), np.median(std_s, 0)
    print(
        f"\nftrac_2005, {n} workspace images{' over anatomy' if background else ''}, {mode} refinement "
        f"({MODES[mode] or 'refine_intensity defaults'}; background models used {dict(models)}), default imaging "
        f"model, raw 16-bit; {len(z_int)} started from "
        + (
            "the true pose perturbed by feature-path-sized errors"
            if perturbed
            else f"the feature path ({skipped} not converged there, skipped)"
        )
    )
    print(f"machine: {machine()} (shared with other jobs)")
    print(
        f"{'axis':6s} {'bound quad':>12s} {'bound used':>12s} {'eff. intensity':>15s} {'95 % interval':>14s} "
        f"{'eff. start' if perturbed else 'eff. features':>14s} {'RMS z int.':>11s} {'RMS z quad':>11s} "
        f"{'mean z int.':>12s}"
    )
    for j, a in enumerate(AXES):
        unit, f = ("deg", 180 / np.pi) if j < 3 else ("mm", 1.0)
        print(
            f"{a:6s} {sq[j] * f:9.5f} {unit:3s}{ss[j] * f:9.5f} {unit:3s} {eff_int[j]:15.2f} "
            f"{'':3s}{lo[j]:5.2f}–{hi[j]:5.2f} {eff_feat[j]:14.4f} "
            f"{np.sqrt(np.mean(z_int[:, j] ** 2)):11.2f} {np.sqrt(np.mean(z_q[:, j] ** 2)):11.2f} "
            f"{np.mean(z_int[:, j]):12.2f}"
        )
    print(
        f"\nintensity efficiency ≥ 0.9 on every axis: {'met' if np.all(eff_int >= 0.9) else 'missed'} "
        f"(min {eff_int.min():.2f}); ended worse than the start: {worse}"
    )
    wall, cpu = np.array(times).T
    print(
        f"refinement time per 1024² image: median {1e3 * np.median(wall):.0f} ms wall, {1e3 * np.median(cpu):.0f} ms "
        f"CPU of this process (max {1e3 * wall.max():.0f} / {1e3 * cpu.max():.0f}); target ≤ 1 s"
    )
    rc = float(np.median(render_cpu))
    print(
        f"baseline, same run: one ROI render {1e3 * rc:.0f} ms CPU (median); refinement = {np.median(cpu) / rc:.0f} "
        f"renders median, {cpu.max() / rc:.0f} max"
    )


if __name__ == "__main__":
    args = sys.argv[1:]
    mode = next((a for a in args if a in MODES), "default")
    main(int(args[0]) if args and args[0].isdigit() else 30, "anatomy" in args, mode, "perturbed" in args)
