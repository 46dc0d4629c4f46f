"""Where to look: the fiducial's region on a half-size image, results moved between a crop
and the full image, and whether a view itself limits what any search could confirm."""

from __future__ import annotations

import math

import numpy as np

from ..features.model import Features
from ..pose import Camera, Observation, Pose
from ..pose.observation import CurveObservation
from . import identify
from .beads import Beads, blob_candidates
from .detection import Scales
from .image import noise_map, top_hat
from .options import AcceptanceOptions, FindOptions, TrackResult
from .ridges import RidgePoints


def fiducial_regions(
    gs: np.ndarray,
    features: Features,
    sc: Scales,
    opts: FindOptions,
    valid: np.ndarray | None = None,
    max_regions: int = 3,
    factor: int = 2,
    noise: np.ndarray | None = None,
) -> list[tuple[int, int, int, int]]:
    """Where the fiducial may be, from a density image ``gs`` reduced ``factor`` times
    (readable where ``valid``; its local noise ``noise`` when already measured): up to
    ``max_regions`` full-size boxes ``(row0, row1, col0, col1)``, each
    around a cluster of bead-like blobs no wider than the fiducial and wide enough for its
    whole projection from any of them, the most ball-like cluster first; empty when nothing
    bead-like is found (then the whole image is searched).

    A cluster's weight is the sum of its ``P`` strongest blobs' SNR, each capped at 3 × the
    bead threshold: a frame grabber's burned-in text or a clipped bone edge has blobs of a
    far higher contrast than the balls behind a patient, and must not win on contrast alone.
    The next region is looked for among the blobs outside the boxes taken."""
    if not features.points:
        return []
    rb = sc.bead_radius_px / factor
    disc = int(math.ceil(max(rb, sc.wire_px / factor) + 3 * opts.blur_px / factor + 2))
    T = top_hat(gs, disc)
    nmap = noise if noise is not None else noise_map(gs, max(sc.ridge_sigma_px / factor, 0.8), valid, structure_px=disc)
    if valid is not None:
        T[~valid] = 0.0
    P = len(features.points)
    cand, resp = blob_candidates(T, rb, nmap, 8 * P + 40, opts.bead_min_snr)
    if len(cand) < 3:
        return []
    D = fiducial_extent_px(features, sc, opts.magnification)
    uv = factor * cand + 0.5 * (factor - 1)  # reduced pixel i covers full-size fi … fi + f − 1
    w = np.minimum(resp, 3.0 * opts.bead_min_snr)
    shape = (factor * gs.shape[0], factor * gs.shape[1])
    return cluster_boxes(uv, w, P, D, shape, max_regions, max_share=0.6)


def outline_points(features: Features) -> np.ndarray:
    """The points that span the fiducial (n, 3) mm, frame F: its balls' centres, its wires'
    ends and its ellipses sampled at 16 points."""
    pts = [features.point_centers().reshape(-1, 3)]
    pts += [np.array([ln.start, ln.end]) for ln in features.lines]
    pts += [e.sample(np.linspace(0, 2 * np.pi, 16, endpoint=False)) for e in features.ellipses]
    return np.concatenate(pts)


def fiducial_extent_mm(features: Features) -> float:
    """The fiducial's largest extent (mm, frame F): the greatest distance between two of its
    :func:`outline_points`; 0 for none."""
    X = outline_points(features)
    return float(np.max(np.linalg.norm(X[:, None] - X[None], axis=-1))) if len(X) > 1 else 0.0


