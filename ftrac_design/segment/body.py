"""The acetal body's modelled projection, subtracted before the wires are found again.

The body's silhouette is a √-shaped ramp under the ellipse wires (they sit 0.3 mm inside the
surface); a top-hat keeps part of that ramp under a wire whose profile it cannot separate
from it, and the ridges shift inward — ellipses shrank (~0.3 px at σ = 0.8 px) and the depth
came out 1–2 mm short; nine_bead's depth was biased the same way. With the body's projection
at the best labelling's pose subtracted first (its density scale fitted to the image, so
display images work too) the wire sits on a flat background again, and the balls are
refitted with the predicted wires' pixels left out.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..features.model import Features
from ..pose import Camera, Pose
from . import identify
from .beads import Beads, fit_beads
from .detection import Scene
from .image import derivatives, top_hat
from .ridges import RidgePoints, ridge_points

#: largest body box rendered, per side, as a multiple of the image's larger side: a
#: labelling whose pose puts the body over more is not modelled (memory stays bounded)
MAX_BOX_SIDE = 2.0


def body_density(
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    blur_px: float,
    margin_px: int = 8,
    clip: tuple[int, int] | None = None,
):
    """The acetal body's modelled density (−ln of its transmission as the detector reads it)
    over its bounding box at pose (R, t): ``(box image, (row0, col0))``; uses the simulator's
    exact hollow-cylinder chords and detector (:func:`ftrac_design.xray.render.detected_deficit`).

    Parameters
    ----------
    features : the design (its body ``features.body`` alone is rendered).
    camera : intrinsics; (R, t) the pose F → X (mm).
    blur_px : Gaussian σ of the image's blur, px (pixel area included).
    clip : (H, W) of the image: the box is cut to it before anything is computed.

    Returns
    -------
    (density (h, w) float64, (row0, col0)), or None when the features have no body, or the pose
    puts it behind the source, outside ``clip`` or wider than :data:`MAX_BOX_SIDE` × its larger side.
    """
    from ..xray import ImagingModel
    from ..xray.render import detected_deficit, line_integral_field

    if features.body is None or not body_box_ok(camera, R, t, features.body, clip):
        return None
    # 3 × 3 sub-samples at the silhouettes: within 1e-3 of the simulator's 5 × 5 there, at a
    # third of the cost
    field = line_integral_field(features.subset(set()), R, t, camera, ImagingModel(supersample=3), margin_px=margin_px)
    # the bead fit's blur includes the pixel's own width (variance 1/12), which the
    # detector's pixel integration adds
    s = math.sqrt(max(blur_px**2 - 1.0 / 12.0, 0.0))
    D = detected_deficit(field, s, s, dtype=np.float64)
    return -np.log(np.maximum(1.0 - D, 1e-12)), field.origin


def body_box_ok(camera: Camera, R: np.ndarray, t: np.ndarray, body, clip: tuple[int, int] | None) -> bool:
    """Whether the body's projection at pose (R, t) is in front of the source, meets the
    image (``clip`` = (H, W), if given; else a 1024² one) and is at most
    :data:`MAX_BOX_SIDE` × the image's larger side across."""
    ro, h = body.outer_diameter / 2, body.length / 2
    corners = np.array([[x, y, z] for x in (-ro, ro) for y in (-ro, ro) for z in (-h, h)])
    X = corners @ np.asarray(R, float).T + np.asarray(t, float)
    if not np.all(np.isfinite(X)) or np.any(X[:, 2] <= 1.0):
        return False
    uv = camera.project(X)
    lo, hi = uv.min(0), uv.max(0)
    H, W = clip if clip is not None else (1024, 1024)
    if float(np.max(hi - lo)) > MAX_BOX_SIDE * max(H, W):
        return False
    return not (hi[0] < 0 or hi[1] < 0 or lo[0] > W - 1 or lo[1] > H - 1)


def wire_mask(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, shape: tuple[int, int], half_px: float
) -> np.ndarray:
    """(H, W) bool of an image of ``shape``: True within ``half_px`` of a wire (line piece or
    ellipse) projected at pose (R, t) — the pixels a ball's fit leaves out."""
    mask = np.zeros(shape, np.uint8)
    for kind, pts in identify.curve_samples(features, camera, R, t).values():
        p = np.round(pts[np.isfinite(pts).all(1)]).astype(np.int32)
        if len(p) > 1:
            cv2.polylines(mask, [p.reshape(-1, 1, 2)], kind == "ellipse", 1, thickness=max(1, int(round(2 * half_px))))
    return mask.astype(bool)


