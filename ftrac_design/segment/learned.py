"""The learned detector in the image path: run once per image, it says where the fiducial is, in
which polarity its balls stand out, and which blobs are balls (:mod:`ftrac_design.detector`).

Its answers replace three classical guesses — the half-size search for regions, the polarity
test and the blob detector's candidates — and nothing else: each candidate is still fitted with
the blurred-sphere model, and the labelling, the pose, the acceptance tests and the covariance
are the geometric back end's as before. A detection is evidence, never a pose.
"""

from __future__ import annotations

import math

import numpy as np

from .. import detector as learned
from ..features.model import Features
from .detection import LEARNED_BALL, Scales
from .options import FindOptions
from .region import cluster_boxes, fiducial_extent_px

Boxes = list[tuple[int, int, int, int]]


def detections(image: np.ndarray, sc: Scales, opts: FindOptions) -> learned.Detections | None:
    """The learned detector's detections in ``image`` (H, W) as stored, or None when the
    classical detectors are to be used (``TrackOptions.detector`` "classical", or "auto"
    without ONNX Runtime or the network). "learned" without them raises
    :class:`~ftrac_design.errors.MissingDependencyError`."""
    if opts.detector == "classical" or (opts.detector == "auto" and not learned.available()):
        return None
    net = learned.load_detector(threads=opts.detector_threads)
    return net.detect(image, sc.bead_radius_px, max_beads=opts.detector_candidates)


def polarity_order(image: np.ndarray, det: learned.Detections, sc: Scales, balls: int) -> list[str] | None:
    """The polarities to try, the balls' own first: at the ``balls`` most probable candidates,
    whether the image is darker in a disc of the ball's radius than in the ring 2–3 radii
    around it (dense-dark) or brighter (dense-bright), each candidate's vote weighted by its
    probability. None with fewer than three candidates of probability ½ (no opinion)."""
    keep = det.beads_score >= LEARNED_BALL
    uv, w = det.beads_uv[keep][:balls], det.beads_score[keep][:balls]
    if len(uv) < 3:
        return None
    r = max(sc.bead_radius_px, 1.0)
    R = int(math.ceil(3 * r)) + 1
    off = np.arange(-R, R + 1)
    oy, ox = np.meshgrid(off, off, indexing="ij")
    rho = np.hypot(ox, oy)
    disc, ring = rho <= r, (rho >= 2 * r) & (rho <= 3 * r)
    H, W = image.shape
    vote = 0.0
    for (u, v), wk in zip(uv, w):
        iu, iv = int(round(u)), int(round(v))
        if not (R <= iu < W - R and R <= iv < H - R):
            continue
        patch = np.asarray(image[iv - R : iv + R + 1, iu - R : iu + R + 1], float)
        vote += wk * float(np.sign(patch[ring].mean() - patch[disc].mean()))
    first = "dense-dark" if vote > 0 else "dense-bright"
    return [first, "dense-bright" if first == "dense-dark" else "dense-dark"]


def regions(
    det: learned.Detections,
    features: Features,
    sc: Scales,
    shape: tuple[int, int],
    magnification: float,
    max_regions: int,
) -> Boxes:
    """Boxes ``(row0, row1, col0, col1)`` around clusters of the learned ball candidates (those
    of probability ≥ 0.2), each no wider than the fiducial can be and grown by half its
    largest extent, the most probable cluster first (the sum of its ``P`` best probabilities),
    at most ``max_regions``; the next among the candidates outside the boxes taken
    (``magnification`` the assumed one, see :func:`.region.fiducial_extent_px`)."""
    P = len(features.points)
    keep = det.beads_score >= 0.2
    uv, w = det.beads_uv[keep], det.beads_score[keep]
    if P == 0 or len(uv) < 3:
        return []
    return cluster_boxes(uv, w, P, fiducial_extent_px(features, sc, magnification), shape, max_regions)
