"""Contour points measured where a labelling's pose predicts each wire.

A bead labelling predicts every wire's centre-line to a pixel or two. Rather than keep only
the ridge points the whole-image detector found (each above ``ridge_min_snr`` on its own:
a faint wire over dense anatomy, or a straight 0.5 mm wire seen face-on behind a patient,
gave too few), each predicted sample is moved to the ridge along the predicted normal by
Steger's step ``t = −(n·∇T) / (nᵀ H n)`` (C. Steger, IEEE PAMI 20(2), 1998) on the
derivatives at the ridge scale, iterated, and kept when it lands within the tolerance of the
prediction, where the image curves down across the wire (a ridge, not a valley) by at least
``min_snr`` times that curvature's noise. The search is a few pixels wide, so a lower
threshold than a whole-image search's admits few false points, and the per-feature χ² tests
and the image agreement judge the rest as before.

The same exclusions as for detected ridge points apply: samples under a predicted ball,
within ``separation_px`` of another predicted curve, or where the image cannot be read; and
an ellipse's points are moved outward by the curvature bias of a blurred curved ridge
(σ²κ/2, σ² the smoothing variance).

A wire too faint for that point by point (a 2 px blur, fluoroscopy dose: about 1 σ a point)
is measured on runs of it instead: each run of a few noise correlation lengths moved to the
ridge as one, by the same step on its mean gradient and curvature, one point per run.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from . import identify
from .detection import Scene, bilinear_many
from .image import second_derivative_gain

#: spacing of the predicted samples (px) that :func:`identify.curve_samples` returns
_STEP_PX = 0.5


def _normals(pts: np.ndarray, closed: bool) -> np.ndarray:
    tv = (np.roll(pts, -1, 0) - np.roll(pts, 1, 0)) if closed else np.gradient(pts, axis=0)
    n = np.stack([-tv[:, 1], tv[:, 0]], -1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def _refine(
    scene: Scene,
    q: np.ndarray,
    n: np.ndarray,
    iterations: int = 3,
    max_angle_deg: float = 25.0,
    max_aspect: float = 0.5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points ``q`` (m, 2) moved along their normals ``n`` to the ridge (Steger's step, each
    step at most 1 px); returns the points, the curvature across them (nᵀ H n), and whether
    the image there is a ridge *along the predicted curve*: its steepest downward curvature
    within ``max_angle_deg`` of the predicted normal, and the curvature along it at most
    ``max_aspect`` of that (another wire crossing the prediction, or a ball, is not this one)."""
    d = scene.derivs
    nx, ny = n[:, 0], n[:, 1]
    q = q.copy()
    cnn = np.zeros(len(q))
    maps = [d["x"], d["y"], d["xx"], d["xy"], d["yy"]]
    for _ in range(iterations):
        gx, gy, a, b, c = bilinear_many(maps, q)
        gn = nx * gx + ny * gy
        cnn = nx * nx * a + 2 * nx * ny * b + ny * ny * c
        with np.errstate(all="ignore"):
            step = np.where(cnn < 0, -gn / cnn, 0.0)
        q += np.clip(np.nan_to_num(step), -1.0, 1.0)[:, None] * n
    a, b, c = bilinear_many(maps[2:], q)
    half, disc = 0.5 * (a + c), np.sqrt(0.25 * (a - c) ** 2 + b * b)
    l1, l2 = half - disc, half + disc
    # eigenvector of l1: (b, l1 − a) or (l1 − c, b), whichever is better conditioned
    e = np.where(
        (np.abs(b) + np.abs(l1 - a) >= np.abs(l1 - c) + np.abs(b))[:, None],
        np.stack([b, l1 - a], -1),
        np.stack([l1 - c, b], -1),
    )
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)
    aligned = np.abs(np.einsum("ij,ij->i", e, n)) >= np.cos(np.radians(max_angle_deg))
    ridge = (l1 < 0) & (np.abs(l2) <= max_aspect * np.abs(l1)) & aligned
    return q, cnn, ridge


