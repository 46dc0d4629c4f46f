"""One frame of a run tracked from a predicted pose: measured only where the model projects,
solved from the prediction, and given out only when the full path's tests pass.

:func:`~ftrac_design.segment.track_image` finds the fiducial with no prior: regions on a half-size image, every
bead labelling that the blobs allow, rival labellings refuted. Within a run the previous
frames say where the fiducial is and which ball is which, so :func:`track_near` does only
what confirms that:

1. the model is projected at the predicted pose and the frame cropped to its bounding box
   and a margin (the top-hat's disc, the derivative filters' reach and the search radius);
   the noise is measured on that box grown to whole tiles of the noise map's clutter term,
   so that the crop's noise is the whole frame's;
2. the crop is conditioned with the run's polarity and formation (:class:`RunContext`),
   its invalid regions found against the whole frame's clip levels, and its local noise
   read from the run's noise level function (:func:`.image.noise_levels`), with the
   clutter term measured on the crop;
3. each ball is looked for as the strongest blob within ``search_px`` of its projection
   (a search beyond the matching tolerance first moves the prediction by the image shift
   that lays the most balls on blobs, :func:`shift_votes`, and looks within
   :data:`VOTE_TOLERANCE` of that) and fitted there with the blurred-sphere model
   (:func:`.detection.ball_fits`); the
   wires' contour points are measured along the projected curves' normals
   (:mod:`.guided`), exactly as the full path measures them for a labelling;
4. the labelling's stages and per-feature tests (:func:`.labelling.evaluate`) run from the
   predicted pose, then the full path's acceptance tests (wire support, evidence; there is
   no rival labelling to refute — the labels come from the prediction);
5. the pose is refused unless the balls it projects lie within the stage-one matching
   tolerance of the predicted ones (RMS): a solution that had to move farther than the
   labels were matched over did not confirm the prediction.

A refused frame is for the caller to identify from scratch (:func:`track_image`); this
module never returns a pose that failed a test.

**What a run shares** (:class:`RunContext`, from a frame the full path tracked): the
polarity and formation (properties of the imaging chain and the file, not of the view),
the fitted blur (the focal spot and detector; the filters are sized for it) and the noise
level function at the ridge scale (quantum noise against background level, set by the
dose and the chain). A change in any of them shows in the tests — a polarity or formation
no longer right leaves no ball or wire to fit, a wrong noise level moves the per-feature
χ² and the wire evidence — and the caller renews the context at its next full
identification.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..features.model import Features
from ..pose import Camera, Diagnostics, Pose, so3
from ..segment import identify
from ..segment.acceptance import refuse
from ..segment.beads import blob_candidates, blob_response
from ..segment.body import ridges_without_body, wire_mask
from ..segment.conditioning import condition
from ..segment.detection import Scene, ball_fits, scales
from ..segment.image import CLUTTER_TILE_PX, NoiseField, NoiseLevels, derivatives, noise_levels, top_hat
from ..segment.labelling import NoLabelling, evaluate
from ..segment.options import FindOptions, TrackOptions, TrackResult, failed_result
from ..segment.pipeline import accept_best, feature_quality
from ..segment.region import shifted
from ..segment.ridges import RidgePoints
from ..threads import one_blas_thread


@dataclass(frozen=True)
class RunContext:
    """What the frames of one run share (see the module), found on a tracked frame.

    Attributes
    ----------
    polarity : "dense-dark" or "dense-bright".
    formation : "linear", "log" or "display" (as the frame was conditioned).
    blur_px : the blur σ the filters are sized for (px).
    ridge_sigma_px : the ridge scale at that blur (px): the scale of ``noise``.
    noise : the noise level function at ``ridge_sigma_px``, or None (then measured on each crop).
    ball_blur_px : the median blur σ the balls were fitted with (px; the pixel's own width
        included): the body's model and the wire mask are blurred by it.
    """

    polarity: str
    formation: str
    blur_px: float
    ridge_sigma_px: float
    noise: NoiseLevels | None
    ball_blur_px: float


def run_context(
    image: np.ndarray, result: TrackResult, features: Features, camera: Camera, options: TrackOptions | None = None
) -> RunContext | None:
    """The :class:`RunContext` of a frame that :func:`~.pipeline.track_image` tracked.

    Parameters
    ----------
    image : (H, W) the frame's pixels as tracked.
    result : its converged result (polarity, formation and blur in its diagnostics).
    features, camera, options : what it was tracked with.

    Returns
    -------
    RunContext, or None when ``result`` has no converged pose.
    """
    if not result.pose.converged or result.polarity not in ("dense-dark", "dense-bright"):
        return None
    find = (options or TrackOptions()).finding
    form = result.diagnostics.formation or "linear"
    blur = float(result.diagnostics.blur_px if result.diagnostics.blur_px is not None else find.blur_px)
    sc0 = scales(features, camera, find)
    sc = scales(features, camera, replace(find, blur_px=blur))
    levels = result.noise_levels
    if levels is None:
        # a result that does not carry its image's noise level function: measured again
        cond = condition(np.asarray(image, np.float32), result.polarity, form, sc0.disc_px)
        form = cond.formation
        levels = noise_levels(cond.density, sc.ridge_sigma_px, cond.valid, structure_px=sc0.disc_px)
    fitted = [q["blur_px"] for q in result.quality.get("points", {}).values() if math.isfinite(q["blur_px"])]
    ball_blur = float(np.median(fitted)) if fitted else blur
    return RunContext(result.polarity, form, blur, sc.ridge_sigma_px, levels, ball_blur)


def predicted_box(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, shape: tuple[int, int], margin_px: float
) -> tuple[int, int, int, int] | None:
    """The box ``(row0, row1, col0, col1)`` holding the fiducial's projection at pose (R, t)
    (balls and wires) and ``margin_px`` around it, clipped to an image of ``shape``; None
    when the projection is not finite or its box misses the image."""
    parts = [identify.project(camera, R, t, features.point_centers())[0]] if features.points else []
    parts += [p for _, p in identify.curve_samples(features, camera, R, t, step_px=4.0).values()]
    if not parts:
        return None
    uv = np.concatenate(parts)
    if not np.isfinite(uv).all():
        return None
    H, W = shape
    lo, hi = uv.min(0) - margin_px, uv.max(0) + margin_px
    c0, r0 = max(int(math.floor(lo[0])), 0), max(int(math.floor(lo[1])), 0)
    c1, r1 = min(int(math.ceil(hi[0])) + 1, W), min(int(math.ceil(hi[1])) + 1, H)
    if c1 - c0 < 16 or r1 - r0 < 16:
        return None
    return r0, r1, c0, c1


def _on_tiles(box: tuple[int, int, int, int], shape: tuple[int, int], tile: int) -> tuple[int, int, int, int]:
    """``box`` (row0, row1, col0, col1) grown outward to whole tiles of ``tile`` px counted
    from the image's corner (clipped to an image of ``shape``)."""
    r0, r1, c0, c1 = box
    H, W = shape
    return r0 // tile * tile, min(-(-r1 // tile) * tile, H), c0 // tile * tile, min(-(-c1 // tile) * tile, W)


