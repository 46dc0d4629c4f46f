"""The radiograph simulator: Beer–Lambert line integrals of the fiducial at a pose.

Image formation, in order:

1. **Line integral** ``p(u, v) = Σ μ_m × chord_m`` through the beads (spheres), the wires
   (tube pieces, :mod:`.geometry`), the body (hollow cylinder) and any occluders, evaluated
   only inside the fiducial's bounding box (:func:`line_integral_field`). Wherever ``p`` is
   not smooth (every pixel a wire or bead touches, and body pixels whose 4-neighbour
   Laplacian exceeds ``BODY_ROUGHNESS``, with ``BODY_DILATE_PX`` rings of neighbours) it is
   taken at s² sub-samples per pixel (``supersample`` = s, a rotated grid,
   :func:`.rays.subsample_offsets`); elsewhere at the pixel centre (midpoint rule, error ≈
   Laplacian / 24 < 4e-4). Steel that fills a groove is not reduced by the acetal it
   displaces (0.3 % of its contrast), and grooves/pockets are not cut from the body.
2. **Photons to pixels** (:func:`detected_deficit`): each sub-sample's transmission
   ``exp(−p)`` — not the exponential of a pixel's mean line integral — is blurred by a
   Gaussian of σ² = σ_detector² + σ_focal², σ_focal = (M − 1) × focal spot / 2.355 / pixel
   pitch with M = f / Z of the fiducial origin (the ±2 % change of M across the fiducial is
   neglected), and integrated over the receiving pixels: the blur convolved exactly with the
   pixel box (:func:`pixel_kernels`). So the detector conserves photons: a part's summed
   contrast Σ(1 − I/I0) is the s²-point quadrature of its attenuation, whatever its
   sub-pixel position (a 0.3 mm wire: < 1 % over phases at s = 5).
3. **Background**: an anatomy line-integral image, taken as already blurred and integrated
   by the detector (as the intensity refinement models it): its transmission multiplies the
   fiducial's detected one. (:mod:`.scenario` multiplies a patient's transmission with the
   fiducial's on the photon field instead, before the blur.)
4. **Quantum noise**: counts ``N = N0 exp(−p)``; Gaussian with variance N (the Poisson
   variance) when every expected count is ≥ 100, where Poisson's skewness 1/√N ≤ 0.1 is
   invisible and Gaussian draws cost a ninth of Poisson ones (10 vs 88 ms per 10⁶ here);
   exact Poisson draws otherwise.
5. **Raw** = round(gain × N) clipped to the bit depth (flat field at 80 % of full scale,
   dense = dark); the **log image** is ``−ln(raw / (gain N0))`` (dense = bright), or the
   noise-free line integral when noise is off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np
from scipy.special import erf

from ..design import Body
from ..features.model import Features
from ..pose.camera import Camera
from .geometry import Pieces, body_chord_uv, sphere_chord, straight_pieces, tube_chord_uv
from .model import ImagingModel, Occluder, Radiograph
from .rays import BODY_ROUGHNESS, Rays, capsule_pixels, feature_pieces, project_points, subsample_offsets

#: Gaussian counts are used when every expected count is at least this
_GAUSSIAN_MIN_COUNTS = 100.0

#: body pixels within this many pixels of a rough one (:func:`rough_body_pixels`) are
#: sub-sampled too. A smooth pixel is detected as if uniform over its area, which ignores
#: its gradient: with one ring, sub-sampling a second moves the noise-free log image next
#: to the body's silhouettes by up to 3.4e-3 (about 0.3 of its quantum noise there at the
#: default dose; ftrac_2005, 667 mm); two rings cost 1.2× the render time of one
BODY_DILATE_PX = 2


def _occluder_pieces(occluders: Sequence[Occluder], imaging: ImagingModel, R: np.ndarray, t: np.ndarray) -> Pieces:
    parts = []
    for k, oc in enumerate(occluders):
        a, b = np.asarray(oc.start, float), np.asarray(oc.end, float)
        if oc.frame == "X":
            a, b = R.T @ (a - t), R.T @ (b - t)
        parts.append(straight_pieces(a, b, oc.diameter / 2, imaging.mu(oc.material), -1 - k))
    return Pieces.concat(parts)


@dataclass
class SubsampledField:
    """The fiducial's line integral over a box of pixels, sub-sampled where it is not smooth.

    ``p`` (h, w): at smooth pixels the line integral at the pixel centre, at the sub-sampled
    ("rough") pixels the mean of their sub-samples; ``rough`` (n,) flat indices into ``p`` of
    the rough pixels and ``sub`` (n, s²) their sub-samples' line integrals (offsets
    :func:`.rays.subsample_offsets`); pixel ``p[j, i]`` is image pixel (row ``origin[0]`` + j,
    column ``origin[1]`` + i); ``supersample`` = s.
    """

    p: np.ndarray
    rough: np.ndarray
    sub: np.ndarray
    origin: tuple[int, int]
    supersample: int


def gather_field(p: np.ndarray, origin: tuple[int, int], groups, s: int) -> SubsampledField:
    """Sum sub-sampled contributions into a :class:`SubsampledField`.

    Parameters
    ----------
    p : (h, w) smooth line integral (the body at pixel centres, or zeros); changed in place:
        its rough pixels become their sub-samples' mean.
    origin : (row0, col0) image pixel of ``p[0, 0]``.
    groups : iterable of ``(rows, cols, values)``: image rows and columns (n,) of pixels inside
        the box and their sub-samples' line integrals (n, s²) to add (several entries may name
        the same pixel; they add).
    s : sub-samples per pixel side.
    """
    h, w = p.shape
    S = s * s
    v0, u0 = origin
    groups = [(((rows - v0) * w + (cols - u0)).astype(np.int64), vals) for rows, cols, vals in groups]
    if not groups:
        return SubsampledField(p, np.zeros(0, np.int64), np.zeros((0, S)), (int(v0), int(u0)), s)
    rough, inv = np.unique(np.concatenate([g[0] for g in groups]), return_inverse=True)
    sub = np.zeros(len(rough) * S)
    pos = 0
    for idx, vals in groups:
        k = inv[pos : pos + len(idx)]
        pos += len(idx)
        sub += np.bincount(
            (k[:, None] * S + np.arange(S)).ravel(), weights=np.asarray(vals, float).ravel(), minlength=len(rough) * S
        )
    sub = sub.reshape(-1, S) + p.ravel()[rough][:, None]
    p.ravel()[rough] = sub.mean(1)
    return SubsampledField(p, rough, sub, (int(v0), int(u0)), s)


def line_integral_field(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera,
    imaging: ImagingModel,
    occluders: Sequence[Occluder] = (),
    margin_px: int = 0,
) -> SubsampledField:
    """Un-blurred line integral of the fiducial over its bounding box (see :class:`SubsampledField`):
    every pixel a wire, bead or occluder touches, and the rough pixels of its body
    (``features.body``; none when it is None), sub-sampled.

    The box is not clipped to the image; ``margin_px`` widens it. Empty: a (0, 0) field.
    """
    R, t = np.asarray(R, float), np.asarray(t, float)
    mu_steel = imaging.mu("steel")
    centers, radii, pieces = feature_pieces(features, mu_steel)
    if occluders:
        pieces = Pieces.concat([pieces, _occluder_pieces(occluders, imaging, R, t)])
    rays = Rays(camera, R, t)
    pix = min(camera.pixel_size_mm)
    s = int(imaging.supersample)
    ou, ov = subsample_offsets(s)
    fdt = np.float32 if imaging.single_precision else np.float64

    groups = []  # (rows, cols, sub-sample values) of the primitives
    lo, hi = [], []
    if len(pieces.L):
        ends = np.concatenate([pieces.a, pieces.a + pieces.L[:, None] * pieces.e])
        uv, Z = project_points(camera, R, t, ends)
        M = len(pieces.L)
        zmin = np.minimum(Z[:M], Z[M:]) - pieces.r
        rad = pieces.r * camera.focal_length_mm / np.maximum(zmin, 1.0) / pix * 1.05 + 0.75
        k, rows, cols = capsule_pixels(uv[:M, 0], uv[:M, 1], uv[M:, 0], uv[M:, 1], rad)
        if len(k):
            U = cols[:, None] + ou[None, :]
            V = rows[:, None] + ov[None, :]
            ch = tube_chord_uv(rays.c, rays.g0, rays.gu, rays.gv, pieces, k, U, V, fdt)
            groups.append((rows, cols, ch * pieces.mu[k][:, None]))
            lo.append([rows.min(), cols.min()])
            hi.append([rows.max(), cols.max()])
    if len(radii):
        uv, Z = project_points(camera, R, t, centers)
        rad = radii * camera.focal_length_mm / np.maximum(Z - radii, 1.0) / pix * 1.05 + 0.75
        k, rows, cols = capsule_pixels(uv[:, 0], uv[:, 1], uv[:, 0], uv[:, 1], rad)
        kk = np.repeat(k, s * s)
        u = np.repeat(cols, s * s) + np.tile(ou, len(k))
        v = np.repeat(rows, s * s) + np.tile(ov, len(k))
        ch = sphere_chord(rays.c, rays(u, v), centers[kk], radii[kk])
        groups.append((rows, cols, ch.reshape(-1, s * s) * mu_steel))
        lo.append([rows.min(), cols.min()])
        hi.append([rows.max(), cols.max()])
    body_box = None
    body = features.body
    if body is not None:
        ro, h = body.outer_diameter / 2, body.length / 2
        corners = np.array([[x, y, z] for x in (-ro, ro) for y in (-ro, ro) for z in (-h, h)])
        uv, _ = project_points(camera, R, t, corners)
        b_lo = np.floor(uv.min(0)).astype(int) - 1
        b_hi = np.ceil(uv.max(0)).astype(int) + 1
        body_box = (b_lo, b_hi)
        lo.append([b_lo[1], b_lo[0]])
        hi.append([b_hi[1], b_hi[0]])
    if not lo:
        return SubsampledField(np.zeros((0, 0)), np.zeros(0, np.int64), np.zeros((0, s * s)), (0, 0), s)
    v0, u0 = np.min(lo, 0) - margin_px
    v1, u1 = np.max(hi, 0) + margin_px
    p = np.zeros((int(v1 - v0 + 1), int(u1 - u0 + 1)))
    if body_box is not None:
        groups.append(_add_body(p, (v0, u0), body_box, body, imaging.mu(body.material), rays, s, fdt))
    return gather_field(p, (int(v0), int(u0)), groups, s)


def line_integral_box(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera,
    imaging: ImagingModel,
    occluders: Sequence[Occluder] = (),
    margin_px: int = 0,
):
    """Un-blurred, pixel-integrated (mean over the sub-samples) line integral over the fiducial's bounding box.

    Returns ``(p, (v0, u0))``: ``p`` (h, w) float64 whose pixel ``p[j, i]`` is image pixel
    (row v0 + j, column u0 + i); the box is not clipped to the image. ``margin_px`` widens it.
    """
    field = line_integral_field(features, R, t, camera, imaging, occluders, margin_px)
    return field.p, field.origin


def _body_values(rays: Rays, U: np.ndarray, V: np.ndarray, body: Body, mu: float, dtype=np.float64) -> np.ndarray:
    c, g0, gu, gv = (np.asarray(x, dtype) for x in (rays.c, rays.g0, rays.gu, rays.gv))
    return mu * body_chord_uv(
        c,
        g0,
        gu,
        gv,
        body.outer_diameter / 2,
        body.bore_diameter / 2,
        body.length / 2,
        np.asarray(U, dtype),
        np.asarray(V, dtype),
    )


def rough_body_pixels(centre: np.ndarray, dilate_px: int = 1) -> np.ndarray:
    """Body pixels to sub-sample (bool, like ``centre``): 4-neighbour Laplacian of the centre
    line integral above :data:`.rays.BODY_ROUGHNESS`, dilated by ``dilate_px`` pixels."""
    lap = np.zeros_like(centre)
    lap[1:-1, 1:-1] = (
        centre[:-2, 1:-1] + centre[2:, 1:-1] + centre[1:-1, :-2] + centre[1:-1, 2:] - 4 * centre[1:-1, 1:-1]
    )
    flag = np.abs(lap) > BODY_ROUGHNESS
    for _ in range(dilate_px):
        f = flag.copy()
        f[1:, :] |= flag[:-1, :]
        f[:-1, :] |= flag[1:, :]
        f[:, 1:] |= flag[:, :-1]
        f[:, :-1] |= flag[:, 1:]
        flag = f
    return flag


def _add_body(p: np.ndarray, origin, box, body: Body, mu: float, rays: Rays, s: int, fdt=np.float32):
    """Add the body's centre line integral to ``p``; return its rough pixels' sub-sample
    corrections (rows, cols, sub − centre) as a group for :func:`gather_field`."""
    (bu0, bv0), (bu1, bv1) = box
    v0, u0 = origin
    cu = np.arange(bu0, bu1 + 1, dtype=float)
    cv = np.arange(bv0, bv1 + 1, dtype=float)
    # float32 (single_precision): the body's μ is small, so rounding (worst at the
    # silhouettes, where R²A − (m√A)² cancels) stays below 1e-4 in p
    centre = _body_values(rays, cu[None, :], cv[:, None], body, mu, fdt).astype(np.float64)
    p[bv0 - v0 : bv1 - v0 + 1, bu0 - u0 : bu1 - u0 + 1] += centre
    jj, ii = np.nonzero(rough_body_pixels(centre, BODY_DILATE_PX))
    if not len(jj):
        return np.zeros(0, int), np.zeros(0, int), np.zeros((0, s * s))
    ou, ov = subsample_offsets(s)
    sub = _body_values(rays, cu[ii][:, None] + ou, cv[jj][:, None] + ov, body, mu, fdt)
    return jj + bv0, ii + bu0, sub - centre[jj, ii][:, None]


def blur_sigma_px(camera: Camera, imaging: ImagingModel, depth_mm: float) -> tuple[float, float]:
    """Total Gaussian σ (σ_u, σ_v) in pixels: detector line-spread and focal spot at magnification f / depth."""
    M = camera.focal_length_mm / depth_mm
    fs = max(M - 1.0, 0.0) * imaging.focal_spot_mm / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    su = math.hypot(imaging.detector_blur_px, fs / camera.pixel_size_mm[0])
    sv = math.hypot(imaging.detector_blur_px, fs / camera.pixel_size_mm[1])
    return su, sv


def pixel_kernels(sigma_px: float, offsets: np.ndarray) -> np.ndarray:
    """Weights (len(offsets), 2m + 1) of the detector's response along one axis to a photon
    ``offsets`` px from a pixel centre: the Gaussian blur of σ ``sigma_px`` integrated over
    the receiving pixels, ``K(x) = ½ [erf((x + ½)/(√2 σ)) − erf((x − ½)/(√2 σ))]`` (the pixel
    box convolved with the Gaussian, exact), as correlation weights (``cv2.sepFilter2D``,
    ``scipy.ndimage.correlate1d``): weight ``j`` multiplies the source pixel ``m − j`` pixels
    before the output one (m = ⌈4σ⌉ + 1). Each
    row sums to 1 (photons are conserved); σ = 0 is the bare pixel box.
    """
    o = np.asarray(offsets, float)
    m = int(math.ceil(4.0 * sigma_px)) + 1
    x = (m - np.arange(2 * m + 1))[None, :] - o[:, None]  # receiving − source, px
    if sigma_px < 1e-6:
        K = ((x > -0.5) & (x < 0.5)).astype(float) + 0.5 * (np.abs(np.abs(x) - 0.5) < 1e-12)
    else:
        a = math.sqrt(2.0) * sigma_px
        K = 0.5 * (erf((x + 0.5) / a) - erf((x - 0.5) / a))
    return K / K.sum(1, keepdims=True)


def _correlate2(a: np.ndarray, ku: np.ndarray, kv: np.ndarray) -> np.ndarray:
    # OpenCV's separable filter is a correlation with the anchor at the kernel's centre, like
    # scipy's correlate1d, and several times faster; zero beyond the box (no deficit there)
    return cv2.sepFilter2D(a, -1, ku, kv, borderType=cv2.BORDER_CONSTANT)


def detected_deficit(
    field: SubsampledField, sigma_u: float, sigma_v: float, behind: np.ndarray | None = None, dtype=np.float32
) -> np.ndarray:
    """What the detector reads of the field's photon deficit: ``1 − I/I0`` per pixel (h, w), ``dtype``.

    The photons, not the line integrals, are blurred and integrated: each sub-sample's
    transmission ``exp(−p_k)`` (weight 1 / s² of its pixel; a smooth pixel's s² sub-samples
    all take its centre value) spreads over the receiving pixels by :func:`pixel_kernels` —
    the Gaussian blur (σ_u, σ_v px) convolved exactly with the pixel box. ``behind`` (h, w), optional:
    the transmission of what else the photons crossed (a patient), taken as constant over a
    pixel, multiplies the field's transmission before the blur (photon-field product).
    Outside the box the field transmits fully (deficit 0).
    """
    s = field.supersample
    Dc = (-np.expm1(-field.p)).astype(dtype)
    if behind is not None:
        behind = np.asarray(behind, dtype)
        Dc *= behind
    ou, ov = subsample_offsets(s)
    ku = pixel_kernels(sigma_u, ou).astype(dtype)
    kv = pixel_kernels(sigma_v, ov).astype(dtype)
    # a smooth pixel is its centre value spread uniformly over the pixel: the mean response
    # of its s² sub-samples (not separable for the rotated grid; exact, so that a constant
    # pixel is detected alike whether it is sub-sampled or not)
    Dc.ravel()[field.rough] = 0.0
    out = cv2.filter2D(Dc, -1, np.einsum("ku,kv->vu", ku, kv) / (s * s), borderType=cv2.BORDER_CONSTANT)
    if len(field.rough):
        Ds = (-np.expm1(-field.sub) / (s * s)).astype(dtype)
        if behind is not None:
            Ds *= behind.ravel()[field.rough][:, None]
        F = np.zeros_like(Dc)
        flat = F.ravel()
        for k in range(s * s):
            flat[field.rough] = Ds[:, k]
            out += _correlate2(F, ku[k], kv[k])
    return out


def transmission_box(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera,
    imaging: ImagingModel,
    occluders: Sequence[Occluder] = (),
):
    """Noise-free transmission I/I0 of the fiducial as the detector reads it (blurred photons
    integrated over each pixel, :func:`detected_deficit`) over its bounding box, clipped to
    the image: ``(I (h, w) float32, (row0, col0))``; outside the box I = 1. Empty box: (0, 0) array."""
    field, (r0, c0) = detector_box(features, R, t, camera, imaging, occluders)
    if field is None:
        return np.ones((0, 0), np.float32), (0, 0)
    su, sv = blur_sigma_px(camera, imaging, float(np.asarray(t, float)[2]))
    I = 1.0 - detected_deficit(field, su, sv)
    v0, u0 = field.origin
    H, W = imaging.image_shape
    return I[r0 - v0 : min(v0 + I.shape[0], H) - v0, c0 - u0 : min(u0 + I.shape[1], W) - u0], (r0, c0)


def detector_box(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera,
    imaging: ImagingModel,
    occluders: Sequence[Occluder] = (),
):
    """The fiducial's :class:`SubsampledField` with a margin wide enough for the blur, and the
    first image (row, col) of its box inside the image: ``(field, (row0, col0))``; ``(None,
    (0, 0))`` when the box misses the image."""
    H, W = imaging.image_shape
    su, sv = blur_sigma_px(camera, imaging, float(np.asarray(t, float)[2]))
    margin = int(math.ceil(4 * max(su, sv))) + 2
    field = line_integral_field(features, R, t, camera, imaging, occluders, margin)
    v0, u0 = field.origin
    r0, r1 = max(v0, 0), min(v0 + field.p.shape[0], H)
    c0, c1 = max(u0, 0), min(u0 + field.p.shape[1], W)
    if field.p.size == 0 or r0 >= r1 or c0 >= c1:
        return None, (0, 0)
    return field, (r0, c0)


def expected_transmission(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera = Camera(),
    imaging: ImagingModel = ImagingModel(),
    occluders: Sequence[Occluder] = (),
) -> np.ndarray:
    """Noise-free blurred transmission I/I0 (H, W) float32 of the fiducial alone (1 = no object)."""
    Ib, (r0, c0) = transmission_box(features, R, t, camera, imaging, occluders)
    out = np.ones(imaging.image_shape, np.float32)
    out[r0 : r0 + Ib.shape[0], c0 : c0 + Ib.shape[1]] = Ib
    return out


def window(image: np.ndarray, origin: tuple[int, int], shape: tuple[int, int]) -> np.ndarray:
    """The ``shape`` (h, w) window of ``image`` whose first pixel is (row, col) ``origin``; rows
    and columns outside the image repeat its nearest edge."""
    H, W = image.shape
    rows = np.clip(np.arange(origin[0], origin[0] + shape[0]), 0, H - 1)
    cols = np.clip(np.arange(origin[1], origin[1] + shape[1]), 0, W - 1)
    return image[np.ix_(rows, cols)]


def render(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera = Camera(),
    imaging: ImagingModel = ImagingModel(),
    rng: np.random.Generator | None = None,
    background: np.ndarray | None = None,
    occluders: Sequence[Occluder] = (),
    image_name: str = "",
) -> Radiograph:
    """A simulated radiograph of ``features`` at pose (R, t) (F → X, mm) — see the module.

    ``background`` (H, W) is a line-integral image (e.g. :func:`.background.anatomy`) added
    in the log domain; ``occluders`` are extra steel (or other) cylinders; the fiducial's body
    is ``features.body`` (None: wires and beads only). ``rng`` draws the noise (default: a fresh
    generator).
    """
    from .truth import truth_dict

    R, t = np.asarray(R, float), np.asarray(t, float)
    H, W = imaging.image_shape
    N0 = float(imaging.photons_per_px) if imaging.noisy else 1.0e4
    if background is None:
        line_integral = np.zeros((H, W))
        N = np.full((H, W), N0, np.float32)
    else:
        bg = np.asarray(background, np.float32)
        if bg.shape != (H, W):
            raise ValueError(f"background: an image of shape {(H, W)}, got {bg.shape}")
        line_integral = bg.astype(np.float64)
        N = np.exp(-bg) * np.float32(N0)
    field, (r0, c0) = detector_box(features, R, t, camera, imaging, occluders)
    if field is not None:
        # only the box holds the fiducial: the rest of the image is the flat field (or background)
        v0, u0 = field.origin
        h, w = field.p.shape
        su, sv = blur_sigma_px(camera, imaging, float(t[2]))
        D = detected_deficit(field, su, sv)[r0 - v0 : min(v0 + h, H) - v0, c0 - u0 : min(u0 + w, W) - u0]
        box = (slice(r0, r0 + D.shape[0]), slice(c0, c0 + D.shape[1]))
        # the background is an image as detected: it multiplies the detected fiducial
        line_integral[box] -= np.log1p(-D.astype(np.float64))
        N[box] *= 1.0 - D
    gain = imaging.raw_gain
    if imaging.noisy:
        rng = rng if rng is not None else np.random.default_rng()
        if float(N.min()) >= _GAUSSIAN_MIN_COUNTS:
            N += np.sqrt(N) * rng.standard_normal((H, W), dtype=np.float32)
        else:
            N = rng.poisson(N).astype(np.float32)
        raw = np.clip(np.rint(N * np.float32(gain)), 0, imaging.full_scale)
        log_image = np.log(np.float32(gain * N0) / np.maximum(raw, np.float32(0.5))).astype(np.float64)
    else:
        raw = np.clip(np.rint(N * np.float32(gain)), 0, imaging.full_scale)
        log_image = line_integral.copy()
    raw = raw.astype(np.uint8 if imaging.bit_depth <= 8 else np.uint16)
    truth = truth_dict(
        features,
        R,
        t,
        camera,
        imaging,
        image_name=image_name,
        occluders=occluders,
        background=None if background is None else "given",
    )
    return Radiograph(line_integral, log_image, raw, camera, R, t, truth)