def guided_contours(
    scene: Scene,
    R: np.ndarray,
    t: np.ndarray,
    bead_radius_px: np.ndarray,
    tol_px: float,
    separation_px: float,
    min_snr: float,
    spacing_px: float = 1.0,
    ridge_var_px2: float = 0.0,
    min_points: int = 8,
    pool_px: float = 0.0,
    corr_px: float = 1.0,
    pool_min_snr: float = 2.0,
) -> identify.Contours:
    """Contour points of each line and ellipse measured where pose (R, t) puts them (see the
    module), one per ``spacing_px`` of predicted arc; curves with fewer than ``min_points``
    are dropped, and marked *missing* when not even ``min_points`` samples could be read.

    A curve with too few points is measured again on runs of ``pool_px`` of it, when that is
    positive: each run moved as one to the ridge, its SNR that of the run's mean curvature
    (the noise along the wire correlated over ``corr_px``), one point per run
    (:func:`_pooled`). A run is a point at ``pool_min_snr``; the curve is kept with at least
    three such points on a line, six on an ellipse (on noise alone a run passes 2 σ one time
    in 44: six of an ellipse's eight, 4 times in 10⁹)."""
    features = scene.features
    out = identify.Contours()
    if scene.derivs is None:
        return out
    curves = identify.curve_samples(features, scene.camera, R, t)
    if not curves:
        return out
    ids = list(curves)
    bu = identify.project(scene.camera, R, t, features.point_centers())[0] if len(features.points) else np.zeros((0, 2))
    rad = np.asarray(bead_radius_px, float)
    trees = {
        fid: cKDTree(p[np.isfinite(p).all(1)]) for fid, (_, p) in curves.items() if np.isfinite(p).all(1).sum() > 1
    }
    gain = second_derivative_gain(scene.scales.ridge_sigma_px)
    every = max(int(round(spacing_px / _STEP_PX)), 1)
    for fid in ids:
        kind, pts = curves[fid]
        closed = kind == "ellipse"
        nrm = _normals(pts, closed)
        idx = np.arange(0, len(pts), every)
        p, n = pts[idx], nrm[idx]
        usable = scene.readable(p, margin_px=2.0)
        if len(bu):
            usable &= (np.linalg.norm(p[:, None] - bu[None], axis=-1) > rad[None]).all(1)
        for other, tree in trees.items():
            if other != fid and usable.any():
                near, _ = tree.query(p, distance_upper_bound=separation_px)
                usable &= ~np.isfinite(near)
        if usable.sum() < min_points:
            out.dropped[fid] = f"{int(usable.sum())} readable samples (the rest lie on beads or other wires)"
            continue
        p, n = p[usable], n[usable]
        q, snr, sel = _points(scene, p, n, gain, tol_px, min_snr)
        need = min_points
        if len(sel) < min_points and pool_px > 0:
            # too faint point by point (a 2 px blur, fluoroscopy dose): the wire measured on
            # runs of it instead, one point per run
            pooled = _pooled(scene, p, n, idx[usable], every, gain, tol_px, pool_min_snr, pool_px, corr_px)
            fewest = _POOLED_MIN_LINE if kind == "line" else _POOLED_MIN_ELLIPSE
            if len(pooled[2]) >= fewest:
                (q, snr, sel), need = pooled, fewest
        if len(sel) < need:
            out.dropped[fid] = f"{len(sel)} contour points measured where the pose puts it"
            if np.median(snr) < 1.0:
                # not a weak wire: no ridge at all where the pose puts one
                out.missing.append(fid)
            continue
        q, snr = q[sel], snr[sel]
        if closed and ridge_var_px2 > 0:
            q = q + identify.outward_shift(pts, ridge_var_px2)[idx][usable][sel]
        (out.lines if kind == "line" else out.ellipses)[fid] = q
        out.snr[fid] = snr
    return out