def _clip_levels(img: np.ndarray) -> tuple[float, float]:
    """The lowest and highest pixel value of a frame (one pass through OpenCV where it can)."""
    if (
        img.dtype in (np.uint8, np.uint16, np.int16, np.float32, np.float64)
        and img.ndim == 2
        and img.flags.c_contiguous
    ):
        lo, hi, _, _ = cv2.minMaxLoc(img)
        return float(lo), float(hi)
    return float(img.min()), float(img.max())


def _balls_near(
    T: np.ndarray, snr: np.ndarray, xx: np.ndarray, yy: np.ndarray, uv: np.ndarray, search_px: float, min_snr: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per predicted ball centre ``uv`` (n, 2), the strongest blob-like pixel (both Hessian
    eigenvalues of the blob filter negative) within ``search_px``, when its response is at
    least ``min_snr`` noise units: the starts (m, 2) and their responses (m,)."""
    H, W = T.shape
    r = int(math.ceil(search_px))
    off = np.arange(-r, r + 1)
    oy, ox = np.meshgrid(off, off, indexing="ij")
    disc = ox**2 + oy**2 <= search_px * search_px
    ox, oy = ox[disc], oy[disc]
    c = np.rint(uv).astype(int)
    ok = np.isfinite(uv).all(1) & (c[:, 0] >= 0) & (c[:, 1] >= 0) & (c[:, 0] < W) & (c[:, 1] < H)
    c = c[ok]
    px = np.clip(c[:, 0:1] + ox[None], 0, W - 1)
    py = np.clip(c[:, 1:2] + oy[None], 0, H - 1)
    v = np.where((xx[py, px] < 0) & (yy[py, px] < 0), snr[py, px], -np.inf)
    k = np.argmax(v, axis=1)
    best = v[np.arange(len(c)), k]
    keep = best >= min_snr
    starts = np.stack([px[np.arange(len(c)), k], py[np.arange(len(c)), k]], -1).astype(float)
    return starts[keep], best[keep]


def _balls(
    T: np.ndarray,
    nmap: np.ndarray,
    features: Features,
    camera: Camera,
    min_snr: float,
    sc,
    R: np.ndarray,
    t: np.ndarray,
    search_px: float,
    ball_blur_px: float,
    censored: np.ndarray | None = None,
):
    """The balls near their projections at pose (R, t) (see :func:`scene_near`; a start's blob
    response at least ``min_snr`` noise units; ``censored`` as for :func:`.detection.ball_fits`)
    and the blob detector's response over its noise (H, W)."""
    resp, xx, yy, nr = blob_response(T, sc.bead_radius_px, nmap, sc.blob_sigma_px)
    snr = (resp / nr).astype(np.float32)
    uv, _ = identify.project(camera, R, t, features.point_centers())
    starts, val = _balls_near(T, snr, xx, yy, uv, search_px, min_snr)
    mask = (
        wire_mask(features, camera, R, t, T.shape, 0.5 * sc.wire_px + 1.5 * ball_blur_px)
        if features.lines or features.ellipses
        else None
    )
    b, ok = ball_fits(T, starts, val, sc.bead_radius_px, nmap, sc.blur_px, exclude=mask, censored=censored)
    weak = ~ok | ~(b.sigma_px <= 0.5)
    if mask is not None and weak.any():
        # the masked fit is kept unless the mask left too little of the ball (its centre far
        # less certain than the plain fit's, or more than a pixel from it)
        plain, ok2 = ball_fits(T, starts[weak], val[weak], sc.bead_radius_px, nmap, sc.blur_px, censored=censored)
        mw = b.take(weak)
        with np.errstate(invalid="ignore"):
            keep_masked = (
                ok[weak]
                & (np.linalg.norm(mw.uv - plain.uv, axis=1) < 1.0)
                & ((mw.sigma_px <= 0.5) | (mw.sigma_px <= 3.0 * plain.sigma_px))
            )
        idx = np.flatnonzero(weak)
        for k in b.__dataclass_fields__:
            getattr(b, k)[idx[~keep_masked]] = getattr(plain, k)[~keep_masked]
        ok[idx] = np.where(keep_masked, ok[idx], ok2)
    b = b.take(ok)
    if len(b) > 1:
        # one fit per blob: two predictions that found the same blob keep it once
        _, first = np.unique(np.round(b.uv, 1), axis=0, return_index=True)
        b = b.take(np.sort(first))
    return b, snr


def scene_near(
    g: np.ndarray,
    features: Features,
    camera: Camera,
    opts: FindOptions,
    R: np.ndarray,
    t: np.ndarray,
    search_px: float,
    valid: np.ndarray | None,
    noise: NoiseField,
    ball_blur_px: float | None = None,
    diag: Diagnostics | None = None,
    hidden: np.ndarray | None = None,
    censored: np.ndarray | None = None,
) -> Scene:
    """A :class:`.detection.Scene` of the density crop ``g`` (seen with ``camera``) measured
    only where pose (R, t) puts the fiducial (see the module).

    The body's modelled projection at (R, t) is subtracted first (``features.body``; :mod:`.body`),
    then each ball is fitted once, starting at the strongest blob within ``search_px`` of
    its projection, with the predicted wires' pixels left out (a ball the mask leaves too
    little of is fitted without it): the pose is predicted, not solved, and a wire modelled
    where it is predicted would pull the ball as far as the prediction is off (the full path
    models them at a solved pose: :func:`.body.refit_beads_at_pose`). No whole-crop ridge
    search is made (``ridges`` is empty): the contours are measured along the predicted
    curves (:mod:`.guided`).

    Parameters
    ----------
    g : (H, W) density crop (dense = bright); ``valid`` where it can be read; ``noise`` its noise.
    features, camera : the design and the crop's intrinsics.
    opts : what finding the features reads (sizes, blur, the balls' SNR threshold).
    R, t : the predicted pose F → X.
    search_px : how far from its projection a ball is looked for (px).
    ball_blur_px : the balls' fitted blur σ (px) the body and the wire mask are blurred with
        (default ``opts.blur_px``).
    diag : diagnostics that get ``body_subtracted`` when the body was subtracted.
    hidden : (H, W) bool, True where a pixel of the crop shows nothing (:attr:`.detection.Scene.hidden`).
    censored : (H, W) bool, True where a pixel of the crop is clipped on the dense side
        (:attr:`.detection.Scene.censored`).

    Returns
    -------
    Scene
    """
    sc = scales(features, camera, opts)
    blur = opts.blur_px if ball_blur_px is None else float(ball_blur_px)
    T = top_hat(g, sc.disc_px)
    nmap = noise.at(sc.ridge_sigma_px)
    if valid is not None:
        T[~valid] = 0.0
    empty = np.zeros((0, 2))
    ridges = RidgePoints(empty, empty, np.zeros(0), np.zeros(0))
    scene = Scene(features, camera, sc, T, nmap, None, ridges, valid, None, None, hidden=hidden, censored=censored)
    if features.body is not None:
        inner = ridges_without_body(g, scene, Pose(R, t, False, math.nan, None, {}, 0), blur, None)
        if inner is not None:
            T = inner.T
            if diag is not None:
                diag.body_subtracted = True
    beads, snr = (
        _balls(T, nmap, features, camera, opts.bead_min_snr, sc, R, t, search_px, blur, censored)
        if features.points
        else (None, None)
    )
    d = derivatives(T, sc.ridge_sigma_px)
    return Scene(features, camera, sc, T, nmap, beads, ridges, valid, d, snr, hidden=hidden, censored=censored)


#: how far (in matching tolerances) a ball may lie from its projection after the image shift a
#: wide search voted for: the rest of a frame-to-frame move (a swing's turn and tilt change
#: the fiducial's image by a few pixels besides moving it)
VOTE_TOLERANCE = 2.5


def shift_votes(proj: np.ndarray, peaks: np.ndarray, radius_px: float, tol_px: float) -> tuple[np.ndarray, int]:
    """The image shift (2,) px within ``radius_px`` that puts the most projected balls ``proj``
    (n, 2) within ``tol_px`` of a blob ``peaks`` (m, 2), and how many it puts there.

    Every (ball, blob) pair proposes the shift that lays the ball on the blob; the proposal
    that lays the most balls on blobs wins (fewer: the smaller sum of squared distances), and
    the shift is then the median of its supporting balls' offsets. A pattern of balls of
    unequal spacing (4, 3 and 2 on three lines) lies on itself under one shift only, so clutter
    blobs and missing balls leave the vote with the true shift. (0, 0) and 0 with no proposal."""
    if not len(proj) or not len(peaks):
        return np.zeros(2), 0
    cand = (peaks[None] - proj[:, None]).reshape(-1, 2)
    cand = cand[np.hypot(cand[:, 0], cand[:, 1]) <= radius_px]
    if not len(cand):
        return np.zeros(2), 0
    moved = proj[None] + cand[:, None]  # (c, n, 2)
    d2 = ((moved[:, :, None] - peaks[None, None]) ** 2).sum(-1).min(-1)  # (c, n)
    hit = d2 <= tol_px * tol_px
    count = hit.sum(1)
    cost = np.where(hit, d2, 0.0).sum(1)
    best = int(np.lexsort((cost, -count))[0])
    n = int(count[best])
    nearest = ((moved[best][:, None] - peaks[None]) ** 2).sum(-1).argmin(1)
    off = peaks[nearest] - proj
    return np.median(off[hit[best]], axis=0), n


def _voted_pose(
    crop: "_Crop", features: Features, sc, min_snr: float, R: np.ndarray, t: np.ndarray, radius_px: float, tol_px: float
) -> tuple[np.ndarray, np.ndarray]:
    """The pose (R, t) moved across the view by the image shift the crop's blobs vote for
    (:func:`shift_votes`), applied at the balls' median depth (mm, camera frame X); (R, t)
    unchanged where fewer than three balls agree with any shift. Between two frames a C-arm
    mostly moves the fiducial's image across the view: one shift puts every ball back near
    its blob, and the labelling's stages take it from there."""
    if not features.points:
        return R, t
    T = top_hat(crop.density, sc.disc_px)
    if crop.valid is not None:
        T[~crop.valid] = 0.0
    nmap = crop.noise.at(sc.ridge_sigma_px)
    limit = 6 * len(features.points)
    peaks, _ = blob_candidates(T, sc.bead_radius_px, nmap, limit, min_snr=min_snr, sigma_px=sc.blob_sigma_px)
    proj, Z = identify.project(crop.camera, R, t, features.point_centers())
    (du, dv), n = shift_votes(proj, peaks, radius_px, tol_px)
    if n < 3:
        return R, t
    z = float(np.median(Z))
    return R, t + np.array([du * z / crop.camera.fx, dv * z / crop.camera.fy, 0.0])


def _moved_px(camera: Camera, features: Features, R0, t0, R1, t1) -> float:
    """RMS distance (px) between the balls projected at two poses."""
    if not features.points:
        return 0.0
    P = features.point_centers()
    a = identify.project(camera, R0, t0, P)[0]
    b = identify.project(camera, R1, t1, P)[0]
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def track_near(
    image: np.ndarray,
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    context: RunContext,
    options: TrackOptions | None = None,
    search: float = 1.0,
    first_stage: int = 0,
    follow: int = 0,
) -> TrackResult:
    """Track one frame of a run from the predicted pose (R, t): see the module.

    Parameters
    ----------
    image : (H, W) the frame's pixels as stored.
    features : the design's features (mm, frame F); their body (``features.body``), where known,
        is subtracted at the predicted pose before the wires are measured (:mod:`.body`).
    camera : the frame's intrinsics (SPEC §1).
    R, t : the predicted pose F → X (rotation (3, 3), translation (3,) mm).
    context : what the run shares (:func:`run_context`).
    options : the image path's settings (default :class:`TrackOptions`); its blur is the context's.
    search : how far from its projection a ball is looked for, in matching tolerances (the
        stage-one bead matching tolerance, max(``match_tol_px``, the ball's radius)): more
        than 1 for a prediction known to be rough (made over several frames). Whatever the
        search, a pose is given out only when it moved no farther than the tolerance from the
        prediction, or through ``follow``.
    first_stage : the labelling stage the solve starts at (:func:`.labelling.evaluate`): 0
        (wide tolerances, then tight and thinned) or 2 (tight and thinned only; for a
        prediction known to be within a fraction of a pixel).
    follow : how many times a pose that passed every test but moved farther than the balls
        were matched within is taken as the prediction and the frame tracked again from it
        (from the wide stage). Such a pose is given out only when a pass from it confirms
        it: the balls matched again around where it puts them, every test passed again, and
        the pose moved no farther than the matching tolerance from it. A frame that follows
        a dropped one moves farther than its prediction says; following it is a tracked
        frame's cost instead of a full identification's.

    Returns
    -------
    TrackResult : converged only when every test passed; ``diagnostics.path = "tracked"``,
    ``diagnostics.moved_px`` the balls' RMS move from the prediction (R, t), whatever was
    followed. Never raises for an image (a failure is a refused pose with its reason).
    """
    R0, t0 = np.asarray(R, float), np.asarray(t, float)
    frame = _Frame(np.asarray(image), features, camera, context, options or TrackOptions())
    try:
        with one_blas_thread():
            res, moved_only = _track_near(frame, R, t, search, first_stage)
            for k in range(max(0, int(follow))):
                if not moved_only:
                    break
                R, t = res.pose.rotation, res.pose.translation_mm
                res, moved_only = _track_near(frame, R, t, 1.0, 0)
                _from_prediction(res.diagnostics, camera, features, R0, t0, res.pose, k + 1)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError, MemoryError, cv2.error) as exc:
        return failed_result(
            f"tracking failed on this frame: {type(exc).__name__}: {' '.join(str(exc).split())}", context.polarity
        )
    return res


