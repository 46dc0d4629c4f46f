"""What the image shows before any labelling: expected sizes, the background-free density,
its noise, bead candidates fitted with the blurred-sphere model and wire ridge points.

:class:`Scene` holds one image's detections together with the design, the camera and the
expected sizes, so that the labelling, the acceptance tests and the body subtraction take one
argument instead of eight; the settings each of them reads are passed beside it
(:mod:`.options`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..features.model import Features
from ..pose import Camera
from .beads import Beads, blob_candidates, blob_response, blob_sigma, fit_beads
from .image import NoiseField, derivatives, second_derivative_gain, top_hat
from .options import FindOptions, TrackOptions
from .ridges import RidgePoints, ridge_points

#: the learned detector's ball probability from which it reads a ball there
LEARNED_BALL = 0.5
#: the blur the ridge scale is sized for (``TrackOptions.blur_px``'s default, px)
DEFAULT_BLUR_PX = TrackOptions.blur_px


@dataclass(frozen=True)
class Scales:
    """Expected sizes in pixels at the assumed magnification (``TrackOptions.magnification``)
    and blur."""

    #: the largest ball's radius, px
    bead_radius_px: float
    #: the thickest wire's width, px
    wire_px: float
    #: mean pixel pitch, mm
    pixel_mm: float
    #: scale of the ridge detector, px
    ridge_sigma_px: float
    #: radius of the top-hat's disc, px: wider than any ball or wire with its blur
    disc_px: int
    #: the blur σ the filters are sized for, px (``TrackOptions.blur_px``, or the image's own
    #: fitted blur when it was detected again at it)
    blur_px: float
    #: the largest distance two balls can be apart in the image, px: their spread in F at
    #: ``TrackOptions.max_magnification``
    max_bead_spread_px: float = float("inf")
    #: scale of the blob detector, px (:func:`.beads.blob_sigma`): r/√2 at the default blur,
    #: wider by the blur beyond it; None: r/√2
    blob_sigma_px: float | None = None

    @property
    def touching_px(self) -> float:
        """The distance (px) at which two balls' blurred discs touch: two radii and two blur σ.
        Balls closer than this may blend into one blob; farther apart, each shows as its own."""
        return 2 * self.bead_radius_px + 2 * self.blur_px


def scales(features: Features, camera: Camera, opts: FindOptions) -> Scales:
    """Expected sizes in pixels of ``features`` seen with ``camera`` at the assumed
    magnification: bead radius, wire width, ridge scale and top-hat disc.

    Parameters
    ----------
    features : the design's features (mm).
    camera : intrinsics (SPEC §1).
    opts : what finding the features reads (``magnification``, ``max_magnification``, ``blur_px``).

    Returns
    -------
    Scales
    """
    pix = float(np.mean(camera.pixel_size_mm))
    m = opts.magnification
    bead = max((p.diameter for p in features.points), default=0.0) / 2 * m / pix
    wires = [ln.wire_diameter for ln in features.lines] + [e.wire_diameter for e in features.ellipses]
    wire = (max(wires) if wires else 0.0) * m / pix
    disc = int(math.ceil(max(bead, wire) + 3 * opts.blur_px + 2))
    # the ridge detector at the wire's blurred width: its own scale for the default blur, and
    # wider by the blur beyond that (a 2 px blur left half the wire below threshold)
    ridge = math.sqrt(max(1.0, 0.5 * wire + 0.5) ** 2 + max(opts.blur_px**2 - DEFAULT_BLUR_PX**2, 0.0))
    P = features.point_centers() if features.points else np.zeros((0, 3))
    spread = float(np.max(np.linalg.norm(P[:, None] - P[None], axis=-1))) if len(P) > 1 else 0.0
    spread_px = spread * opts.max_magnification / min(camera.pixel_size_mm) + 2 * bead
    blob = blob_sigma(bead, math.sqrt(max(opts.blur_px**2 - DEFAULT_BLUR_PX**2, 0.0)))
    return Scales(bead, wire, pix, ridge, disc, opts.blur_px, spread_px, blob)


@dataclass(frozen=True)
class Scene:
    """One density image's detections, with what they were found for.

    Every threshold is in units of the local noise (:func:`.image.noise_map` at the ridge
    scale) where it is applied; positions are measured on ``T`` itself (dividing it by a
    varying map would pull every centre along the map's gradient)."""

    features: Features
    camera: Camera
    scales: Scales
    #: background-free density image (white top-hat, dense = bright)
    T: np.ndarray
    #: local noise σ of ``T`` (H, W), density units
    noise_map: np.ndarray
    beads: Beads | None
    ridges: RidgePoints | None
    #: True where the image can be read (None: everywhere)
    valid: np.ndarray | None = None
    #: first and second derivatives of ``T`` at the ridge scale (keys x, y, xx, xy, yy)
    derivs: dict[str, np.ndarray] | None = None
    #: the blob detector's response over its noise (:func:`.beads.blob_response`)
    blob_snr: np.ndarray | None = None
    #: the learned detector's detections in this image's pixels (:mod:`ftrac_design.detector`),
    #: or None on the classical path
    learned: object | None = None
    #: True where a pixel shows nothing of what lies there (clipped, or burned-in graphics:
    #: :attr:`.conditioning.Cleaned.hidden`); None: nowhere
    hidden: np.ndarray | None = None
    #: True where a pixel's density is at least what it shows: clipped on the dense side
    #: (:attr:`.conditioning.Conditioned.censored`), read so by the ball fits; None: nowhere
    censored: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the image searched."""
        return self.T.shape

    @property
    def pixel_noise(self) -> float:
        """The median local noise σ in density units (a diagnostic)."""
        return float(np.median(self.noise_map))

    def ball_evidence(self, uv: np.ndarray) -> np.ndarray:
        """The blob detector's response over its noise at points ``uv`` (n, 2) px: several
        units where a ball is, about zero on background (0 where it was not computed)."""
        if self.blob_snr is None:
            return np.zeros(len(uv))
        return bilinear(self.blob_snr, np.asarray(uv, float).reshape(-1, 2))

    def hidden_fraction(self, uv: np.ndarray, radius_px: float) -> np.ndarray:
        """Per point ``uv`` (n, 2) px, the fraction of the pixels within ``radius_px`` of it that
        show nothing of what lies there (:attr:`hidden`; outside the image counts as hidden)."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        if self.hidden is None or not len(uv):
            return np.zeros(len(uv))
        r = int(math.ceil(radius_px))
        oy, ox = np.mgrid[-r : r + 1, -r : r + 1]
        disc = ox**2 + oy**2 <= radius_px * radius_px
        ox, oy = ox[disc], oy[disc]
        H, W = self.hidden.shape
        c = np.rint(np.nan_to_num(uv, nan=-1e6)).astype(np.int64)
        x, y = c[:, :1] + ox[None], c[:, 1:] + oy[None]
        inside = (x >= 0) & (y >= 0) & (x < W) & (y < H)
        hid = np.ones(x.shape, bool)
        hid[inside] = self.hidden[y[inside], x[inside]]
        return hid.mean(1)

    def learned_ball(self, uv: np.ndarray) -> np.ndarray:
        """The learned detector's ball probability at points ``uv`` (n, 2) px (0 on the classical path)."""
        if self.learned is None:
            return np.zeros(len(uv))
        return self.learned.ball_probability(np.asarray(uv, float).reshape(-1, 2))

    def learned_wire(self, uv: np.ndarray) -> np.ndarray:
        """The learned detector's wire probability at points ``uv`` (n, 2) px (0 on the classical path)."""
        if self.learned is None:
            return np.zeros(len(uv))
        return self.learned.wire_probability(np.asarray(uv, float).reshape(-1, 2))

    def noise_at(self, uv: np.ndarray) -> np.ndarray:
        """The local noise σ at points ``uv`` (n, 2) px."""
        return bilinear(self.noise_map, np.asarray(uv, float).reshape(-1, 2))

    def bead_exclusion(self, extra_px: float = 1.0) -> np.ndarray:
        """Per model bead, the radius (px) within which wire evidence is not read: the ball's
        blurred image and ``extra_px``."""
        return np.full(len(self.features.points), self.scales.bead_radius_px + 2 * self.scales.blur_px + extra_px)

    def with_detections(
        self,
        T: np.ndarray,
        beads: Beads | None,
        ridges: RidgePoints | None,
        derivs: dict[str, np.ndarray] | None = None,
    ) -> "Scene":
        """The same scene with other detections (the body subtracted)."""
        return replace(self, T=T, beads=beads, ridges=ridges, derivs=derivs if derivs is not None else self.derivs)

    def readable(self, uv: np.ndarray, margin_px: float = 0.0) -> np.ndarray:
        """Whether each point (n, 2) px lies inside the image (``margin_px`` clear of its
        edge) and where it can be read (``valid``)."""
        H, W = self.shape
        uv = np.asarray(uv, float)
        ok = (
            np.isfinite(uv).all(-1)
            & (uv[..., 0] >= margin_px)
            & (uv[..., 1] >= margin_px)
            & (uv[..., 0] <= W - 1 - margin_px)
            & (uv[..., 1] <= H - 1 - margin_px)
        )
        if self.valid is not None and ok.any():
            iu = np.clip(np.rint(uv[..., 0]), 0, W - 1).astype(int)
            iv = np.clip(np.rint(uv[..., 1]), 0, H - 1).astype(int)
            ok &= self.valid[iv, iu]
        return ok

    def ridge_evidence(self, uv: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Ridge strength across ``normal`` (n, 2, unit) at points ``uv`` (n, 2) px, in units
        of its noise: −∂²T/∂n² at the ridge scale (bilinear), over that filter's response
        to unit white noise. A wire there reads several units; bare background reads about
        zero, whatever its level (a second derivative has none)."""
        xx, xy, yy, nz = bilinear_many(
            [self.derivs["xx"], self.derivs["xy"], self.derivs["yy"], self.noise_map],
            np.asarray(uv, float).reshape(-1, 2),
        )
        nx, ny = normal[:, 0], normal[:, 1]
        c = nx * nx * xx + 2 * nx * ny * xy + ny * ny * yy
        return -c / (second_derivative_gain(self.scales.ridge_sigma_px) * nz)


def bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``img`` (H, W) at points ``uv`` (n, 2) px (u = column), bilinear; points outside
    are clamped to the border."""
    H, W = img.shape
    u = np.clip(uv[:, 0], 0, W - 1.000001)
    v = np.clip(uv[:, 1], 0, H - 1.000001)
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - u0, v - v0
    return (
        img[v0, u0] * (1 - fu) * (1 - fv)
        + img[v0, u0 + 1] * fu * (1 - fv)
        + img[v0 + 1, u0] * (1 - fu) * fv
        + img[v0 + 1, u0 + 1] * fu * fv
    )


def bilinear_many(imgs: list[np.ndarray], uv: np.ndarray) -> list[np.ndarray]:
    """Each of ``imgs`` (all (H, W)) at points ``uv`` (n, 2) px, as :func:`bilinear` gives
    them (the same numbers): the cell and weights are found once for all the images."""
    H, W = imgs[0].shape
    u = np.clip(uv[:, 0], 0, W - 1.000001)
    v = np.clip(uv[:, 1], 0, H - 1.000001)
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - u0, v - v0
    i = v0 * W + u0
    i1, iw, iw1 = i + 1, i + W, i + W + 1
    gu, gv = 1 - fu, 1 - fv
    out = []
    for img in imgs:
        f = img.reshape(-1)
        # the products in bilinear's order: the same rounding, the same numbers
        out.append(f[i] * gu * gv + f[i1] * fu * gv + f[iw] * gu * fv + f[iw1] * fu * fv)
    return out


def ball_fits(
    T: np.ndarray,
    starts: np.ndarray,
    response: np.ndarray,
    radius_px: float,
    noise: np.ndarray,
    blur_px: float,
    exclude: np.ndarray | None = None,
    censored: np.ndarray | None = None,
) -> tuple[Beads, np.ndarray]:
    """The blurred-sphere model fitted at every start (n, 2) px of the background-free image
    ``T`` (:func:`.beads.fit_beads`, pixels where ``exclude`` is True left out), and which
    fits look like a ball.

    A fit that ran off (amplitude far from the others', radius or blur at a bound) is redone
    with priors 25× stronger (σ_prior / 5); a fit looks like a ball when it is finite, its
    radius within 0.5–2 × ``radius_px``, its blur below 3 px, its amplitude positive and its
    centre clear of the image's edge by a blurred ball.

    Parameters
    ----------
    T : (H, W) background-free density image.
    starts, response : start centres (n, 2) px and their blob response over its noise (n,).
    radius_px : the expected ball radius, px.
    noise : (H, W) local noise σ of ``T``.
    blur_px : the blur σ the fits start from, px.
    exclude : (H, W) bool, pixels no fit uses (a predicted wire), or None.
    censored : (H, W) bool, pixels whose density is at least what ``T`` shows (clipped on the
        dense side: :attr:`Scene.censored`), or None.

    Returns
    -------
    (Beads (n, every fit, in the order of ``starts``), (n,) bool: the fits that look like a ball)
    """
    rb = radius_px
    b = fit_beads(T, starts, rb, blur_px, bilinear(noise, starts), response, exclude=exclude, censored=censored)
    if len(b) > 2:
        med = float(np.median(b.amplitude))
        bad = ~((b.amplitude > 0.2 * med) & (b.amplitude < 5 * med) & np.isfinite(b.sigma_px))
        if bad.any():
            b2 = fit_beads(
                T,
                starts[bad],
                rb,
                blur_px,
                bilinear(noise, starts[bad]),
                response[bad],
                exclude=exclude,
                prior_scale=25.0,
                censored=censored,
            )
            for k in b.__dataclass_fields__:
                getattr(b, k)[bad] = getattr(b2, k)
    H, W = T.shape
    edge = rb + 2 * blur_px + 1
    with np.errstate(invalid="ignore"):
        ok = (
            np.isfinite(b.uv).all(1)
            & (b.radius > 0.5 * rb)
            & (b.radius < 2.0 * rb)
            & (b.blur < 3.0)
            & (b.amplitude > 0)
            & (b.uv[:, 0] > edge)
            & (b.uv[:, 1] > edge)
            & (b.uv[:, 0] < W - 1 - edge)
            & (b.uv[:, 1] < H - 1 - edge)
            & np.isfinite(b.sigma_px)
        )
    return b, ok


def balls_at(scene: Scene, starts: np.ndarray, min_snr: float, tol_px: float) -> Beads:
    """Balls fitted where a pose predicts them: the blurred-sphere fits at ``starts`` (n, 2)
    px on ``scene.T`` that look like a ball (:func:`ball_fits`), stay within ``tol_px`` of
    their start, stand ``min_snr`` above the noise in the blob detector's response (the
    threshold of the search without a prediction), lie clear of pixels that cannot be read
    and of every other ball; at most one per start.

    The search without a prediction keeps the design's balls × 3 + 6 strongest blobs, and
    over dense anatomy or on a display frame clutter outranks the balls: of a blurred
    ftrac_2005 over dense anatomy (tuning seed 21) it kept four, too few to confirm the right
    labelling, which found its fifth ball where it predicted one."""
    starts = np.asarray(starts, float).reshape(-1, 2)
    z = np.zeros(0)
    none = Beads(np.zeros((0, 2)), z, z, z, z, z, z, z)
    if len(starts) == 0:
        return none
    # the fit runs where the blob detector sees something at all (a quarter of the
    # threshold): most predictions of wrong hypotheses land on bare background
    starts = starts[scene.ball_evidence(starts) >= 0.25 * min_snr]
    if len(starts) == 0:
        return none
    sc = scene.scales
    b, ok = ball_fits(
        scene.T,
        starts,
        scene.ball_evidence(starts),
        sc.bead_radius_px,
        scene.noise_map,
        sc.blur_px,
        censored=scene.censored,
    )
    b.response[:] = scene.ball_evidence(b.uv)
    with np.errstate(invalid="ignore"):
        ok &= (np.linalg.norm(b.uv - starts, axis=1) <= tol_px) & (b.response >= min_snr)
    if ok.any() and scene.valid is not None and not scene.valid.all():
        H, W = scene.shape
        clear = cv2.distanceTransform(scene.valid.astype(np.uint8), cv2.DIST_L2, 3)
        c = np.clip(np.rint(np.nan_to_num(b.uv)).astype(int), 0, [W - 1, H - 1])
        ok &= clear[c[:, 1], c[:, 0]] > sc.bead_radius_px
    others = scene.beads.uv if scene.beads is not None and len(scene.beads) else np.zeros((0, 2))
    keep: list[int] = []
    for i in np.flatnonzero(ok):
        near = [b.uv[j] for j in keep] + list(others)
        if not near or np.linalg.norm(np.asarray(near) - b.uv[i], axis=1).min() > sc.bead_radius_px:
            keep.append(int(i))
    return b.take(np.array(keep, int)) if keep else none


def _bead_candidates(
    T: np.ndarray, features: Features, sc: Scales, noise: np.ndarray, min_snr: float, censored: np.ndarray | None
) -> Beads:
    rb = sc.bead_radius_px
    P = len(features.points)
    # more candidates than the labelling uses: over anatomy or on a display frame, clutter
    # (a clipped bone edge's staircase, edge-enhancement overshoot) can outrank the balls in
    # response alone; the model fit tells them apart (below)
    cand, resp = blob_candidates(T, rb, noise, 8 * P + 40, min_snr, sigma_px=sc.blob_sigma_px)
    if len(cand):
        # the beads are the strongest blobs; anything far weaker is a wire crossing or clutter
        ref = np.sort(resp)[::-1][:P]
        keep = resp >= 0.25 * float(np.median(ref))
        cand, resp = cand[keep], resp[keep]
    b, ok = ball_fits(T, cand, resp, rb, noise, sc.blur_px, censored=censored)
    b = b.take(ok)
    # strongest first, each response discounted by its misfit to the ball model (a ball fits
    # to its noise, rms ≈ 1–2 even with a wire under it; the clutter above fitted at rms 4–5),
    # and, loosely, by how far its fitted radius is from a ball's (burned-in text: 0.3–0.9 ×;
    # a display frame's window and gamma make a ball look 1.2–1.4 × its size)
    size = np.exp(-0.5 * (np.log(b.radius / rb) / 0.5) ** 2)
    order = np.argsort(-(b.response * size / np.maximum(b.rms, 1.0)), kind="stable")[: 3 * P + 6]
    if len(order) < len(b):
        # the kept ones fitted again among themselves: the fit's robust scale is pooled over
        # the candidates fitted together, and the clutter left out must not loosen it
        kept = b.take(order)
        again = fit_beads(T, kept.uv, rb, sc.blur_px, bilinear(noise, kept.uv), kept.response, censored=censored)
        same = (
            np.isfinite(again.uv).all(1)
            & (np.linalg.norm(again.uv - kept.uv, axis=1) < 1.0)
            & np.isfinite(again.sigma_px)
        )
        return Beads(
            *(
                np.where(same[:, None] if getattr(kept, k).ndim == 2 else same, getattr(again, k), getattr(kept, k))
                for k in kept.__dataclass_fields__
            )
        )
    return b.take(order)


def _learned_candidates(
    T: np.ndarray,
    starts: np.ndarray,
    features: Features,
    sc: Scales,
    noise: np.ndarray,
    snr: np.ndarray,
    valid: np.ndarray | None = None,
    censored: np.ndarray | None = None,
) -> Beads:
    """The blurred-sphere fits at the learned detector's ball candidates ``starts`` (n, 2) px,
    most probable first: those that look like a ball, in the detector's order, at most
    3 × the design's balls + 6. Each fit's ``response`` is ``snr`` (H, W), the classical blob
    detector's response over its noise, at the fitted centre (what the rest of the path reads
    as a ball's SNR).

    A fit whose ball reaches into pixels that are not ``valid`` (a display window's clipped
    white or black, a shutter; ``T`` is zero there) is left out: its edge is the clip's, not
    the ball's, and the network, unlike the classical blob search, proposes balls there too."""
    P = len(features.points)
    H, W = T.shape
    starts = np.asarray(starts, float).reshape(-1, 2)
    starts = starts[(starts[:, 0] >= 0) & (starts[:, 1] >= 0) & (starts[:, 0] <= W - 1) & (starts[:, 1] <= H - 1)]
    if len(starts) == 0:
        z = np.zeros(0)
        return Beads(np.zeros((0, 2)), z, z, z, z, z, z, z)
    b, ok = ball_fits(T, starts, bilinear(snr, starts), sc.bead_radius_px, noise, sc.blur_px, censored=censored)
    b = b.take(ok)
    if len(b) and valid is not None and not valid.all():
        clear = cv2.distanceTransform(valid.astype(np.uint8), cv2.DIST_L2, 3)
        c = np.clip(np.rint(b.uv).astype(int), 0, [W - 1, H - 1])
        b = b.take(np.flatnonzero(clear[c[:, 1], c[:, 0]] > sc.bead_radius_px))
    if len(b):
        b.response[:] = bilinear(snr, b.uv)
    return b.take(np.arange(min(len(b), 3 * P + 6)))


def detect(
    g: np.ndarray,
    features: Features,
    camera: Camera,
    opts: FindOptions,
    valid: np.ndarray | None = None,
    noise: NoiseField | None = None,
    learned=None,
    hidden: np.ndarray | None = None,
    censored: np.ndarray | None = None,
) -> Scene:
    """Background-free image and its local noise, fitted bead candidates and ridge points of the
    density image ``g`` (dense = bright).

    Parameters
    ----------
    g : (H, W) density image.
    features, camera : the design and the intrinsics of ``g``'s pixels.
    opts : what finding the features reads (sizes, blur and the SNR thresholds).
    valid : (H, W) bool, True where ``g`` can be read; nothing is detected elsewhere.
    noise : the local noise of ``g`` (:class:`.image.NoiseField`, of the whole image when
        ``g`` is a crop of it); measured on ``g`` when not given.
    learned : the learned detector's detections in ``g``'s pixels (:mod:`ftrac_design.detector`):
        its ball candidates (most probable first) are fitted instead of the classical blob
        detector's, and the scene keeps them as evidence; None for the classical path.
    hidden : (H, W) bool, True where a pixel shows nothing of what lies there (kept by the
        scene: :attr:`Scene.hidden`).
    censored : (H, W) bool, True where a pixel's density is at least what it shows
        (:attr:`Scene.censored`).

    Returns
    -------
    Scene
    """
    sc = scales(features, camera, opts)
    T = top_hat(g, sc.disc_px)
    if noise is None:
        noise = NoiseField(g, valid, sc.disc_px)
    nmap = noise.at(sc.ridge_sigma_px)
    if valid is not None:
        T[~valid] = 0.0
    snr = None
    if features.points:
        resp, _, _, nr = blob_response(T, sc.bead_radius_px, nmap, sc.blob_sigma_px)
        snr = (resp / nr).astype(np.float32)
    if not features.points:
        beads = None
    elif learned is not None:
        beads = _learned_candidates(T, learned.beads_uv, features, sc, nmap, snr, valid, censored)
    else:
        beads = _bead_candidates(T, features, sc, nmap, opts.bead_min_snr, censored)
    d = derivatives(T, sc.ridge_sigma_px)
    ridges = None
    if features.lines or features.ellipses:
        ridges = ridge_points(T, sc.ridge_sigma_px, nmap, opts.ridge_min_snr, derivs=d)
    return Scene(features, camera, sc, T, nmap, beads, ridges, valid, d, snr, learned, hidden, censored)


def fitted_blur(scene: Scene) -> float | None:
    """The image's blur σ (px) as the balls show it, or None with fewer than three
    candidates: the blur that gives a ball of the expected radius the median second moment
    of the most ball-like candidates (as many as the design has balls).

    A blurred sphere's image has the second moment r²/5 + σ² per axis (its projected chord
    alone: r²/5). The fit pins that sum, not its parts: under a 1.6–2 px blur the fits of
    ftrac_2005's 3.4 px balls came out at radius 4.2–5.8 px and blur 0.6–1.3 px (tuning
    seed, blur condition), and their median blur alone never asked for the image to be
    detected again at its own blur."""
    b = scene.beads
    if b is None or len(b) < 3:
        return None
    n = max(3, len(scene.features.points))
    moment = float(np.median(b.second_moment_px2[:n]))
    return math.sqrt(max(moment - scene.scales.bead_radius_px**2 / 5.0, 0.0))
