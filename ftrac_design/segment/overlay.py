"""Overlay picture of a tracked image: what was detected and what the pose predicts.

Per feature id, in one colour each: the detected bead centres (+) and contour points
(dots), and the model reprojected at the solved pose (bead circles, line segments, ellipse
curves) with the id written beside it. Blobs and ridge points left unlabelled are shown
faintly in grey, so that a missed or misread feature stands out. matplotlib (Agg).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..features.model import Features
from ..fileio import atomic_file
from .identify import project


def _crop_box(img: np.ndarray, result, features: Features, cam, ok_pose: bool) -> tuple[np.ndarray, np.ndarray]:
    """The (col, row) corners of what was found plus 30 px: the blobs, and the balls and ellipses
    projected at the pose (the fiducial covers a few hundred pixels of a 1024² image)."""
    pose = result.pose
    pts = []
    if result.beads is not None and len(result.beads):
        pts.append(result.beads.uv)
    if ok_pose:
        uv, _ = (
            project(cam, pose.rotation, pose.translation_mm, features.point_centers())
            if features.points
            else (np.zeros((0, 2)), None)
        )
        pts.append(uv)
        for el in features.ellipses:
            pts.append(project(cam, pose.rotation, pose.translation_mm, el.sample(np.linspace(0, 2 * np.pi, 16)))[0])
    H, W = img.shape
    if not pts:
        return np.array([0, 0]), np.array([W - 1, H - 1])
    allp = np.concatenate(pts)
    allp = allp[np.isfinite(allp).all(1)]
    lo = np.clip(np.floor(allp.min(0)) - 30, 0, [W - 1, H - 1]).astype(int)
    hi = np.clip(np.ceil(allp.max(0)) + 30, 0, [W - 1, H - 1]).astype(int)
    return lo, hi


def _draw_found(ax, result, colour: dict, lo: np.ndarray, hi: np.ndarray) -> None:
    """The ridge points and blobs found (grey) and what the observation used (each feature's colour)."""
    if result.ridges is not None and len(result.ridges):
        r = result.ridges.uv
        inside = (r >= lo).all(1) & (r <= hi).all(1)
        ax.plot(r[inside, 0], r[inside, 1], ".", color="0.55", ms=1.0, alpha=0.6)
    if result.beads is not None and len(result.beads):
        ax.plot(result.beads.uv[:, 0], result.beads.uv[:, 1], "o", mfc="none", mec="0.6", ms=9, mew=0.6)
    obs = result.observation
    if obs is not None:
        for fid, uv in obs.points.items():
            ax.plot(uv[0], uv[1], "+", color=colour[fid], ms=10, mew=1.5)
        for store in (obs.lines, obs.ellipses):
            for fid, c in store.items():
                ax.plot(c.points[:, 0], c.points[:, 1], ".", color=colour[fid], ms=2.5)


def _draw_model(ax, plt, pose, features: Features, cam, colour: dict) -> None:
    """The model projected at the pose: balls as circles, lines and ellipses, each named (dashed
    when the pose did not converge)."""
    R, t = pose.rotation, pose.translation_mm
    style = "-" if pose.converged else "--"
    for p in features.points:
        uv = project(cam, R, t, p.center[None])[0][0]
        rad = p.diameter / 2 * cam.fx / float((R @ p.center + t)[2])
        ax.add_patch(plt.Circle(uv, rad, fill=False, color=colour[p.id], lw=1.0, ls=style))
        ax.annotate(p.id, uv, xytext=(6, -6), textcoords="offset points", color=colour[p.id], fontsize=8)
    for ln in features.lines:
        ab = project(cam, R, t, np.array([ln.start, ln.end]))[0]
        ax.plot(ab[:, 0], ab[:, 1], style, color=colour[ln.id], lw=0.9, alpha=0.9)
        m = ab.mean(0)
        ax.annotate(ln.id, m, xytext=(8, 8), textcoords="offset points", color=colour[ln.id], fontsize=9, weight="bold")
    for el in features.ellipses:
        uv = project(cam, R, t, el.sample(np.linspace(0, 2 * np.pi, 200)))[0]
        ax.plot(uv[:, 0], uv[:, 1], style, color=colour[el.id], lw=0.9, alpha=0.9)
        top = uv[np.argmin(uv[:, 1])]
        ax.annotate(
            el.id,
            top,
            xytext=(0, -10),
            textcoords="offset points",
            color=colour[el.id],
            fontsize=9,
            weight="bold",
            ha="center",
        )


def _heading(title: str, pose, ok_pose: bool) -> str:
    """The picture's title: ``title``, then the translation, RMS residual and whether it converged."""
    status = "converged" if pose.converged else f"NOT converged: {pose.error}"
    head = title + ("\n" if title else "")
    if ok_pose:
        tt = pose.translation_mm
        head += f"t = ({tt[0]:.2f}, {tt[1]:.2f}, {tt[2]:.2f}) mm, rms {pose.rms_residual_px:.3f} px — {status}"
    else:
        head += status
    return head if len(head) < 160 else head[:157] + "…"


def draw_overlay(path: str | Path, image: np.ndarray, features: Features, result, title: str = "") -> Path:
    """Write the overlay PNG of ``result`` (a :class:`~.options.TrackResult`) on ``image``
    (the density image or the image as stored; shown dense = bright), atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img = np.asarray(image, float)
    if result.polarity == "dense-dark":
        img = -np.log(np.maximum(img, max(float(img.max()) * 1e-4, 1e-6)))
    pose = result.pose
    cam = result.observation.camera if result.observation is not None else None
    ok_pose = bool(np.all(np.isfinite(pose.rotation))) and cam is not None
    lo, hi = _crop_box(img, result, features, cam, ok_pose)
    crop = img[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
    fig, ax = plt.subplots(figsize=(8, 8 * crop.shape[0] / max(crop.shape[1], 1) + 0.6), dpi=110)
    vmin, vmax = np.percentile(crop, [1, 99.8]) if crop.size else (0, 1)
    ax.imshow(
        crop,
        cmap="gray",
        vmin=vmin,
        vmax=vmax,
        extent=(lo[0] - 0.5, hi[0] + 0.5, hi[1] + 0.5, lo[1] - 0.5),
        interpolation="nearest",
    )
    ids = features.ids
    cmap = plt.get_cmap("tab20" if len(ids) > 10 else "tab10")
    colour = {fid: cmap(i % cmap.N) for i, fid in enumerate(ids)}
    _draw_found(ax, result, colour, lo, hi)
    if ok_pose:
        _draw_model(ax, plt, pose, features, cam, colour)
    ax.set_xlim(lo[0] - 0.5, hi[0] + 0.5)
    ax.set_ylim(hi[1] + 0.5, lo[1] - 0.5)
    ax.set_title(_heading(title, pose, ok_pose), fontsize=9)
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return Path(path)
