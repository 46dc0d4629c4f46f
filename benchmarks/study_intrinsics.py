"""Calibration from the fiducial (paper §V's "potential" use): how well images of a design
determine the C-arm's intrinsics — Cramér–Rao bounds, and the joint estimation checked by
Monte-Carlo — from SIMULATED observations.

For each preset, at 2,000 workspace poses (beams within 25° of AP, 667 ± 25 mm): the bound σ
of the focal length f (mm, at the 0.44 mm pixel pitch — f/s is what is observable) and of
the principal point (mm at the detector) from one image with the pose unknown
(ftrac_design.reconstruct.intrinsics.crb: the analysis's Fisher information with the four
intrinsic columns added), their correlation with the depth t_z, and what freeing them costs
the pose's depth. The bound for N images is at best 1/√N of one image's (every image keeps its
own depth: the f–t_z ambiguity of weak perspective holds for each); the joint estimation
(``solve --estimate-intrinsics``) is run on TRIALS sets of five images per segmentation
error to check that it reaches the bound and to show when an estimate would beat a 2 mm
(the paper's ±2 mm) calibration.

Plot: docs/img/study_intrinsics.png. Run: ``.venv/bin/python benchmarks/study_intrinsics.py [TRIALS]``
"""

from __future__ import annotations

import sys
import time

import numpy as np
from _common import load, machine, save_plot
from _recon_common import CAM

from ftrac_design.pose import NoiseModel, SolverOptions
from ftrac_design.pose.simulate import Workspace, simulate_observation
from ftrac_design.reconstruct import intrinsics as ik

PIX = CAM.pixel_size_mm[0]


def bounds(features, e_mm=0.25, n=2000):
    R, t = Workspace().sample(n, features.nominal_beam_direction, np.random.default_rng(0))
    noise = NoiseModel.from_segmentation_error(e_mm)
    b = ik.crb(features, CAM, R, t, noise, params=("f", "ox", "oy"))
    return {
        "f": np.median(b.std[:, 0]) * PIX,
        "o": np.median(b.std[:, 1:]) * PIX,
        "corr": np.median(np.abs(b.corr_tz[:, 0])),
        "corr_o": np.median(np.abs(b.corr_tz[:, 1:])),
        "tz_free": np.median(b.pose_std[:, 5]),
        "tz_known": np.median(b.pose_std_known[:, 5]),
    }


def joint(features, e_mm, trials, rng, images=5):
    errs, stds = [], []
    opts = SolverOptions(noise=NoiseModel.from_segmentation_error(e_mm))
    for _ in range(trials):
        R, t = Workspace().sample(images, features.nominal_beam_direction, rng)
        obs = [
            simulate_observation(features, CAM, R[j], t[j], e_mm, rng, solve_camera=CAM.perturbed(2.0))
            for j in range(images)
        ]
        est = ik.estimate(features, obs, params=("f",), options=opts, max_relative_std=np.inf)
        if est.ok:
            errs.append(est.camera.focal_length_mm - CAM.focal_length_mm)
            stds.append(est.std[0] * PIX)
    return float(np.sqrt(np.mean(np.square(errs)))), float(np.mean(stds)), len(errs)


def main(trials: int = 40) -> None:
    rng = np.random.default_rng(3)
    print(f"machine: {machine()} (shared with other jobs)")
    print(
        "SIMULATED observations. One image, f, ox, oy free besides the pose; medians over 2,000 workspace poses, "
        "0.25 mm segmentation error"
    )
    t0 = time.time()
    print(
        f"{'preset':12s} {'σ_f mm':>7s} {'σ_o mm':>7s} {'|corr(f,tz)|':>12s} {'|corr(o,tz)|':>12s} "
        f"{'σ_tz known → free mm':>22s}"
    )
    per = {}
    for name in ("ftrac_2005", "ftrac_mini", "nine_bead"):
        f = load(name)
        b = bounds(f)
        per[name] = b
        print(
            f"{name:12s} {b['f']:7.1f} {b['o']:7.1f} {b['corr']:12.4f} {b['corr_o']:12.3f} "
            f"{b['tz_known']:10.2f} → {b['tz_free']:.1f}"
        )
    f = load("ftrac_2005")
    print(f"\nftrac_2005, joint estimation of f over 5 images (f off by 2 mm, {trials} trials) vs the bound:")
    print(
        f"{'seg. error mm':>13s} {'bound σ_f 1 image':>18s} {'bound 5 images':>15s} {'estimate RMS error':>19s} "
        f"{'reported σ':>11s}"
    )
    rows = []
    for e in (0.25, 0.05, 0.01):
        b = bounds(f, e, 500)
        rms, sd, n = joint(f, e, trials, rng)
        rows.append((e, b["f"], b["f"] / np.sqrt(5), rms, sd))
        print(
            f"{e:13.2f} {b['f']:15.1f} mm {b['f'] / np.sqrt(5):12.1f} mm {rms:16.2f} mm {sd:8.2f} mm  ({n} estimated)"
        )
    need = [(e, b1 / np.sqrt(5)) for e, b1, *_ in rows]
    print(
        "σ_f scales with the segmentation error: an estimate better than the paper's ±2 mm focal tolerance "
        f"(σ 1.15 mm) from 5 images needs e ≲ {0.25 * 1.15 / need[0][1]:.3f} mm"
    )
    print(f"total {time.time() - t0:.0f} s")
    plot(per, rows)


def plot(per, rows) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    N = np.array([1, 2, 5, 10, 20, 50, 100])
    for name, b in per.items():
        axes[0].loglog(N, b["f"] / np.sqrt(N), "o-", label=f"{name}: f")
        axes[0].loglog(N, b["o"] / np.sqrt(N), "s--", label=f"{name}: principal point")
    axes[0].axhline(2.0, color="k", ls=":", label="paper's ±2 mm focal tolerance")
    axes[0].set_xlabel("images (best case: information adds)")
    axes[0].set_ylabel("Cramér–Rao σ (mm), 0.25 mm segmentation")
    axes[0].set_title("what images of the fiducial tell about the intrinsics")
    axes[0].legend(fontsize=7)
    r = np.array(rows)
    axes[1].loglog(r[:, 0], r[:, 2], "o-", label="bound, 5 images")
    axes[1].loglog(r[:, 0], r[:, 3], "s", ms=9, label="joint estimate, RMS error (Monte-Carlo)")
    axes[1].axhline(2.0 / np.sqrt(3), color="k", ls=":", label="σ of the paper's ±2 mm")
    axes[1].set_xlabel("segmentation error (mm)")
    axes[1].set_ylabel("focal length σ (mm)")
    axes[1].set_title("ftrac_2005: joint estimation reaches the bound")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    print("plot:", save_plot(fig, "study_intrinsics"))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
