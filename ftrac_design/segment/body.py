"""The acetal body's modelled projection, subtracted before the wires are found again.

The body's silhouette is a √-shaped ramp under the ellipse wires (they sit 0.3 mm inside the
surface); a top-hat keeps part of that ramp under a wire whose profile it cannot separate
from it, and the ridges shift inward — ellipses shrank (~0.3 px at σ = 0.8 px) and the depth
came out 1–2 mm short; nine_bead's depth was biased the same way. With the body's projection
at the best labelling's pose subtracted first (its density scale fitted to the image, so
display images work too) the wire sits on a flat background again, and the balls are
refitted at that pose: the radius it gives them, the image's blur, and the predicted wires
modelled under them (:func:`refit_beads_at_pose`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..features.model import Features
from ..pose import Camera, Pose
from . import identify
from .beads import Beads, fit_beads, fit_patch_half_px
from .detection import Scene
from .image import derivatives, top_hat
from .pixelfit import density_box
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
    if features.body is None or not body_box_ok(camera, R, t, features.body, clip):
        return None
    return density_box(features.subset(set()), camera, R, t, blur_px, margin_px)


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


def wire_profile(
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    shape: tuple[int, int],
    sigma_px: float,
    near_uv: np.ndarray,
    half_px: int,
) -> np.ndarray:
    """(H, W) float of an image of ``shape``: the wires projected at pose (R, t) as lines of
    unit peak blurred by a Gaussian of σ ``sigma_px`` (px), summed over the wires, within
    ``half_px`` of the points ``near_uv`` (n, 2) px and 0 elsewhere. ``sigma_px`` is the line's
    σ: the image's blur with the wire's own chord profile added by the caller (variance D²/16
    for a wire D px across).

    A straight piece is a segment blurred in closed form, ``exp(−d²/2σ²) · ½ [erf(s/√2σ) +
    erf((L − s)/√2σ)]`` (d across it, s along it from one end, L its length): a piece ends
    where it butts against a ball, and a profile round about its last point put half as much
    wire again under that ball's edge (the balls at the lines' ends came out 0.03 px outward
    on clean frames). An ellipse, closed, is the profile about its nearest dense sample."""
    from scipy.spatial import cKDTree
    from scipy.special import erf

    H, W = shape
    out = np.zeros(shape)
    if len(near_uv) == 0:
        return out
    off = np.arange(-half_px, half_px + 1)
    c = np.round(np.asarray(near_uv, float)).astype(int)
    rows = np.clip(c[:, 1, None, None] + off[None, :, None], 0, H - 1)
    cols = np.clip(c[:, 0, None, None] + off[None, None, :], 0, W - 1)
    # each pixel once where patches overlap (marked on the image: a sort of the pixel list
    # cost more than the profile itself)
    marked = np.zeros(shape, bool)
    marked[rows, cols] = True
    pr, pc = np.nonzero(marked)
    q = np.stack([pc, pr], 1).astype(float)
    total = np.zeros(len(q))
    k = math.sqrt(2.0) * sigma_px
    reach = 4.0 * sigma_px + 1.0
    pieces = features.wire_pieces
    if pieces:
        ends = identify.project(camera, R, t, np.concatenate([[a, b] for _, a, b in pieces]))[0].reshape(-1, 2, 2)
        for a, b in ends:
            L = float(np.linalg.norm(b - a))
            if not (np.isfinite(L) and L > 0):
                continue
            d = (b - a) / L
            s = (q - a) @ d
            across = (q - a) @ np.array([-d[1], d[0]])
            on = (np.abs(across) < reach) & (s > -reach) & (s < L + reach)
            s, across = s[on], across[on]
            total[on] += np.exp(-0.5 * (across / sigma_px) ** 2) * 0.5 * (erf(s / k) + erf((L - s) / k))
    for kind, pts in identify.curve_samples(features, camera, R, t).values():
        pts = pts[np.isfinite(pts).all(1)]
        if kind != "ellipse" or len(pts) == 0:
            continue
        dist, _ = cKDTree(pts).query(q, distance_upper_bound=reach)
        near = np.isfinite(dist)
        total[near] += np.exp(-0.5 * (dist[near] / sigma_px) ** 2)
    out[pr, pc] = total
    return out


#: the farthest (px) a refitted ball may lie from its first fit and replace it: a ball beside
#: a wire blurred by 2 px sat 1.4–1.8 px off in its first fit
REFIT_MOVE_PX = 2.0


def pose_ball_radii_px(features: Features, camera: Camera, pose: Pose) -> np.ndarray:
    """Each ball's radius (px) as pose ``pose`` projects it: the focal length (px) × its
    radius (mm) over its depth in the camera frame (mm); (P,), in ``features.points``' order."""
    if not features.points:
        return np.zeros(0)
    Z = features.point_centers() @ pose.rotation[2] + pose.translation_mm[2]
    dia = np.array([p.diameter for p in features.points], float)
    return camera.fx * dia / 2 / Z


