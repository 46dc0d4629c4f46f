"""A rendered fluoroscopy run: the fiducial through a C-arm's swing
(:func:`ftrac_design.pose.simulate.carm_sweep`), over anatomy that moves with it.

The fiducial is fixed to the patient, so the anatomy behind it moves in the image with the
fiducial's projection: one anatomy image (:func:`.background.anatomy`), wider than a frame
by ``margin_px`` on each side, is cut at the fiducial origin's projected displacement from
frame 0 (whole pixels, clipped to the margin). Each frame's quantum noise has its own seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera
from ..pose.simulate import carm_sweep
from .background import anatomy
from .model import ImagingModel
from .render import render


@dataclass(frozen=True)
class SweepRun:
    """A rendered run.

    Attributes
    ----------
    raw : (n, H, W) raw detector counts (uint16, dense = dark), one frame per C-arm position.
    rotation, translation_mm : (n, 3, 3), (n, 3): the true poses F → X (mm).
    camera : the intrinsics every frame was rendered with.
    """

    raw: np.ndarray
    rotation: np.ndarray
    translation_mm: np.ndarray
    camera: Camera


def render_sweep(
    features: Features,
    R0: np.ndarray,
    t0: np.ndarray,
    n: int,
    camera: Camera = Camera(),
    imaging: ImagingModel = ImagingModel(),
    seed: int = 0,
    anatomy_strength: float = 1.0,
    margin_px: int = 160,
    **sweep,
) -> SweepRun:
    """``n`` radiographs of ``features`` through a C-arm's swing starting at pose (R0, t0).

    Parameters
    ----------
    features : the design's features (mm, frame F).
    R0, t0 : the pose F → X at frame 0.
    n : number of frames.
    camera, imaging : the intrinsics and the imaging model (its ``image_shape`` is the frame's).
    seed : the anatomy's seed; frame k's noise has seed ``seed`` × 100003 + k.
    anatomy_strength : scales the anatomy (0: none).
    margin_px : how far the anatomy can move with the fiducial (px).
    **sweep : :func:`~ftrac_design.pose.simulate.carm_sweep`'s motion settings.

    Returns
    -------
    SweepRun
    """
    R, t = carm_sweep(R0, t0, n, **sweep)
    H, W = imaging.image_shape
    bg = None
    if anatomy_strength > 0:
        bg = anatomy(
            (H + 2 * margin_px, W + 2 * margin_px),
            seed=seed,
            pixel_mm=float(np.mean(camera.pixel_size_mm)),
            strength=anatomy_strength,
        )
    o0 = camera.project(t[0])
    raw = np.empty((n, H, W), np.uint16)
    for k in range(n):
        frame_bg = None
        if bg is not None:
            du, dv = np.clip(np.rint(camera.project(t[k]) - o0).astype(int), -margin_px, margin_px)
            frame_bg = bg[margin_px - dv : margin_px - dv + H, margin_px - du : margin_px - du + W]
        rad = render(
            features,
            R[k],
            t[k],
            camera,
            imaging,
            rng=np.random.default_rng(seed * 100003 + k),
            background=frame_bg,
        )
        raw[k] = rad.raw
    return SweepRun(raw, R, t, camera)