def _from_prediction(
    diag: Diagnostics, camera: Camera, features: Features, R: np.ndarray, t: np.ndarray, pose: Pose, followed: int
) -> None:
    """Record in ``diag`` the move and the rotation of ``pose`` from the first prediction (R, t),
    reached after ``followed`` passes more."""
    diag.followed = followed
    if np.all(np.isfinite(pose.rotation)) and np.all(np.isfinite(pose.translation_mm)):
        diag.moved_px = round(_moved_px(camera, features, R, t, pose.rotation, pose.translation_mm), 2)
        diag.rotation_step_deg = round(math.degrees(float(so3.angle(pose.rotation, R))), 3)


@dataclass(frozen=True)
class _Crop:
    """The frame around the predicted fiducial, conditioned: density (dense = bright), where it
    can be read, its noise, the crop's camera and its corner (col0, row0) in the frame."""

    density: np.ndarray
    valid: np.ndarray | None
    noise: NoiseField
    camera: Camera
    corner: tuple[int, int]
    formation: str
    #: where a pixel shows nothing (:attr:`~ftrac_design.segment.conditioning.Conditioned.hidden`)
    hidden: np.ndarray | None = None
    #: where a pixel is clipped on the dense side (:attr:`~ftrac_design.segment.conditioning.Conditioned.censored`)
    censored: np.ndarray | None = None


