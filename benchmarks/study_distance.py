"""Paper Fig. 7f: pose error vs where the fiducial sits between source and detector.

ftrac_2005 with the workspace (SPEC §1: beam within 25° of AP, any roll, ±25 mm around the
depth, ±25 mm off the principal ray) centred at depths of 30–90 % of the focal length
(f = 1000 mm) from the source. The paper plots against the distance from the *image plane*
(f − depth) in % of f; both are printed. For each depth:

- predicted by the analysis over N workspace poses (default 6,000, the paper's count) at
  0.25 mm segmentation error: median 3-D RMS translation, its depth (tz) and lateral (tx)
  parts, and the 3-D RMS rotation;
- a Monte-Carlo check with the robust solver (no initial guess), 300 images per depth at
  six depths, with segmentation error only and with the paper's C-arm errors added (focal
  length ±2 mm, principal point ±0.5 mm, pixel size ±1 µm — kept on in its studies).

Why: a pinhole image of a fiducial of size s at depth Z moves by about f·δX/Z for a
lateral shift or a rotation and by f·s·δZ/Z² for a depth shift, so with image noise alone
the lateral and rotation errors should grow ∝ Z and the depth error ∝ Z² (paper §III.A.1:
"the depth derivative has a quadratic term in the denominator"). A focal-length error δf
instead biases the depth by Z·δf/f, ∝ Z (a pixel-size or principal-point error likewise
gives a bias ∝ Z). Each curve's exponent k in error ∝ Z^k is fitted
(least squares in log–log) and printed.

The paper (§III.A.6, 6,000 poses): "A fiducial closer to the source has a larger
magnification, thus scaling any small errors and making the algorithm converge better …
Figure 7(f) shows the pose recovery error as a function of the distance from the image
plane, expressed as a percentage of the focal length. It can be concluded that orientation
is independent of fiducial placement, while the translation error drops linearly in depth."
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
MC_PCT = (30, 40, 50, 66.7, 80, 90)
MC_N = 300


def exponent(pct, values) -> float:
    """k of the least-squares fit values ∝ depth^k."""
    return float(np.polyfit(np.log(np.asarray(pct, float)), np.log(np.asarray(values, float)), 1)[0])


def main(n: int = 6000) -> None:
    f = load("ftrac_2005")
    print(f"machine: {machine()}")
    print(f"\npredicted 1σ over {n} workspace poses per depth, segmentation error {E_MM} mm (medians; t, r 3-D RMS)")
    print(f"{'from source %f':>15s} {'from detector %f':>17s} {'t mm':>8s} {'tz mm':>8s} {'tx mm':>8s} {'r °':>7s}")
    rows = {}
    for p in DEPTHS_PCT:
        m = predicted(f, n, E_MM, workspace=Workspace(depth_mm=p / 100 * FOCAL_MM))
        rows[p] = (
            np.median(m.translation_rms_mm),
            np.median(m.translation_std_mm[:, 2]),
            np.median(m.translation_std_mm[:, 0]),
            np.median(m.rotation_rms_deg),
        )
        print(f"{p:15.1f} {100 - p:17.1f} {rows[p][0]:8.3f} {rows[p][1]:8.3f} {rows[p][2]:8.4f} {rows[p][3]:7.3f}")
    k_pred = [exponent(DEPTHS_PCT, [rows[p][i] for p in DEPTHS_PCT]) for i in range(4)]
    print(
        f"fitted exponent k (error ∝ depth^k): t {k_pred[0]:.2f}, tz {k_pred[1]:.2f}, tx {k_pred[2]:.2f}, "
        f"r {k_pred[3]:.2f}   (pinhole expectation: tz 2, tx 1, r 1)"
    )
    lo, hi = rows[DEPTHS_PCT[0]], rows[DEPTHS_PCT[-1]]
    print(
        f"{DEPTHS_PCT[0]} % → {DEPTHS_PCT[-1]} % of f from the source (× {DEPTHS_PCT[-1] / DEPTHS_PCT[0]:.1f} in "
        f"depth): depth error × {hi[1] / lo[1]:.1f}, lateral × {hi[2] / lo[2]:.1f}, "
        f"rotation × {hi[3] / lo[3]:.1f}"
    )

    print(f"\nMonte-Carlo, {MC_N} images per depth and condition, robust solver, no initial guess (3-D RMS)")
    print(
        f"{'from source %f':>15s} {'from detector %f':>17s} | {'seg. only: t mm':>15s} {'r °':>6s} | "
        f"{'+ paper C-arm errors: t mm':>26s} {'r °':>6s} | {'not solved':>10s}"
    )
    mc = {}
    for p in MC_PCT:
        seg, cal, bad = monte_carlo_pair(f, MC_N, E_MM, seed=int(p), workspace=Workspace(depth_mm=p / 100 * FOCAL_MM))
        mc[p] = (seg, cal)
        print(f"{p:15.1f} {100 - p:17.1f} | {seg[0]:15.3f} {seg[1]:6.3f} | {cal[0]:26.3f} {cal[1]:6.3f} | {bad:10d}")
    k_mc = {(c, j): exponent(MC_PCT, [mc[p][c][j] for p in MC_PCT]) for c in (0, 1) for j in (0, 1)}
    print(
        f"fitted exponent k: segmentation only t {k_mc[0, 0]:.2f}, r {k_mc[0, 1]:.2f}; "
        f"with C-arm errors t {k_mc[1, 0]:.2f}, r {k_mc[1, 1]:.2f}"
    )

    print(
        "\npaper (Fig. 7f, 6000 poses, x-axis = distance from the image plane): orientation independent of "
        "placement; translation error drops linearly as the fiducial moves away from the image plane "
        "(toward the source)."
    )
    print(
        f"ours: the same direction for translation — nearer the source is better — but with segmentation "
        f"error alone the translation (depth) error grows as depth^{k_mc[0, 0]:.1f}, not linearly; with the "
        f"paper's C-arm errors their bias (∝ depth for a focal-length, pixel-size or principal-point error) "
        f"adds in and the solver's translation "
        f"error grows as depth^{k_mc[1, 0]:.1f}, close to the paper's straight line. Orientation is not "
        f"independent of placement: it grows about ∝ depth (k = {k_mc[0, 1]:.1f} segmentation only, "
        f"{k_mc[1, 1]:.1f} with C-arm errors; × {mc[90][1][1] / mc[30][1][1]:.1f} from 30 % to 90 %), "
        f"though it stays small ({min(v[1][1] for v in mc.values()):.2f}–"
        f"{max(v[1][1] for v in mc.values()):.2f}° with the C-arm errors)."
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    x = 100 - np.array(DEPTHS_PCT)
    xm = 100 - np.array(MC_PCT)
    for ax, col, j in ((axs[0], 0, 0), (axs[1], 3, 1)):
        ax.plot(x, [rows[p][col] for p in DEPTHS_PCT], "o-", label="predicted median (segmentation only)")
        ax.plot(xm, [mc[p][0][j] for p in MC_PCT], "ks", label="solver, segmentation only")
        ax.plot(xm, [mc[p][1][j] for p in MC_PCT], "r^-", label="solver, + paper C-arm errors")
        ax.set_xlabel("distance from the image plane, % of focal length")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    axs[0].set_ylabel("3-D RMS translation error, mm")
    axs[1].set_ylabel("3-D RMS rotation error, deg")
    fig.suptitle(
        f"Fig. 7f: error vs region of use (ftrac_2005, 0.25 mm segmentation error, {n} poses per depth)", fontsize=10
    )
    print(f"\nplot: {save_plot(fig, 'study_distance')}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 6000)