#: the fewest pooled points that measure a line / an ellipse (a conic needs five, and the
#: outlier pass six)
_POOLED_MIN_LINE, _POOLED_MIN_ELLIPSE = 3, 6


def _points(
    scene: Scene, p: np.ndarray, n: np.ndarray, gain: float, tol_px: float, min_snr: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each predicted sample ``p`` (m, 2) moved to the ridge along its normal ``n``: the moved
    points, their SNR (the curvature across the wire over its noise) and the indices of
    those that are contour points (within ``tol_px`` of the prediction, a ridge along the
    curve, at least ``min_snr``)."""
    q, cnn, ridge = _refine(scene, p, n)
    snr = -cnn / (gain * scene.noise_at(q))
    off = np.einsum("ij,ij->i", q - p, n)
    keep = (np.abs(off) <= tol_px) & (snr >= min_snr) & ridge & np.isfinite(q).all(1)
    return q, snr, np.flatnonzero(keep)


def _pooled(
    scene: Scene,
    p: np.ndarray,
    n: np.ndarray,
    at: np.ndarray,
    every: int,
    gain: float,
    tol_px: float,
    min_snr: float,
    pool_px: float,
    corr_px: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A faint wire measured on runs of ``pool_px`` of its predicted samples ``p`` (m, 2),
    normals ``n``, ``at`` their sample indices along the curve (a run is unbroken where they
    are ``every`` apart, ``_STEP_PX`` each): each run is moved as one along its normals by
    Steger's step on its mean gradient and curvature across the wire, iterated as
    :func:`_refine` does, and stands for one point, at its middle sample.

    Returns, as :func:`_points` does, one entry per sample of ``p`` (NaN, SNR 0 where no run
    is centred): the moved middle samples, their SNR — the run's mean curvature over its
    noise, which averaging divides by √(run length / ``corr_px``, the correlation length of
    the noise along the wire) — and the indices of those within ``tol_px`` of the prediction
    and at least ``min_snr``, in a downward curvature."""
    m = max(int(round(pool_px / (every * _STEP_PX))), 2)
    q = np.full_like(p, np.nan)
    snr = np.zeros(len(p))
    breaks = np.flatnonzero(np.diff(at) > every) + 1
    starts = [k for a, b in zip(np.r_[0, breaks], np.r_[breaks, len(at)]) for k in range(a, b - m + 1, m)]
    if not starts:
        return q, snr, np.zeros(0, int)
    d = scene.derivs
    maps = [d["x"], d["y"], d["xx"], d["xy"], d["yy"]]
    rows = np.asarray(starts)[:, None] + np.arange(m)[None]
    P, N = p[rows], n[rows]
    nx, ny = N[..., 0], N[..., 1]
    off, cnn = np.zeros(len(rows)), np.zeros(len(rows))
    for _ in range(3):
        vals = bilinear_many(maps, (P + off[:, None, None] * N).reshape(-1, 2))
        gx, gy, a, b, c = (v.reshape(rows.shape) for v in vals)
        gn = (nx * gx + ny * gy).mean(1)
        cnn = (nx * nx * a + 2 * nx * ny * b + ny * ny * c).mean(1)
        with np.errstate(all="ignore"):
            step = np.where(cnn < 0, -gn / cnn, 0.0)
        off += np.clip(np.nan_to_num(step), -1.0, 1.0)
    mid = rows[:, m // 2]
    q[mid] = p[mid] + off[:, None] * n[mid]
    n_eff = max(m * every * _STEP_PX / corr_px, 1.0)
    snr[mid] = -cnn * np.sqrt(n_eff) / (gain * scene.noise_at(q[mid]))
    keep = (np.abs(off) <= tol_px) & (snr[mid] >= min_snr) & (cnn < 0)
    return q, snr, mid[keep]
