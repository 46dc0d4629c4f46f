"""Picture of a bead-grid distortion fit: measured and fitted displacement, magnified.

For every indexed bead, an arrow from its ideal place H(i, j) to where it was seen (the
measured displacement, black) and one to where the model puts it (D(H(i, j)), red), both
magnified so that pixels of distortion are visible; beads the fit left out are marked. A
second panel shows the residuals (seen − fitted), magnified far more. matplotlib (Agg).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fileio import atomic_file
from .gridcal import GridReport


def draw_grid_fit(path: str | Path, image: np.ndarray, report: GridReport, title: str = "") -> Path:
    """Write the PNG of ``report`` over ``image`` (shown as stored, grey), atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img = np.asarray(image, float)
    ideal, seen, fit = report.ideal_px, report.detected_px, report.fitted_px
    disp = np.hypot(*(seen - ideal).T)
    res = np.hypot(*(seen - fit).T)
    H, W = img.shape
    # magnify so that the largest displacement (residual) spans about one grid pitch (half)
    k_disp = report.pitch_px / max(float(disp.max(initial=0.0)), 1e-6)
    k_res = 0.5 * report.pitch_px / max(float(res[report.used].max(initial=0.0)), 1e-6)
    fig, axes = plt.subplots(1, 2, figsize=(14, 7.4), dpi=100)
    vmin, vmax = np.percentile(img, [1, 99.5])
    for ax in axes:
        ax.imshow(img, cmap="gray", vmin=vmin, vmax=vmax, interpolation="nearest")
        ax.set_xlim(-0.5, W - 0.5)
        ax.set_ylim(H - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
    u = report.used
    quiver = dict(angles="xy", scale_units="xy", scale=1.0, width=0.0022)
    axes[0].quiver(ideal[:, 0], ideal[:, 1], *(k_disp * (seen - ideal)).T, color="k", **quiver)
    axes[0].quiver(ideal[:, 0], ideal[:, 1], *(k_disp * (fit - ideal)).T, color="tab:red", alpha=0.7, **quiver)
    axes[0].plot(seen[~u, 0], seen[~u, 1], "x", color="tab:orange", ms=6)
    axes[0].set_title(
        f"displacement × {k_disp:.3g}: measured (black), model (red); max {disp.max(initial=0.0):.2f} px", fontsize=9
    )
    axes[1].quiver(fit[u, 0], fit[u, 1], *(k_res * (seen - fit)[u]).T, color="tab:blue", **quiver)
    axes[1].plot(seen[~u, 0], seen[~u, 1], "x", color="tab:orange", ms=6)
    axes[1].set_title(
        f"residual × {k_res:.3g}: RMS {report.rms_px:.3f} px, max {report.max_px:.3f} px "
        f"({report.n_used} beads; × left out)",
        fontsize=9,
    )
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return Path(path)
