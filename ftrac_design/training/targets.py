"""The maps the detector learns, drawn from a scene's exact truth on its output grid.

Per output cell (``STRIDE`` working pixels; cell (c, r) centred at working pixel
(2c + ½, 2r + ½), see :mod:`ftrac_design.detector.decode`):

- **ball**: a Gaussian of σ 0.6 cells around each ball's projected centre (peak 1), the largest
  where two overlap; only balls inside the readable field;
- **ball offset**: the centre's offset (working px) from the cell's centre, on the 3 × 3 cells
  around it (weight 1 there, 0 elsewhere);
- **wire**: a Gaussian of σ 0.6 cells of the distance to the nearest projected centre-line,
  within the readable field;
- **wire direction**: (cos 2θ, sin 2θ) of the nearest centre-line's tangent, where the wire map
  is above ½ (weight 1 there).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..detector.normalise import STRIDE, downsample

BALL_SIGMA_CELLS = 0.6
WIRE_SIGMA_CELLS = 0.6


def to_cells(uv: np.ndarray, scale: int) -> np.ndarray:
    """Image points (n, 2) px in output-cell coordinates at working scale ``scale``."""
    return ((np.asarray(uv, float) - (scale - 1) / 2) / scale - 0.5) / STRIDE


def _tangents(curve: np.ndarray) -> np.ndarray:
    d = np.gradient(curve, axis=0) if len(curve) > 1 else np.zeros_like(curve)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)


def target_maps(
    beads_uv: np.ndarray, curves: list[np.ndarray], valid: np.ndarray, scale: int, cells: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Targets (6, h, w) and their weights (6, h, w) on a grid of ``cells`` = (h, w).

    Parameters
    ----------
    beads_uv : (n, 2) ndarray
        Projected ball centres, image px.
    curves : list of (m, 2) ndarray
        Wire centre-lines, image px, densely sampled.
    valid : (H, W) bool ndarray
        Where the image can be read.
    scale : int
        The working scale.
    cells : (int, int)
        The output grid's (h, w).

    Returns
    -------
    targets, weights : (6, h, w) float32 ndarrays
        Channels as :data:`ftrac_design.detector.decode.CHANNELS`. The classification channels
        (0 and 3) have weight 1 everywhere.
    """
    h, w = cells
    y = np.zeros((6, h, w), np.float32)
    wt = np.zeros((6, h, w), np.float32)
    wt[0] = wt[3] = 1.0
    rr, cc = np.mgrid[0:h, 0:w]
    vcell = _valid_cells(valid, scale, (h, w))
    H, W = valid.shape
    for uv in np.asarray(beads_uv, float).reshape(-1, 2):
        iu, iv = int(round(uv[0])), int(round(uv[1]))
        if not (0 <= iu < W and 0 <= iv < H and valid[iv, iu]):
            continue
        cu, cv = to_cells(uv[None], scale)[0]
        y[0] = np.maximum(y[0], np.exp(-((cc - cu) ** 2 + (rr - cv) ** 2) / (2 * BALL_SIGMA_CELLS**2)))
        c0, r0 = int(round(cu)), int(round(cv))
        wu = (uv[0] - (scale - 1) / 2) / scale
        wv = (uv[1] - (scale - 1) / 2) / scale
        for r in range(max(r0 - 1, 0), min(r0 + 2, h)):
            for c in range(max(c0 - 1, 0), min(c0 + 2, w)):
                y[1, r, c] = wu - (STRIDE * c + 0.5)
                y[2, r, c] = wv - (STRIDE * r + 0.5)
                wt[1, r, c] = wt[2, r, c] = 1.0
    pts = [to_cells(c, scale) for c in curves if len(c)]
    if pts:
        tang = np.concatenate([_tangents(c) for c in curves if len(c)])
        allp = np.concatenate(pts)
        d, j = cKDTree(allp).query(np.stack([cc.ravel(), rr.ravel()], -1), distance_upper_bound=2.0)
        near = np.isfinite(d)
        heat = np.zeros(h * w, np.float32)
        heat[near] = np.exp(-(d[near] ** 2) / (2 * WIRE_SIGMA_CELLS**2))
        y[3] = heat.reshape(h, w) * vcell
        th = np.arctan2(tang[np.where(near, j, 0), 1], tang[np.where(near, j, 0), 0])
        y[4] = np.where(near, np.cos(2 * th), 0).reshape(h, w)
        y[5] = np.where(near, np.sin(2 * th), 0).reshape(h, w)
        wt[4] = wt[5] = (y[3] > 0.5).astype(np.float32)
    y[0] *= vcell
    return y, wt


def _valid_cells(valid: np.ndarray, scale: int, cells: tuple[int, int]) -> np.ndarray:
    """Whether each output cell lies in the readable field (most of its pixels do)."""
    v = downsample(np.asarray(valid, np.float32), scale * STRIDE)
    out = np.zeros(cells, np.float32)
    h, w = min(cells[0], v.shape[0]), min(cells[1], v.shape[1])
    out[:h, :w] = v[:h, :w] > 0.5
    return out
