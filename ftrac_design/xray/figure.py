"""A rendered radiograph with its truth drawn on it (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def truth_overlay(
    image: np.ndarray,
    truth: dict,
    path: str | Path,
    title: str = "",
    margin_px: int = 40,
    raw_image: np.ndarray | None = None,
) -> Path:
    """Write a PNG of ``image`` (dense = bright) cropped around the fiducial, beside the same
    crop with the truth's projected beads, lines and ellipses drawn per feature id. With
    ``raw_image`` a third panel shows the raw detector counts (dense = dark)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..fileio import atomic_file

    pr = truth["projected"]
    pts = [np.asarray(v) for v in pr["points"].values()]
    pts += [np.asarray(v[k]) for v in pr["lines"].values() for k in ("start", "end")]
    ell = {}
    for k, e in pr["ellipses"].items():
        A, B, C, D, E, F = e["conic"]
        M = np.array([[A, B / 2, D / 2], [B / 2, C, E / 2], [D / 2, E / 2, F]])
        c = np.asarray(e["center"])
        w, V = np.linalg.eigh(M[:2, :2])
        F0 = M[2, 2] + M[:2, 2] @ c
        ax = np.sqrt(np.abs(F0 / w))
        s = np.linspace(0, 2 * np.pi, 200)
        ell[k] = c + (V @ np.stack([ax[0] * np.cos(s), ax[1] * np.sin(s)])).T
        pts += list(ell[k])
    pts = np.array(pts)
    H, W = image.shape
    u0, v0 = (np.floor(pts.min(0)) - margin_px).astype(int)
    u1, v1 = (np.ceil(pts.max(0)) + margin_px).astype(int)
    u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, W - 1), min(v1, H - 1)
    crop = image[v0 : v1 + 1, u0 : u1 + 1]
    ext = (u0 - 0.5, u1 + 0.5, v1 + 0.5, v0 - 0.5)
    panels = 3 if raw_image is not None else 2
    fig, axes = plt.subplots(1, panels, figsize=(4.2 * panels, 4.4))
    lo, hi = np.percentile(crop, [0.5, 99.8])
    for ax in axes[:2]:
        ax.imshow(crop, cmap="gray", vmin=lo, vmax=hi, extent=ext, interpolation="nearest")
        ax.set_xticks([])
        ax.set_yticks([])
    axes[0].set_title("log image (dense = bright)", fontsize=9)
    ax = axes[1]
    colours = plt.get_cmap("tab10")
    for i, (k, xy) in enumerate(ell.items()):
        ax.plot(xy[:, 0], xy[:, 1], "-", lw=0.8, color=colours(i))
        ax.text(*xy[0], k, color=colours(i), fontsize=8)
    for i, (k, ln) in enumerate(pr["lines"].items()):
        a, b = np.asarray(ln["start"]), np.asarray(ln["end"])
        ax.plot([a[0], b[0]], [a[1], b[1]], "-", lw=0.8, color=colours(i + 3))
        ax.text(*b, k, color=colours(i + 3), fontsize=8)
    for k, p in pr["points"].items():
        ax.plot(*p, "+", ms=6, mew=0.8, color="yellow")
        ax.text(p[0] + 3, p[1] - 3, k, color="yellow", fontsize=7)
    ax.set_xlim(ext[0], ext[1])
    ax.set_ylim(ext[2], ext[3])
    ax.set_title("truth: projected features", fontsize=9)
    if raw_image is not None:
        rc = raw_image[v0 : v1 + 1, u0 : u1 + 1]
        axes[2].imshow(rc, cmap="gray", extent=ext, interpolation="nearest")
        axes[2].set_xticks([])
        axes[2].set_yticks([])
        axes[2].set_title("raw counts (dense = dark)", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path
