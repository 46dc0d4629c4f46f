"""Paper Fig. 7e: pose error vs fiducial size, same configuration scaled.

ftrac_2005 (Ø30 × 50 mm) scaled about its origin to outer diameters 10–50 mm (factor d/30;
the length scales with it, so Ø10 is 1 × 1 × 1.7 cm), plus the ftrac_mini preset
(1 × 1 × 2 cm, re-laid out for manufacture — the paper's "1 × 1 × 2 cm" size). For each:

- predicted by the analysis (Cramér–Rao bound of the solver's Jacobian) over N workspace
  poses (default 8,000, the paper's count) at 0.25 mm segmentation error: median and 95th
  percentile of the 3-D RMS translation error, of its depth part (tz, camera z) and of the
  3-D RMS rotation error;
- a Monte-Carlo check with the robust solver (no initial guess) at Ø10, Ø30, Ø50 and on
  ftrac_mini, 300 images each: with segmentation error only (what the prediction is for),
  with the paper's default C-arm errors added (focal length ±2 mm, principal point
  ±0.5 mm, pixel size ±1 µm, paper §III.A — its sensitivity studies keep them on), and with
  the focal-length error alone, to see which calibration error sets the floor.

Why: with segmentation error alone every image displacement a pose change causes scales
with the fiducial, so the bound should fall as 1/size with no plateau; the paper reports a
plateau at 30 mm. The Monte-Carlo columns show where the plateau comes from.

The paper (§III.A.5, 8,000 poses): "the curve practically plateaus at 30 mm, with a bigger
fiducial exhibiting no improvement in accuracy. Moreover, a fiducial of 1 × 1 × 2 cm size
appears to be practical for most applications, with only a marginal drop in accuracy."
Plot: docs/img/study_size.png.

Run: ``.venv/bin/python benchmarks/study_size.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine, monte_carlo, predicted, rms3, save_plot

from ftrac_design.pose.simulate import PAPER_CALIBRATION_ERROR, CalibrationError

E_MM = 0.25
DIAMETERS = (10, 15, 20, 25, 30, 40, 50)
MC_DIAMETERS = (10, 30, 50)
MC_N = 300
FOCAL_ONLY = CalibrationError(focal_mm=PAPER_CALIBRATION_ERROR.focal_mm)


def _summary(m) -> tuple[float, ...]:
    """t median, t p95, tz median, tz p95 (mm), r median, r p95 (deg) of PoseMetrics."""
    t, tz, r = m.translation_rms_mm, m.translation_std_mm[:, 2], m.rotation_rms_deg
    return (
        np.median(t),
        np.percentile(t, 95),
        np.median(tz),
        np.percentile(tz, 95),
        np.median(r),
        np.percentile(r, 95),
    )


def _mc(f, seed: int) -> dict[str, tuple[float, float]]:
    """3-D RMS (t mm, r deg) of MC_N solved images per error condition, and refusals."""
    out, refused = {}, 0
    for key, cal in (("seg", None), ("carm", PAPER_CALIBRATION_ERROR), ("focal", FOCAL_ONLY)):
        err, bad = monte_carlo(f, MC_N, E_MM, seed=seed, calibration=cal)
        out[key] = rms3(err)
        refused += bad
    out["refused"] = refused
    return out


def main(n: int = 8000) -> None:
    base = load("ftrac_2005")
    print(f"machine: {machine()}")
    print(f"\npredicted 1σ over {n} workspace poses, segmentation error {E_MM} mm (t, r: 3-D RMS; tz: depth, camera z)")
    head = ("t median", "t p95", "tz median", "tz p95", "r median °", "r p95 °")
    print(f"{'fiducial':24s} " + " ".join(f"{h:>10s}" for h in head))
    rows = {}
    for d in DIAMETERS:
        rows[d] = _summary(predicted(base.scaled(d / 30.0), n, E_MM))
        print(f"{f'ftrac_2005 × {d / 30:.2f} (Ø{d})':24s} " + " ".join(f"{v:10.3f}" for v in rows[d]))
    mini_f = load("ftrac_mini")
    mini = _summary(predicted(mini_f, n, E_MM))
    print(f"{'ftrac_mini (Ø10 × 20)':24s} " + " ".join(f"{v:10.3f}" for v in mini))
    print(
        f"\nØ10 vs Ø30 (predicted medians): translation × {rows[10][0] / rows[30][0]:.2f}, depth × "
        f"{rows[10][2] / rows[30][2]:.2f}, rotation × {rows[10][4] / rows[30][4]:.2f} "
        f"(1/size would give × 3.00)"
    )
    print(
        f"Ø30 vs Ø50 (predicted medians): translation × {rows[30][0] / rows[50][0]:.2f}, depth × "
        f"{rows[30][2] / rows[50][2]:.2f}, rotation × {rows[30][4] / rows[50][4]:.2f} "
        f"(1/size would give × 1.67; a plateau × 1.00)"
    )
    print(
        f"ftrac_mini vs ftrac_2005: translation × {mini[0] / rows[30][0]:.2f}, rotation × {mini[4] / rows[30][4]:.2f}"
    )

    print(f"\nMonte-Carlo, {MC_N} images per cell, robust solver, no initial guess (3-D RMS, t mm / r °)")
    print(
        f"{'fiducial':12s} {'predicted t':>11s} | {'seg. only':>15s} | {'+ paper C-arm errors':>20s} | "
        f"{'+ focal ±2 mm only':>18s} | {'not solved':>10s}"
    )
    mc = {}
    for key, f, seed in [*((d, base.scaled(d / 30.0), d) for d in MC_DIAMETERS), ("mini", mini_f, 7)]:
        mc[key] = _mc(f, seed)
        pred_t = float(np.sqrt(np.mean(predicted(f, MC_N, E_MM, seed=seed).translation_rms_mm ** 2)))
        label = f"Ø{key}" if key != "mini" else "ftrac_mini"
        cells = " | ".join(
            f"{mc[key][k][0]:{w - 8}.3f} / {mc[key][k][1]:5.3f}" for k, w in (("seg", 15), ("carm", 20), ("focal", 18))
        )
        print(f"{label:12s} {pred_t:11.3f} | {cells} | {mc[key]['refused']:10d}")
    c = {k: mc[k]["carm"] for k in mc}
    print(
        f"\nwith the paper's C-arm errors: Ø10 / Ø30 translation × {c[10][0] / c[30][0]:.2f}, rotation × "
        f"{c[10][1] / c[30][1]:.2f}; Ø30 / Ø50 translation × {c[30][0] / c[50][0]:.2f}, rotation × "
        f"{c[30][1] / c[50][1]:.2f}; ftrac_mini / Ø30 translation × {c['mini'][0] / c[30][0]:.2f}, "
        f"rotation × {c['mini'][1] / c[30][1]:.2f}"
    )

    print(
        "\npaper (Fig. 7e, 8000 poses, C-arm errors on): the error plateaus at 30 mm, a bigger fiducial does "
        "not improve it; 1 × 1 × 2 cm loses only marginally."
    )
    # the calibration floor: what the C-arm errors add on top of segmentation, in quadrature
    floor = np.sqrt(c[50][0] ** 2 - mc[50]["seg"][0] ** 2)
    focal = np.sqrt(max(mc[50]["focal"][0] ** 2 - mc[50]["seg"][0] ** 2, 0.0))
    print(
        f"ours: with segmentation error alone the bound and the solver fall as 1/size (depth included) — no "
        f"plateau, and 1 × 1 × 2 cm is about × {mini[0] / rows[30][0]:.1f} worse than Ø30. The paper's C-arm "
        f"errors add a size-independent translation floor ({floor:.2f} mm in quadrature at Ø50, of which the "
        f"focal-length error alone gives {focal:.2f} mm), which flattens the translation curve above 30 mm; "
        f"rotation keeps improving with size even with them (Ø30 → Ø50: × {c[30][1] / c[50][1]:.2f}), and the "
        f"small fiducial still costs × {c['mini'][0] / c[30][0]:.1f} in translation and "
        f"× {c['mini'][1] / c[30][1]:.1f} in rotation."
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    d = np.array(DIAMETERS)
    for ax, col, k, label in ((axs[0], 0, 0, "translation, mm"), (axs[1], 4, 1, "rotation, deg")):
        ax.plot(
            d, [rows[x][col] for x in DIAMETERS], "o-", color="tab:blue", label="predicted median (segmentation only)"
        )
        ax.plot(d, [rows[x][col + 1] for x in DIAMETERS], "o--", color="tab:blue", mfc="none", label="predicted p95")
        ax.plot(MC_DIAMETERS, [mc[x]["seg"][k] for x in MC_DIAMETERS], "ks", label="solver, segmentation only")
        ax.plot(MC_DIAMETERS, [mc[x]["carm"][k] for x in MC_DIAMETERS], "r^-", label="solver, + paper C-arm errors")
        ax.plot(
            MC_DIAMETERS,
            [mc[x]["focal"][k] for x in MC_DIAMETERS],
            "v:",
            color="tab:orange",
            label="solver, + focal ±2 mm only",
        )
        ax.plot([10], [mini[col]], "D", color="tab:purple", label="ftrac_mini preset (predicted median)")
        ax.plot(
            [10], [mc["mini"]["carm"][k]], "D", mfc="none", color="tab:red", label="ftrac_mini, solver + C-arm errors"
        )
        ax.set_xlabel("fiducial outer diameter, mm (configuration of ftrac_2005 scaled)")
        ax.set_ylabel(f"3-D RMS {label}")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.suptitle(f"Fig. 7e: error vs size (0.25 mm segmentation error, {n} workspace poses)", fontsize=10)
    print(f"\nplot: {save_plot(fig, 'study_size')}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8000)