def _crop(img: np.ndarray, context: RunContext, camera: Camera, box: tuple[int, int, int, int], disc_px: int) -> _Crop:
    """The frame ``img`` cropped to ``box`` (row0, row1, col0, col1) and conditioned with the run's
    polarity and formation (:func:`~ftrac_design.segment.conditioning.condition`) against the
    whole frame's clip levels, its noise read from the run's noise level function."""
    # the noise is measured on the box grown to the clutter term's tiles (:func:`.image.noise_map`):
    # the anatomy's clutter is then measured in the tiles the whole frame's would be (other tiles
    # gave ftrac_mini's depth a quarter more scatter over a 60-frame run); the rest works on the box
    r0, r1, c0, c1 = box
    a0, a1, b0, b1 = _on_tiles(box, img.shape, CLUTTER_TILE_PX)
    crop = img[a0:a1, b0:b1].astype(np.float32)
    cond = condition(crop, context.polarity, context.formation, disc_px, _clip_levels(img))
    levels = {context.ridge_sigma_px: context.noise} if context.noise is not None else None
    inner = (slice(r0 - a0, r1 - a0), slice(c0 - b0, c1 - b0))
    noise = NoiseField(cond.density, cond.valid, disc_px, levels=levels).crop(r0 - a0, r1 - a0, c0 - b0, c1 - b0)
    density = np.ascontiguousarray(cond.density[inner])
    valid = None if cond.valid is None else np.ascontiguousarray(cond.valid[inner])
    crop_cam = replace(
        camera, principal_point_px=(camera.principal_point_px[0] - c0, camera.principal_point_px[1] - r0)
    )
    hidden = None if cond.hidden is None else np.ascontiguousarray(cond.hidden[inner])
    censored = None if cond.censored is None else np.ascontiguousarray(cond.censored[inner])
    return _Crop(density, valid, noise, crop_cam, (c0, r0), cond.formation, hidden, censored)


