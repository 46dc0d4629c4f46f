"""Paper Table I's feature combinations, scored by conditioning instead of by trial.

The combinations of ftrac_2005 the paper solved with its basic algorithm — 6P+3L+2E,
6P+2E, 6P+3L, 3L+2E, 6P, where 6P are the six beads at the lines' end-points (as in
``paper_table1.py``) — analysed over N workspace poses (default 20,000) at 0.25 mm
segmentation error: median and worst condition number of the scaled Jacobian, median
D-optimality, the share of singular poses, and the 95th-percentile predicted 3-D RMS
translation and rotation errors; printed beside the paper's Table I (mean errors and the
basic algorithm's failure rate from far guesses, which include the paper's C-arm errors).

Conditioning measures how well a combination *determines* the pose near the truth; the
paper's failures measure whether a local solve from far away *finds* it. The two need not
agree, and the comparison says which of the paper's numbers conditioning explains. The
paper's errors are mean error norms with its C-arm errors on, ours 1σ bounds from
segmentation error alone, so rankings are compared (Spearman ρ), not values.
Plot: docs/img/study_combinations.png.

Run: ``.venv/bin/python benchmarks/study_combinations.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine, save_plot
from paper_table1 import COMBOS, PAPER

from ftrac_design.analysis import AnalysisSettings, score_design


def main(n: int = 20_000) -> None:
    f = load("ftrac_2005")
    settings = AnalysisSettings(poses=n)
    print(f"machine: {machine()}")
    print(f"\n{n} workspace poses, segmentation error {settings.segmentation_error_mm} mm, predicted 1σ (3-D RMS)")
    print(
        f"{'features':9s} | {'paper: t mm':>11s} {'rot °':>6s} {'fail %':>7s} | {'cond median':>11s} {'worst':>7s} "
        f"{'D-opt':>6s} {'singular':>9s} {'t p95 mm':>9s} {'r p95 °':>8s}"
    )
    out = {}
    for name, ids in COMBOS.items():
        s = score_design(f.subset(ids), settings)
        figs = s.figures
        sing = float(np.mean(~np.isfinite(s.analysis.overall.condition)))
        out[name] = (
            figs["condition"]["median"],
            figs["condition"]["worst"],
            figs["d_optimality"]["median"],
            sing,
            figs["translation_mm"]["p95"],
            figs["rotation_deg"]["p95"],
        )
        p = PAPER[name]
        c = out[name]
        print(
            f"{name:9s} | {p[0]:11.2f} {p[1]:6.2f} {p[2]:7.1f} | {c[0]:11.0f} {c[1]:7.0f} {c[2]:6.2f} {c[3]:9.1%} "
            f"{c[4]:9.3f} {c[5]:8.3f}"
        )
    names = list(COMBOS)

    def spearman(a, b) -> float:
        """Rank correlation of two sequences without ties (5 combinations: a coarse measure)."""
        ra, rb = (np.argsort(np.argsort(np.asarray(x, float))) for x in (a, b))
        return float(np.corrcoef(ra, rb)[0, 1])

    def order(col) -> str:
        return " < ".join(sorted(names, key=lambda k: col(k)))

    print(f"\nranked by translation: paper {order(lambda k: PAPER[k][0])}")
    print(
        f"                       ours  {order(lambda k: out[k][4])}   (Spearman ρ = "
        f"{spearman([PAPER[k][0] for k in names], [out[k][4] for k in names]):+.1f})"
    )
    print(f"ranked by rotation:    paper {order(lambda k: PAPER[k][1])}")
    print(
        f"                       ours  {order(lambda k: out[k][5])}   (Spearman ρ = "
        f"{spearman([PAPER[k][1] for k in names], [out[k][5] for k in names]):+.1f})"
    )
    print(
        f"paper failures vs median condition: Spearman ρ = "
        f"{spearman([PAPER[k][2] for k in names], [out[k][0] for k in names]):+.1f}; "
        f"singular poses in any combination: {max(out[k][3] for k in names):.1%}"
    )
    print("(ρ over 5 combinations is coarse: only |ρ| = 1.0 is significant at the 5 % level, two-sided)")
    print(
        "\nreading: no combination is singular anywhere in the workspace and 3L+2E is as well conditioned as "
        "the full set, so conditioning does not explain the paper's 90.6 % failures for 3L+2E, nor does it "
        "separate the others (27–31 % failures at condition numbers from 37 to 103). Those failures are "
        "convergence failures of a single local solve from far guesses — a question of the basin of "
        "attraction, which the bound at the true pose cannot see (paper_table1.py measures it directly). "
        "The predicted accuracy does rank the combinations as the paper's errors do: exactly in rotation, "
        "and in translation except that 3L+2E and 6P+3L swap. The condition number alone does not rank "
        "accuracy: 6P is well conditioned but weak (lowest D-optimality), and adding the lines to it "
        "sharpens some directions far more than others (6P+3L has the largest condition number)."
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.arange(len(names))
    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    axs[0].bar(x - 0.2, [out[k][4] for k in names], 0.4, label="predicted p95 translation, mm")
    axs[0].bar(x + 0.2, [out[k][5] for k in names], 0.4, label="predicted p95 rotation, deg")
    axs[0].set_xticks(x, names)
    axs[0].legend(fontsize=8)
    axs[0].grid(True, axis="y", alpha=0.3)
    axs[1].bar(x - 0.2, [out[k][0] for k in names], 0.4, label="median condition number")
    ax2 = axs[1].twinx()
    ax2.bar(x + 0.2, [PAPER[k][2] for k in names], 0.4, color="tab:red", label="paper: basic-algorithm failures, %")
    axs[1].set_xticks(x, names)
    axs[1].set_ylabel("condition number")
    ax2.set_ylabel("paper failures, %")
    # one legend for both axes, with head-room so it covers no bar
    axs[1].set_ylim(0, 1.3 * max(out[k][0] for k in names))
    ax2.set_ylim(0, 130)
    handles = axs[1].get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
    axs[1].legend(handles, [h.get_label() for h in handles], loc="upper left", fontsize=8)
    fig.suptitle(f"Table I's feature combinations scored by conditioning ({n} workspace poses, 0.25 mm)", fontsize=10)
    print(f"\nplot: {save_plot(fig, 'study_combinations')}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20_000)
