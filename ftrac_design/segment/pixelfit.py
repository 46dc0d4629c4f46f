"""Two poses compared on the image's pixels: the fiducial's steel rendered at each, fitted to
the background-free density, and the fits' difference in noise units.

The labellings' misfit compares detections — blobs and ridge points the detectors found, or
missed. Where two labellings explain those equally well (a near-mirror of a small design,
both fitting the few features that were read), the image still holds what the detectors did
not pass on: each ball's exact disc and every pixel of each wire, at the place and depth each
pose puts them. The model that is fitted here is the simulator's own projection of the steel
(:func:`ftrac_design.xray.render.line_integral_field`, blurred as the image is), with a free
density scale and offset (display processing scales the density by an unknown factor), so
the comparison is a likelihood ratio on the pixels rather than on features.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..features.model import Features
from ..pose import Camera, Pose
from .detection import Scene

#: the template's pixels compared: where either pose's steel reads at least this fraction of
#: the denser one's peak, widened by :data:`WINDOW_GROW_PX`
WINDOW_FRACTION = 0.02
WINDOW_GROW_PX = 2
#: a box wider than this multiple of the image's larger side is not rendered (memory bounded)
MAX_BOX_SIDE = 2.0
#: two poses whose fitted steel differs by less than this fraction of the first's own weight
#: (both in noise units²) draw the same image — a design's symmetry, or two refinements of one
#: pose — and the pixels have no word (``z`` = 0): an evenly spaced helix's two-fold twins
#: differed by 0.0002 after refinement, the right and wrong poses of the tuning seeds' ties by
#: 0.149 or more
DISTINCT_FRACTION = 0.05


def density_box(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, blur_px: float, margin_px: int
) -> tuple[np.ndarray, tuple[int, int]]:
    """What ``features`` (steel and body as given) at pose (R, t) add to the image's density:
    −ln of the transmission the detector reads, blurred by ``blur_px`` (px, the pixel's own
    width included, as the ball fits measure it), over their bounding box widened by
    ``margin_px``: ``(box (h, w) float64, (row0, col0))``; uses the simulator's exact chords and
    detector (:func:`ftrac_design.xray.render.detected_deficit`). The box may be empty and is
    not cut to any image."""
    from ..xray import ImagingModel
    from ..xray.render import detected_deficit, line_integral_field

    # 3 × 3 sub-samples at the silhouettes: within 1e-3 of the simulator's 5 × 5 there, at a
    # third of the cost
    field = line_integral_field(features, R, t, camera, ImagingModel(supersample=3), margin_px=margin_px)
    if field.p.size == 0:
        return field.p, field.origin
    # the ball fits' blur includes the pixel's own width (variance 1/12), which the
    # detector's pixel integration adds again
    s = math.sqrt(max(blur_px**2 - 1.0 / 12.0, 0.0))
    D = detected_deficit(field, s, s, dtype=np.float64)
    return -np.log(np.maximum(1.0 - D, 1e-12)), field.origin


def steel_density(scene: Scene, R: np.ndarray, t: np.ndarray, features: Features | None = None) -> np.ndarray | None:
    """The design's steel (balls and wires of ``features``, by default the scene's; not the
    body) at pose (R, t) as the image's density would show it (:func:`density_box` at the
    scene's blur, :attr:`.detection.Scales.blur_px`), over the scene's pixels (H, W); None when
    the pose puts the steel behind the source, off the image or wider than
    :data:`MAX_BOX_SIDE` × the image, or its rendering is not finite."""
    R, t = np.asarray(R, float), np.asarray(t, float)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))) or t[2] <= 1.0:
        return None
    H, W = scene.shape
    steel = replace(scene.features if features is None else features, body=None)
    box, (v0, u0) = density_box(steel, scene.camera, R, t, scene.scales.blur_px, margin_px=6)
    h, w = box.shape
    if h == 0 or w == 0 or max(h, w) > MAX_BOX_SIDE * max(H, W) or not np.all(np.isfinite(box)):
        # a pose whose steel is not finite everywhere is not compared: least squares on it
        # fails (a ray along a wire's axis once drew NaN for a ftrac_mini near-mirror)
        return None
    a0, b0, a1, b1 = max(v0, 0), max(u0, 0), min(v0 + h, H), min(u0 + w, W)
    if a1 <= a0 or b1 <= b0:
        return None
    out = np.zeros((H, W))
    out[a0:a1, b0:b1] = box[a0 - v0 : a1 - v0, b0 - u0 : b1 - u0]
    return out


@dataclass(frozen=True)
class PixelComparison:
    """Which of two poses the image's pixels prefer (:func:`compare`)."""

    #: weighted residual sum of squares of the second pose's fit minus the first's (noise
    #: units²): positive where the first explains the pixels better
    d_rss: float
    #: what that difference would be, noise-free, were the first pose right (its fitted
    #: steel against the second's): the comparison's strength
    separation: float
    #: ``d_rss`` over its spread under white noise were the first right (2 √separation):
    #: several units where the first explains the pixels clearly better; 0 where the two
    #: poses draw the same image (:data:`DISTINCT_FRACTION`)
    z: float
    #: the fitted density scale of each pose's steel
    scale_first: float
    scale_second: float
    #: pixels compared
    pixels: int