def _crop_at(frame: "_Frame", sc0, sc, R: np.ndarray, t: np.ndarray, search_px: float) -> "_Crop | None":
    """The frame cropped around the model projected at (R, t) with the margin the filters and
    a ball search of ``search_px`` need (:func:`_crop`; ``sc0`` the settings' scales, whose
    top-hat disc conditions it, ``sc`` the run's), or None where that lies outside the image."""
    margin = sc.disc_px + 4 * sc.ridge_sigma_px + search_px + sc.bead_radius_px + 4
    box = predicted_box(frame.features, frame.camera, R, t, frame.image.shape, margin)
    return None if box is None else _crop(frame.image, frame.context, frame.camera, box, sc0.disc_px)


def _confirmed(
    pose: Pose, crop: _Crop, features: Features, R, t, capture: float, diag: Diagnostics
) -> tuple[Pose, bool]:
    """``pose`` unless its balls moved from the prediction (R, t) farther than ``capture`` px
    (RMS) they were matched within: then refused. Records the move and the rotation step;
    also returns whether the move was its only fault (a pose to follow)."""
    finite = bool(np.all(np.isfinite(pose.rotation)))
    moved = _moved_px(crop.camera, features, R, t, pose.rotation, pose.translation_mm) if finite else math.inf
    diag.moved_px = round(moved, 2) if math.isfinite(moved) else math.nan
    diag.rotation_step_deg = round(math.degrees(float(so3.angle(pose.rotation, R))), 3) if finite else math.nan
    if pose.converged and moved > capture:
        pose = refuse(
            pose,
            f"tracking not confirmed: the balls moved {moved:.1f} px (RMS) from where the previous frames "
            f"put them, more than the {capture:.1f} px they were matched within",
        )
        return pose, True
    return pose, False