def pose_bead_radius_px(features: Features, camera: Camera, pose: Pose) -> float:
    """The balls' mean radius (px) as pose ``pose`` projects them (their diameters at their
    depths); NaN for a design without balls."""
    if not features.points:
        return math.nan
    return float(np.mean(pose_ball_radii_px(features, camera, pose)))


def refit_beads_at_pose(scene: Scene, T: np.ndarray, beads: Beads, pose: Pose) -> Beads:
    """The bead fits again at a known pose, on the image with the body subtracted: each ball
    started at the radius the pose gives it and the image's blur (the median of the first
    fits'), with the wires the pose predicts modelled under it (:func:`wire_profile`, their
    amplitude fitted per ball with the plane) instead of left out.

    Leaving the wires' pixels out left too little of a ball under blur: on 24 images per
    condition of the tuning seed (ftrac_2005; clean, raw, both display frames, fluoroscopy,
    strong anatomy, blur; 1,335 ball fits) the balls so refitted were 0.38 px RMS off (95th
    percentile 0.83) against 0.34 (0.73) for their first fits, worse in every condition but
    the clean one. With the wires modelled: 0.34 (0.69), a ball more than 4σ off 6 % of the
    time against 10 %; clean frames 0.07 → 0.02 px (the balls beside the ellipses had been
    pulled toward them), fluoroscopy and strong anatomy 0.38 → 0.36, raw 0.28 → 0.27, blur and
    display frames 0.01–0.04 px worse than the first fits. Pinning the radius and blur as well
    (priors 1,000× stronger) gave 0.33 px here but tracked fewer over the tuning seed's 780
    images of three presets (ftrac_2005 236 right against 238, one of them confidently wrong;
    ftrac_mini 123 against 128; nine_bead 225 against 228).

    A refit that moved more than :data:`REFIT_MOVE_PX`, shrank below half the radius or came
    out far less certain keeps the first fit."""
    if len(beads) == 0:
        return beads
    sc = scene.scales
    blur = float(np.median(beads.blur))
    radius = pose_bead_radius_px(scene.features, scene.camera, pose)
    if not (math.isfinite(radius) and radius > 0):
        radius = sc.bead_radius_px
    half = fit_patch_half_px(radius, blur)
    profile = wire_profile(
        scene.features,
        scene.camera,
        pose.rotation,
        pose.translation_mm,
        T.shape,
        math.sqrt(max(blur, 0.5) ** 2 + sc.wire_px**2 / 16),
        beads.uv,
        half,
    )
    refit = fit_beads(
        T,
        beads.uv,
        radius,
        blur,
        scene.noise_at(beads.uv),
        beads.response,
        censored=scene.censored,
        background=profile,
    )
    ok = (
        np.isfinite(refit.uv).all(1)
        & (np.linalg.norm(refit.uv - beads.uv, axis=1) < REFIT_MOVE_PX)
        & np.isfinite(refit.sigma_px)
        & (refit.radius > 0.5 * radius)
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