def mirror_signal_px(features: Features, camera: Camera, R: np.ndarray, t: np.ndarray) -> float:
    """How far (px) the view at pose (R, t) is from its own mirror image: the fiducial's
    :func:`outline_points` reflected through the plane through their centroid square to the
    line of sight (the ray from the source to the centroid), projected, aligned on the view's
    projection by the least-squares affine map, and the largest distance left.

    Projected along the line of sight (the affine approximation of the cone of rays around
    it) a view and that reflection are the same image, which is why a
    near-mirror labelling (the design's features permuted onto the reflected view) can explain
    a small fiducial's detections as well as the right one; only perspective, growing with the
    fiducial's depth over its distance, sets them apart. 0 for fewer than four points or a
    point not in front of the source."""
    X = outline_points(features) @ np.asarray(R, float).T + np.asarray(t, float)
    if len(X) < 4 or not np.all(X[:, 2] > 0):
        return 0.0
    c = X.mean(0)
    d = c / np.linalg.norm(c)
    M = X - 2 * ((X - c) @ d)[:, None] * d
    if not np.all(M[:, 2] > 0):
        return 0.0
    u, _ = identify.project(camera, np.eye(3), np.zeros(3), X)
    m, _ = identify.project(camera, np.eye(3), np.zeros(3), M)
    A = np.c_[m, np.ones(len(m))]
    coef, *_ = np.linalg.lstsq(A, u, rcond=None)
    return float(np.linalg.norm(A @ coef - u, axis=1).max())


def mirror_distinct(features: Features, camera: Camera, pose: Pose, opts: AcceptanceOptions) -> bool:
    """Whether perspective sets the view at ``pose`` apart from its mirror image: at least
    ``opts.mirror_signal_px`` between them (:func:`mirror_signal_px`; never where that is 0 or
    the pose is not finite). Where it does not, a near-mirror labelling puts the fiducial's
    balls and wires within a fraction of a pixel of where the right one puts them."""
    return (
        opts.mirror_signal_px > 0
        and bool(np.all(np.isfinite(pose.rotation)))
        and bool(np.all(np.isfinite(pose.translation_mm)))
        and mirror_signal_px(features, camera, pose.rotation, pose.translation_mm) >= opts.mirror_signal_px
    )


def balls_needed(features: Features, camera: Camera, pose: Pose, wires_confirm: bool, opts: AcceptanceOptions) -> int:
    """How many balls a confident labelling at ``pose`` must use: ``opts.min_beads`` (at most
    the design's), one fewer (never below four) where wire contours confirm the labelling
    (``wires_confirm``) and the view is set apart from its mirror image
    (:func:`mirror_distinct`), so that no near-mirror labelling can explain its wires."""
    need = min(opts.min_beads, len(features.points))
    if need > 4 and wires_confirm and mirror_distinct(features, camera, pose, opts):
        return need - 1
    return need


def fiducial_extent_px(features: Features, sc: Scales, magnification: float) -> float:
    """The fiducial's largest extent in pixels at a generous magnification (1.25 ×
    ``magnification``): the widest a cluster of its balls can be.

    Parameters
    ----------
    features : the fiducial (balls, wires' ends, ellipses sampled at 16 points).
    sc : the image's scales (``pixel_mm``, mm per pixel).
    magnification : the assumed magnification (``TrackOptions.magnification``).

    Returns
    -------
    float : the extent, pixels.
    """
    return fiducial_extent_mm(features) * magnification * 1.25 / sc.pixel_mm


def cluster_boxes(
    uv: np.ndarray,
    w: np.ndarray,
    P: int,
    D: float,
    shape: tuple[int, int],
    max_regions: int,
    max_share: float | None = None,
) -> list[tuple[int, int, int, int]]:
    """Boxes ``(row0, row1, col0, col1)`` around clusters of ball candidates, the heaviest first.

    A cluster is the candidates within ``D`` of one of them, weighed by its ``P`` heaviest; its
    box is grown by half ``D`` and 8 px and clipped to the image. The candidates inside a box
    taken are not looked at again; at most ``max_regions`` boxes, and none once fewer than three
    candidates are left together.

    Parameters
    ----------
    uv : (n, 2) candidates' positions (u, v), pixels.
    w : (n,) their weights.
    P : the fiducial's balls: how many candidates weigh a cluster.
    D : the widest a cluster may be, pixels (:func:`fiducial_extent_px`).
    shape : the image's (rows, columns).
    max_regions : the most boxes looked for.
    max_share : a box over this share of the image's area is dropped (but its candidates are
        still taken); None: none is.

    Returns
    -------
    list of (row0, row1, col0, col1) : pixel rows and columns, the ends exclusive.
    """
    near = np.linalg.norm(uv[:, None] - uv[None], axis=-1) <= D
    H, W = shape
    alive = np.ones(len(uv), bool)
    boxes: list[tuple[int, int, int, int]] = []
    while len(boxes) < max_regions and alive.sum() >= 3:
        member = near & alive[None, :] & alive[:, None]
        wk = np.where(member, w[None, :], 0.0)
        score = -np.sort(-wk, axis=1)[:, :P].sum(1)
        k = int(np.argmax(score))
        if member[k].sum() < 3:
            break
        cl = uv[member[k]]
        lo = cl.min(0) - 0.5 * D - 8
        hi = cl.max(0) + 0.5 * D + 8
        c0, r0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
        c1, r1 = min(int(math.ceil(hi[0])) + 1, W), min(int(math.ceil(hi[1])) + 1, H)
        inside = (uv[:, 0] >= c0) & (uv[:, 0] < c1) & (uv[:, 1] >= r0) & (uv[:, 1] < r1)
        alive &= ~inside
        alive[k] = False
        if max_share is None or (r1 - r0) * (c1 - c0) <= max_share * H * W:
            boxes.append((r0, r1, c0, c1))
    return boxes


