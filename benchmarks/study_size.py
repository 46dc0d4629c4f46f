"""Paper Fig. 7e: pose error vs fiducial size, same configuration scaled.

ftrac_2005 scaled about its origin to outer diameters 10–50 mm (factor d/30; the length
scales with it, so 10 mm is 1 × 1 × 1.7 cm), plus the ftrac_mini preset (1 × 1 × 2 cm,
re-laid out for manufacture). For each:

- predicted by the analysis (Cramér–Rao bound of the solver's Jacobian) over N workspace
  poses (default 8,000, the paper's count) at 0.25 mm segmentation error: median and 95th
  percentile 3-D RMS translation and rotation error, and the depth (tz) part;
- a Monte-Carlo check with the robust solver at 10, 30 and 50 mm (300 images each) with
  segmentation error only, and with the paper's default C-arm errors added (focal length
  ±2 mm, principal point ±0.5 mm, pixel size ±1 µm, paper §III.A — Fig. 7e was made with
  them): 3-D RMS errors.

The paper: "the curve practically plateaus at 30 mm … a fiducial of 1 × 1 × 2 cm size
appears to be practical for most applications, with only a marginal drop in accuracy".
Plot: docs/img/study_size.png.

Run: ``.venv/bin/python benchmarks/study_size.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine, monte_carlo_pair, predicted, save_plot

E_MM = 0.25
DIAMETERS = (10, 15, 20, 25, 30, 40, 50)
MC_DIAMETERS = (10, 30, 50)
MC_N = 300


def main(n: int = 8000) -> None:
    base = load("ftrac_2005")
    print(f"machine: {machine()}")
    print(f"\npredicted 1σ over {n} workspace poses, segmentation error {E_MM} mm (3-D RMS; tz = depth)")
    print(f"{'fiducial':22s} {'t median':>9s} {'t p95':>7s} {'tz p95':>7s} {'r median °':>11s} {'r p95 °':>8s}")
    rows = {}
    for d in DIAMETERS:
        m = predicted(base.scaled(d / 30.0), n, E_MM)
        rows[d] = (np.median(m.translation_rms_mm), np.percentile(m.translation_rms_mm, 95),
                   np.percentile(m.translation_std_mm[:, 2], 95), np.median(m.rotation_rms_deg),
                   np.percentile(m.rotation_rms_deg, 95))
        print(f"{f'ftrac_2005 × {d / 30:.2f} (Ø{d})':22s} " + " ".join(f"{v:{w}.3f}" for v, w in zip(rows[d], (9, 7, 7, 11, 8))))
    mini = predicted(load("ftrac_mini"), n, E_MM)
    mrow = (np.median(mini.translation_rms_mm), np.percentile(mini.translation_rms_mm, 95),
            np.percentile(mini.translation_std_mm[:, 2], 95), np.median(mini.rotation_rms_deg),
            np.percentile(mini.rotation_rms_deg, 95))
    print(f"{'ftrac_mini (Ø10 × 20)':22s} " + " ".join(f"{v:{w}.3f}" for v, w in zip(mrow, (9, 7, 7, 11, 8))))
    ratio = rows[10][0] / rows[30][0]
    print(f"\nØ10 vs Ø30: translation × {ratio:.2f}, rotation × {rows[10][3] / rows[30][3]:.2f} "
          f"(an exact 1/size law would give × 3.00)")

    print(f"\nMonte-Carlo, {MC_N} images each, robust solver, no initial guess (3-D RMS)")
    print(f"{'diameter':9s} {'seg. only: t mm':>16s} {'r °':>6s} {'predicted t':>12s} | "
          f"{'+ paper C-arm errors: t mm':>27s} {'r °':>6s} {'not solved':>11s}")
    mc = {}
    for d in MC_DIAMETERS:
        f = base.scaled(d / 30.0)
        seg, cal, bad = monte_carlo_pair(f, MC_N, E_MM, seed=d)
        mc[d] = (seg, cal)
        pred_t = float(np.sqrt(np.mean(predicted(f, MC_N, E_MM, seed=d).translation_rms_mm ** 2)))
        print(f"Ø{d:<8d} {mc[d][0][0]:16.3f} {mc[d][0][1]:6.3f} {pred_t:12.3f} | {mc[d][1][0]:27.3f} "
              f"{mc[d][1][1]:6.3f} {bad:11d}")
    print("\npaper (Fig. 7e, 8000 poses, with the C-arm errors): the error plateaus at 30 mm; 1 × 1 × 2 cm "
          "gives only a marginal drop in accuracy.")
    print("ours: with segmentation error alone the bound falls as 1/size and never plateaus; with the "
          "paper's C-arm errors the focal-length error adds a size-independent depth error, and that "
          "floor is what flattens the curve.")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    d = np.array(DIAMETERS)
    for ax, col, mcol, label in ((axs[0], 0, 0, "translation, mm"), (axs[1], 3, 1, "rotation, deg")):
        ax.plot(d, [rows[k][col] for k in DIAMETERS], "o-", label="predicted median (segmentation only)")
        ax.plot(d, [rows[k][col + 1] for k in DIAMETERS], "o--", label="predicted p95")
        ax.plot(MC_DIAMETERS, [mc[k][0][mcol] for k in MC_DIAMETERS], "ks", label="solver, segmentation only")
        ax.plot(MC_DIAMETERS, [mc[k][1][mcol] for k in MC_DIAMETERS], "r^-", label="solver, + paper C-arm errors")
        ax.plot([10], [mrow[col]], "D", color="tab:purple", label="ftrac_mini preset (predicted median)")
        ax.set_xlabel("fiducial outer diameter, mm (configuration of ftrac_2005 scaled)")
        ax.set_ylabel(f"3-D RMS {label}")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.suptitle(f"Fig. 7e: error vs size (0.25 mm segmentation error, {n} workspace poses)", fontsize=10)
    print(f"\nplot: {save_plot(fig, 'study_size')}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8000)