def refit_beads_off_wires(scene: Scene, T: np.ndarray, beads: Beads, pose: Pose) -> Beads:
    """The bead fits again with the pixels of the pose's predicted wires left out (a
    wire passing under a ball biases its centre; two crossing there, by ~0.4 px)."""
    if len(beads) == 0:
        return beads
    sc = scene.scales
    mask = wire_mask(
        scene.features,
        scene.camera,
        pose.rotation,
        pose.translation_mm,
        T.shape,
        0.5 * sc.wire_px + 1.5 * float(np.median(beads.blur)),
    )
    refit = fit_beads(
        T,
        beads.uv,
        sc.bead_radius_px,
        float(np.median(beads.blur)),
        scene.noise_at(beads.uv),
        beads.response,
        exclude=mask,
        censored=scene.censored,
    )
    # keep the first fit where the mask left too little of a ball to fit (its centre then
    # comes out far less certain: a 1 mm ball's patch is mostly wire mask, σ 1.5–3 px)
    ok = (
        np.isfinite(refit.uv).all(1)
        & (np.linalg.norm(refit.uv - beads.uv, axis=1) < 1.0)
        & np.isfinite(refit.sigma_px)
        & (refit.radius > 0.5 * sc.bead_radius_px)
        & ((refit.sigma_px <= 0.5) | (refit.sigma_px <= 3.0 * beads.sigma_px))
    )
    return Beads(
        *(
            np.where(ok[:, None] if getattr(beads, k).ndim == 2 else ok, getattr(refit, k), getattr(beads, k))
            for k in beads.__dataclass_fields__
        )
    )


def ridges_without_body(
    g: np.ndarray, scene: Scene, pose: Pose, blur: float, ridge_min_snr: float | None
) -> Scene | None:
    """The scene over the body's box again after subtracting the modelled projection of the body
    (``scene.features.body``) at ``pose`` from the density image ``g``: the background-free
    image and its second derivatives with that box replaced, and the ridge points found there
    (those of the box only, at least ``ridge_min_snr`` noise units; none looked for when it is
    None); None when there is no body or it cannot be modelled there."""
    bd = body_density(scene.features, scene.camera, pose.rotation, pose.translation_mm, blur, clip=g.shape)
    if bd is None:
        return None
    B, (v0, u0) = bd
    T, sc = scene.T, scene.scales
    H, W = g.shape
    r0, r1 = max(v0, 0), min(v0 + B.shape[0], H)
    c0, c1 = max(u0, 0), min(u0 + B.shape[1], W)
    if r1 - r0 < 8 or c1 - c0 < 8:
        return None
    box = (slice(r0, r1), slice(c0, c1))
    gb = g[box].astype(np.float64)
    Bb = B[r0 - v0 : r1 - v0, c0 - u0 : c1 - u0]
    quiet = T[box] < 3 * scene.noise_map[box]  # not a wire or a bead
    if scene.valid is not None:
        quiet &= scene.valid[box]
    if quiet.sum() < 50 or np.ptp(Bb[quiet]) <= 0:
        return None
    # the least-squares line g ≈ scale · B + offset over the quiet pixels, in closed form (an
    # SVD of the (n, 2) design matrix took ~1 ms a run's frame for the same two numbers)
    bq, gq = Bb[quiet], gb[quiet]
    bc = bq - bq.mean()
    scale = float(bc @ (gq - gq.mean())) / float(bc @ bc)
    if not scale > 0:
        return None
    T2 = top_hat((gb - scale * Bb).astype(np.float32), sc.disc_px)
    if scene.valid is not None:
        T2[~scene.valid[box]] = 0.0
    wanted = ridge_min_snr is not None and bool(scene.features.lines or scene.features.ellipses)
    # a run's frame keeps no derivatives and looks for no ridges here: none taken for it
    d = derivatives(T2, sc.ridge_sigma_px) if wanted or scene.derivs is not None else None
    rp = None
    if wanted:
        rp = ridge_points(T2, sc.ridge_sigma_px, scene.noise_map[box], ridge_min_snr, derivs=d)
        rp.uv = rp.uv + np.array([c0, r0], float)
        rp = rp.take(scene.readable(rp.uv))
    Tb = T.copy()
    Tb[box] = T2
    derivs = None
    if scene.derivs is not None:
        derivs = {k: v.copy() for k, v in scene.derivs.items()}
        for k, v in derivs.items():
            v[box] = d[k]
    return scene.with_detections(Tb, scene.beads, rp, derivs)


def merge_ridges(ridges: RidgePoints | None, inner: RidgePoints | None) -> RidgePoints | None:
    """``inner`` (found over the body's box) with the ridge points of ``ridges`` outside that box."""
    if ridges is None or inner is None or not len(inner):
        return None
    lo, hi = inner.uv.min(0) - 1, inner.uv.max(0) + 1
    outside = ~((ridges.uv >= lo) & (ridges.uv <= hi)).all(1)
    return RidgePoints(
        np.concatenate([ridges.uv[outside], inner.uv]),
        np.concatenate([ridges.normal[outside], inner.normal]),
        np.concatenate([ridges.strength[outside], inner.strength]),
        np.concatenate([ridges.snr[outside], inner.snr]),
    )
