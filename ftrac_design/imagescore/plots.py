"""The image-true score as a picture: the distribution of the right poses' 3-D errors per condition
(cumulative share of images), the p95 marked, and the shares refused and wrong in the legend."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .figures import trial_figures

COLORS = {"clean": "tab:blue", "anatomy": "tab:red"}


def plot_image_score(records: Sequence[dict[str, Any]], path: str | Path, title: str = "") -> Path:
    """Write the error distributions of a trial's ``records`` to ``path`` (PNG).

    Parameters
    ----------
    records : sequence of dict
        :func:`ftrac_design.imagescore.trial.run_trial` records.
    path : str or pathlib.Path
        The PNG to write.
    title : str
        The figure's title (e.g. the design's name).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = trial_figures(records)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, (key, fkey, unit) in zip(
        axes, (("translation_mm", "translation_p95_mm", "mm"), ("rotation_deg", "rotation_p95_deg", "°"))
    ):
        for cond, f in figs.items():
            v = np.sort([r[key] for r in records if r["condition"] == cond and r["outcome"] == "right"])
            if not len(v):
                continue
            n = f["images"]
            label = (
                f"{cond}: p95 {f[fkey]:.3g} {unit}" if f[fkey] is not None else cond
            ) + f" (refused {f['refused_pct']:.1f} %, wrong {f['wrong_pct']:.1f} %)"
            ax.step(v, np.arange(1, len(v) + 1) / n, where="post", color=COLORS.get(cond), label=label)
            if f[fkey] is not None:
                ax.axvline(f[fkey], color=COLORS.get(cond), lw=0.8, ls="--")
        ax.set_xlabel(f"3-D {key.split('_')[0]} error of the tracked pose, {unit}")
        ax.set_ylabel("share of images (right poses)")
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle(title or "image-true score")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