def shifted(res: TrackResult, camera: Camera, du: int, dv: int) -> TrackResult:
    """``res`` found on a crop whose corner is at (du, dv) px, in the full image's pixels
    (``camera`` the full image's)."""
    off = np.array([du, dv], float)
    if res.observation is not None:
        o = res.observation
        res.observation = Observation(
            camera,
            {k: v + off for k, v in o.points.items()},
            {k: CurveObservation(points=c.points + off) for k, c in o.lines.items()},
            {k: CurveObservation(points=c.points + off) for k, c in o.ellipses.items()},
            origin=o.origin,
        )
    if res.beads is not None:
        res.beads = Beads(
            *(
                getattr(res.beads, k) + off if k == "uv" else getattr(res.beads, k)
                for k in res.beads.__dataclass_fields__
            )
        )
    if res.ridges is not None:
        res.ridges = RidgePoints(res.ridges.uv + off, res.ridges.normal, res.ridges.strength, res.ridges.snr)
    return res


def resolvable_beads(features: Features, camera: Camera, pose: Pose, shape: tuple[int, int], sc: Scales) -> int:
    """How many balls a perfect segmentation could use at ``pose``: those projected inside
    the image of ``shape`` (clear of its edge as detection requires, ``sc`` the image's
    expected sizes) and not within the merging distance of another ball (the labelling leaves
    those out). A bound set by the view alone, whatever the noise or the region searched."""
    if not features.points:
        return 0
    uv, _ = identify.project(camera, pose.rotation, pose.translation_mm, features.point_centers())
    H, W = shape
    edge = sc.bead_radius_px + 2 * sc.blur_px + 1
    sep = sc.touching_px
    inside = (
        np.isfinite(uv).all(1)
        & (uv[:, 0] > edge)
        & (uv[:, 1] > edge)
        & (uv[:, 0] < W - 1 - edge)
        & (uv[:, 1] < H - 1 - edge)
    )
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9
    return int((inside & (dd.min(1) >= sep)).sum())


def view_limited(
    res: TrackResult, features: Features, camera: Camera, shape: tuple[int, int], sc: Scales, opts: AcceptanceOptions
) -> bool:
    """Whether a region's unconfirmed answer is limited by the view itself, so that searching
    the whole image (``shape``, seen with ``camera``, its expected sizes ``sc``) again cannot
    confirm it (``opts.min_beads``, as the acceptance tests count them): too few balls
    could be used, and even a perfect segmentation of the whole image at that pose could
    use no more (:func:`resolvable_beads`: the others overlap or leave the image). The
    whole-image retry cost ~200 ms and ended the same way. Any wire contour observed counts as
    confirming (:func:`balls_needed`), which can only ask the whole image for fewer balls."""
    p = res.pose
    obs = res.observation
    if p.converged or obs is None or not np.all(np.isfinite(p.rotation)):
        return False
    need = balls_needed(features, camera, p, bool(obs.lines or obs.ellipses), opts)
    if not str(p.error or "").startswith("too little evidence") or len(obs.points) >= need:
        return False
    n = resolvable_beads(features, camera, p, shape, sc)
    res.diagnostics.beads_resolvable = n
    return n < need