def _fit(y: np.ndarray, w: np.ndarray, x: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted least squares y ≈ a x + b: (residual sum of squares, (a, b))."""
    A = np.stack([x, np.ones_like(x)], 1)
    Aw = A * w[:, None]
    coef = np.linalg.lstsq(Aw.T @ A, Aw.T @ y, rcond=None)[0]
    r = y - A @ coef
    return float(np.sum(w * r * r)), coef


def compare(scene: Scene, first: Pose, seconds: list[Pose]) -> list[PixelComparison | None]:
    """The likelihood ratio of ``first`` against each of ``seconds`` on the scene's pixels: each
    pose's steel (:func:`steel_density`, ``first``'s rendered once) fitted, with a free scale
    and offset, to the background-free density ``scene.T`` weighted by its local noise, over
    the pixels either pose's steel covers (not those hidden, clipped or outside the readable
    field). None for a pair where either pose's steel cannot be rendered or nothing is left to
    compare.

    Under white noise of the mapped σ, ``d_rss`` is the log-likelihood ratio × 2: with the
    first pose right it is spread about ``separation`` by 2 √separation. The image's noise is
    not white (anatomy, display filters), so ``z`` is read as a ranking with a margin, not as
    a probability."""
    tA = steel_density(scene, first.rotation, first.translation_mm)
    if tA is None:
        return [None] * len(seconds)
    wgt = 1.0 / np.maximum(scene.noise_map, 1e-12) ** 2
    readable = np.ones(scene.shape, bool)
    for mask, keep in ((scene.valid, True), (scene.hidden, False), (scene.censored, False)):
        if mask is not None:
            readable &= mask if keep else ~mask
    return [_pair(scene.T, wgt, readable, tA, steel_density(scene, q.rotation, q.translation_mm)) for q in seconds]


def _pair(T: np.ndarray, wgt: np.ndarray, readable: np.ndarray, tA: np.ndarray, tB: np.ndarray | None):
    """:class:`PixelComparison` of two rendered steels ``tA``, ``tB`` on the density ``T``."""
    if tB is None:
        return None
    peak = max(float(tA.max()), float(tB.max()))
    if not peak > 0:
        return None
    M = (tA > WINDOW_FRACTION * peak) | (tB > WINDOW_FRACTION * peak)
    k = 2 * WINDOW_GROW_PX + 1
    M = cv2.dilate(M.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool) & readable
    if M.sum() < 10:
        return None
    y, w, a, b = T[M], wgt[M], tA[M], tB[M]
    rA, cA = _fit(y, w, a)
    rB, cB = _fit(y, w, b)
    sep = float(np.sum(w * (cA[0] * (a - b)) ** 2))
    weight = float(np.sum(w * (cA[0] * a) ** 2))
    d = rB - rA
    z = d / (2.0 * math.sqrt(sep)) if sep > DISTINCT_FRACTION * weight else 0.0
    return PixelComparison(d, sep, z, float(cA[0]), float(cB[0]), int(M.sum()))
