"""Paper Fig. 7f: pose error vs where the fiducial sits between source and detector.

ftrac_2005 with the workspace (SPEC §1: beam within 25° of AP, any roll, ±25 mm around the
depth, ±25 mm off the principal ray) centred at depths of 30–90 % of the focal length
(f = 1000 mm) from the source; the paper plots against the distance from the *image plane*
(f − depth) in % of f. For each depth:

- predicted by the analysis over N workspace poses (default 6,000, the paper's count) at
  0.25 mm segmentation error: median 3-D RMS translation, its depth part, and rotation;
- a Monte-Carlo check with the robust solver at 40, 67 and 90 % (300 images each), with
  segmentation error only and with the paper's C-arm errors added.

The paper: "orientation is independent of fiducial placement, while the translation error
drops linearly in depth" (a fiducial nearer the source is magnified more).
Plot: docs/img/study_distance.png.

Run: ``.venv/bin/python benchmarks/study_distance.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine, monte_carlo_pair, predicted, save_plot

from ftrac_design.pose.simulate import Workspace

E_MM = 0.25
FOCAL_MM = 1000.0
DEPTHS_PCT = (30, 40, 50, 60, 66.7, 70, 80, 90)
MC_PCT = (40, 66.7, 90)
MC_N = 300


def main(n: int = 6000) -> None:
    f = load("ftrac_2005")
    print(f"machine: {machine()}")
    print(f"\npredicted 1σ over {n} workspace poses per depth, segmentation error {E_MM} mm")
    print(f"{'from source %f':>15s} {'from detector %f':>17s} {'t median mm':>12s} {'tz median':>10s} "
          f"{'tx median':>10s} {'r median °':>11s}")
    rows = {}
    for p in DEPTHS_PCT:
        ws = Workspace(depth_mm=p / 100 * FOCAL_MM)
        m = predicted(f, n, E_MM, workspace=ws)
        rows[p] = (np.median(m.translation_rms_mm), np.median(m.translation_std_mm[:, 2]),
                   np.median(m.translation_std_mm[:, 0]), np.median(m.rotation_rms_deg))
        print(f"{p:15.1f} {100 - p:17.1f} {rows[p][0]:12.3f} {rows[p][1]:10.3f} {rows[p][2]:10.4f} {rows[p][3]:11.3f}")
    lo, hi = rows[DEPTHS_PCT[0]], rows[DEPTHS_PCT[-1]]
    span = DEPTHS_PCT[-1] / DEPTHS_PCT[0]
    print(f"\n{DEPTHS_PCT[0]} % → {DEPTHS_PCT[-1]} % of f from the source (× {span:.1f} in depth): depth error × "
          f"{hi[1] / lo[1]:.1f} (∝ depth² would be × {span ** 2:.1f}), lateral × {hi[2] / lo[2]:.1f}, "
          f"rotation × {hi[3] / lo[3]:.1f} (∝ depth: × {span:.1f})")

    print(f"\nMonte-Carlo, {MC_N} images each, robust solver, no initial guess (3-D RMS)")
    print(f"{'from source %f':>15s} {'seg. only: t mm':>16s} {'r °':>6s} | {'+ paper C-arm errors: t mm':>27s} "
          f"{'r °':>6s} {'not solved':>11s}")
    mc = {}
    for p in MC_PCT:
        ws = Workspace(depth_mm=p / 100 * FOCAL_MM)
        seg, cal, bad = monte_carlo_pair(f, MC_N, E_MM, seed=int(p), workspace=ws)
        mc[p] = (seg, cal)
        print(f"{p:15.1f} {mc[p][0][0]:16.3f} {mc[p][0][1]:6.3f} | {mc[p][1][0]:27.3f} {mc[p][1][1]:6.3f} {bad:11d}")
    print("\npaper (Fig. 7f, 6000 poses): orientation independent of placement; translation error drops "
          "linearly as the fiducial moves away from the image plane (toward the source).")
    print("ours: the same direction — nearer the source is better — but the bound is not linear: depth "
          "error grows about as depth², and rotation error grows about linearly with depth, not flat.")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    x = 100 - np.array(DEPTHS_PCT)
    xm = 100 - np.array(MC_PCT)
    axs[0].plot(x, [rows[p][0] for p in DEPTHS_PCT], "o-", label="predicted median (segmentation only)")
    axs[0].plot(xm, [mc[p][0][0] for p in MC_PCT], "ks", label="solver, segmentation only")
    axs[0].plot(xm, [mc[p][1][0] for p in MC_PCT], "r^-", label="solver, + paper C-arm errors")
    axs[1].plot(x, [rows[p][3] for p in DEPTHS_PCT], "o-", label="predicted median")
    axs[1].plot(xm, [mc[p][0][1] for p in MC_PCT], "ks", label="solver, segmentation only")
    axs[1].plot(xm, [mc[p][1][1] for p in MC_PCT], "r^-", label="solver, + paper C-arm errors")
    axs[0].set_ylabel("3-D RMS translation error, mm")
    axs[1].set_ylabel("3-D RMS rotation error, deg")
    for ax in axs:
        ax.set_xlabel("distance from the image plane, % of focal length")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Fig. 7f: error vs region of use (ftrac_2005, 0.25 mm segmentation error, {n} poses per depth)",
                 fontsize=10)
    print(f"\nplot: {save_plot(fig, 'study_distance')}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 6000)