@dataclass(frozen=True)
class _Frame:
    """What every pass of :func:`track_near` on one frame shares."""

    image: np.ndarray
    features: Features
    camera: Camera
    context: RunContext
    options: TrackOptions


def _track_near(
    frame: _Frame, R: np.ndarray, t: np.ndarray, search: float, first_stage: int
) -> tuple[TrackResult, bool]:
    """:func:`track_near`'s one pass from (R, t), and whether its pose failed only by moving too far."""
    features, camera, context, opts = frame.features, frame.camera, frame.context, frame.options
    # the filters are sized for the run's blur; the crop is conditioned as the run's context
    # was measured, with the top-hat's disc of the settings' own blur
    find = replace(opts.finding, blur_px=context.blur_px)
    labelling = opts.labelling
    R, t = np.asarray(R, float), np.asarray(t, float)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        return failed_result("no finite predicted pose", context.polarity), False
    sc0 = scales(features, camera, opts.finding)
    sc = scales(features, camera, find)
    capture = max(labelling.match_tol_px, sc.bead_radius_px)
    search_px = capture * max(1.0, float(search))
    # a search beyond the matching tolerance first finds, on a crop grown by the search, the
    # image shift that puts the most balls on blobs; the frame is then cropped and matched
    # around the shifted pose, and the move is judged from (R, t)
    Rs, ts = R, t
    if search > 1.0:
        wide = _crop_at(frame, sc0, sc, R, t, search_px)
        if wide is None:
            return failed_result("the predicted fiducial lies outside the image", context.polarity), False
        Rs, ts = _voted_pose(wide, features, sc, find.bead_min_snr, R, t, search_px, capture * VOTE_TOLERANCE)
        search_px = min(search_px, capture * VOTE_TOLERANCE)
    crop = _crop_at(frame, sc0, sc, Rs, ts, search_px)
    if crop is None:
        return failed_result("the predicted fiducial lies outside the image", context.polarity), False
    (c0, r0), (h, w) = crop.corner, crop.density.shape
    diag = Diagnostics(path="tracked", roi=[int(c0), int(r0), int(w), int(h)], formation=crop.formation)
    diag.blur_px = find.blur_px
    scene = scene_near(
        crop.density,
        features,
        crop.camera,
        find,
        Rs,
        ts,
        search_px,
        crop.valid,
        crop.noise,
        context.ball_blur_px,
        diag,
        crop.hidden,
        crop.censored,
    )
    diag.blobs = 0 if scene.beads is None else len(scene.beads)
    if scene.beads is None or len(scene.beads) < 3:
        why = f"tracking lost: {diag.blobs} balls found near their predicted places"
        return shifted(failed_result(why, context.polarity, scene.beads, None, diag), camera, c0, r0), False
    try:
        lab = evaluate(scene, identify.BeadHypothesis(Rs, ts, {}, 0, 0.0), labelling, first_stage=first_stage)
    except NoLabelling as exc:
        why = f"tracking lost: {exc.reason}"
        return shifted(failed_result(why, context.polarity, scene.beads, None, diag), camera, c0, r0), False
    lab = accept_best(scene, lab, [], diag, opts.acceptance)
    pose, moved_only = _confirmed(lab.pose, crop, features, R, t, capture, diag)
    diag.labelled(len(lab.obs.points), lab.dropped, lab.removed, scene.pixel_noise, lab.variance_factor)
    res = TrackResult(pose, lab.obs, feature_quality(scene, lab), scene.beads, None, context.polarity, lab.noise, diag)
    return shifted(res, camera, c0, r0), moved_only
