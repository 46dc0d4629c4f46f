"""The radiograph simulator: Beer–Lambert line integrals of the fiducial at a pose.

Image formation, in order:

1. **Line integral** ``p(u, v) = Σ μ_m × chord_m`` through the beads (spheres), the wires
   (tube pieces, :mod:`.geometry`), the body (hollow cylinder) and any occluders, evaluated
   only inside the fiducial's bounding box. Wherever ``p`` is not smooth (every pixel a
   wire or bead touches, and body pixels whose 4-neighbour Laplacian exceeds
   ``BODY_ROUGHNESS``, with their neighbours) the pixel value is the mean of
   ``supersample²`` sub-samples — pixel integration, so feature centres carry no aliasing
   bias (4 × 4 vs 16 × 16: a blurred bead's centroid moves ≤ 0.005 px, a wire's profile
   centre ≤ 0.007 px); elsewhere the pixel centre (midpoint rule, error ≈ Laplacian / 24
   < 4e-4).
   Steel that fills a groove is not reduced by the acetal it displaces (0.3 % of its
   contrast), and grooves/pockets are not cut from the body.
2. **Blur**, applied to the intensity ``exp(−p)`` (both blurs act on photons): a Gaussian of
   σ² = σ_detector² + σ_focal², σ_focal = (M − 1) × focal spot / 2.355 / pixel pitch with
   M = f / Z of the fiducial origin (the ±2 % change of M across the fiducial is neglected).
3. **Background**: an anatomy line-integral image added in the log domain (multiplies the
   intensity); it is taken as already blurred.
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
from typing import Sequence

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..features.model import Features
from ..pose.camera import Camera
from .geometry import Pieces, body_chord_uv, sphere_chord, straight_pieces, tube_chord_uv
from .model import Body, ImagingModel, Occluder, Radiograph
from .rays import BODY_ROUGHNESS, Rays, capsule_pixels, feature_pieces, project_points, subsample_offsets

#: Gaussian counts are used when every expected count is at least this
_GAUSSIAN_MIN_COUNTS = 100.0

AUTO = "auto"

def _occluder_pieces(occluders: Sequence[Occluder], imaging: ImagingModel, R: np.ndarray, t: np.ndarray) -> Pieces:
    parts = []
    for k, oc in enumerate(occluders):
        a, b = np.asarray(oc.start, float), np.asarray(oc.end, float)
        if oc.frame == "X":
            a, b = R.T @ (a - t), R.T @ (b - t)
        parts.append(straight_pieces(a, b, oc.diameter / 2, imaging.mu(oc.material), -1 - k))
    return Pieces.concat(parts)


def resolve_body(features: Features, body) -> Body | None:
    """The body to render: ``body`` itself, None, or for ``"auto"`` the body of the design
    named in ``features.source`` when that file can be found (else None)."""
    if body is None or isinstance(body, Body):
        return body
    if body != AUTO:
        raise TypeError("body: a Body, None or 'auto'")
    from .scene import body_from_source
    return body_from_source(features.source)


def line_integral_box(features: Features, R: np.ndarray, t: np.ndarray, camera: Camera, imaging: ImagingModel,
                      body: Body | None, occluders: Sequence[Occluder] = (), margin_px: int = 0):
    """Un-blurred, pixel-integrated line integral over the fiducial's bounding box.

    Returns ``(p, (v0, u0))``: ``p`` (h, w) float64 whose pixel ``p[j, i]`` is image pixel
    (row v0 + j, column u0 + i); the box is not clipped to the image. ``margin_px`` widens it.
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

    groups = []          # (rows, cols, values) of supersampled primitives
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
            val = ch.mean(1) * pieces.mu[k]
            groups.append((rows, cols, val))
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
        groups.append((rows, cols, ch.reshape(-1, s * s).mean(1) * mu_steel))
        lo.append([rows.min(), cols.min()])
        hi.append([rows.max(), cols.max()])
    body_box = None
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
        return np.zeros((0, 0)), (0, 0)
    v0, u0 = np.min(lo, 0) - margin_px
    v1, u1 = np.max(hi, 0) + margin_px
    hgt, wid = int(v1 - v0 + 1), int(u1 - u0 + 1)
    acc = np.zeros(hgt * wid)
    for rows, cols, val in groups:
        acc += np.bincount((rows - v0) * wid + (cols - u0), weights=val, minlength=hgt * wid)
    p = acc.reshape(hgt, wid)
    if body_box is not None:
        _add_body(p, (v0, u0), body_box, body, imaging.mu(body.material), rays, s, fdt)
    return p, (int(v0), int(u0))


def _body_values(rays: Rays, U: np.ndarray, V: np.ndarray, body: Body, mu: float,
                 dtype=np.float64) -> np.ndarray:
    c, g0, gu, gv = (np.asarray(x, dtype) for x in (rays.c, rays.g0, rays.gu, rays.gv))
    return mu * body_chord_uv(c, g0, gu, gv, body.outer_diameter / 2, body.bore_diameter / 2, body.length / 2,
                              np.asarray(U, dtype), np.asarray(V, dtype))


def _add_body(p: np.ndarray, origin, box, body: Body, mu: float, rays: Rays, s: int, fdt=np.float32) -> None:
    (bu0, bv0), (bu1, bv1) = box
    v0, u0 = origin
    cu = np.arange(bu0, bu1 + 1, dtype=float)
    cv = np.arange(bv0, bv1 + 1, dtype=float)
    # float32 (single_precision): the body's μ is small, so rounding (worst at the
    # silhouettes, where R²A − (m√A)² cancels) stays below 1e-4 in p
    centre = _body_values(rays, cu[None, :], cv[:, None], body, mu, fdt).astype(np.float64)
    lap = np.zeros_like(centre)
    lap[1:-1, 1:-1] = (centre[:-2, 1:-1] + centre[2:, 1:-1] + centre[1:-1, :-2] + centre[1:-1, 2:]
                       - 4 * centre[1:-1, 1:-1])
    rough = np.abs(lap) > BODY_ROUGHNESS
    flag = rough.copy()
    flag[1:, :] |= rough[:-1, :]
    flag[:-1, :] |= rough[1:, :]
    flag[:, 1:] |= rough[:, :-1]
    flag[:, :-1] |= rough[:, 1:]
    jj, ii = np.nonzero(flag)
    if len(jj):
        ou, ov = subsample_offsets(s)
        centre[jj, ii] = _body_values(rays, cu[ii][:, None] + ou, cv[jj][:, None] + ov, body, mu, fdt).mean(1)
    p[bv0 - v0:bv1 - v0 + 1, bu0 - u0:bu1 - u0 + 1] += centre


def blur_sigma_px(camera: Camera, imaging: ImagingModel, depth_mm: float) -> tuple[float, float]:
    """Total Gaussian σ (σ_u, σ_v) in pixels: detector line-spread and focal spot at magnification f / depth."""
    M = camera.focal_length_mm / depth_mm
    fs = max(M - 1.0, 0.0) * imaging.focal_spot_mm / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    su = math.hypot(imaging.detector_blur_px, fs / camera.pixel_size_mm[0])
    sv = math.hypot(imaging.detector_blur_px, fs / camera.pixel_size_mm[1])
    return su, sv


def transmission_box(features: Features, R: np.ndarray, t: np.ndarray, camera: Camera, imaging: ImagingModel,
                     body: Body | None, occluders: Sequence[Occluder] = ()):
    """Noise-free blurred transmission I/I0 of the fiducial over its bounding box, clipped to
    the image: ``(I (h, w) float32, (row0, col0))``; outside the box I = 1. Empty box: (0, 0) array."""
    H, W = imaging.image_shape
    su, sv = blur_sigma_px(camera, imaging, float(np.asarray(t, float)[2]))
    margin = int(math.ceil(4 * max(su, sv))) + 2
    p, (v0, u0) = line_integral_box(features, R, t, camera, imaging, body, occluders, margin)
    r0, r1 = max(v0, 0), min(v0 + p.shape[0], H)
    c0, c1 = max(u0, 0), min(u0 + p.shape[1], W)
    if p.size == 0 or r0 >= r1 or c0 >= c1:
        return np.ones((0, 0), np.float32), (0, 0)
    I = np.exp(-p).astype(np.float32)
    if sv > 0:
        I = gaussian_filter1d(I, sv, axis=0, mode="nearest", truncate=4.0)
    if su > 0:
        I = gaussian_filter1d(I, su, axis=1, mode="nearest", truncate=4.0)
    return I[r0 - v0:r1 - v0, c0 - u0:c1 - u0], (r0, c0)


def expected_transmission(features: Features, R: np.ndarray, t: np.ndarray, camera: Camera = Camera(),
                          imaging: ImagingModel = ImagingModel(), body: Body | None | str = AUTO,
                          occluders: Sequence[Occluder] = ()) -> np.ndarray:
    """Noise-free blurred transmission I/I0 (H, W) float32 of the fiducial alone (1 = no object)."""
    body = resolve_body(features, body)
    Ib, (r0, c0) = transmission_box(features, R, t, camera, imaging, body, occluders)
    out = np.ones(imaging.image_shape, np.float32)
    out[r0:r0 + Ib.shape[0], c0:c0 + Ib.shape[1]] = Ib
    return out


def render(features: Features, R: np.ndarray, t: np.ndarray, camera: Camera = Camera(),
           imaging: ImagingModel = ImagingModel(), rng: np.random.Generator | None = None,
           background: np.ndarray | None = None, occluders: Sequence[Occluder] = (),
           body: Body | None | str = AUTO, image_name: str = "") -> Radiograph:
    """A simulated radiograph of ``features`` at pose (R, t) (F → X, mm) — see the module.

    ``background`` (H, W) is a line-integral image (e.g. :func:`.background.anatomy`) added
    in the log domain; ``occluders`` are extra steel (or other) cylinders; ``body`` is the
    fiducial's body (``"auto"``: from the design named in ``features.source`` if found,
    ``None``: wires and beads only). ``rng`` draws the noise (default: a fresh generator).
    """
    from .truth import truth_dict

    R, t = np.asarray(R, float), np.asarray(t, float)
    H, W = imaging.image_shape
    body = resolve_body(features, body)
    Ib, (r0, c0) = transmission_box(features, R, t, camera, imaging, body, occluders)
    box = (slice(r0, r0 + Ib.shape[0]), slice(c0, c0 + Ib.shape[1]))
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
    # only the box holds the fiducial: the rest of the image is the flat field (or background)
    line_integral[box] -= np.log(Ib.astype(np.float64))
    N[box] *= Ib
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
    truth = truth_dict(features, R, t, camera, imaging, image_name=image_name, body=body, occluders=occluders,
                       background=None if background is None else "given")
    return Radiograph(line_integral, log_image, raw, camera, R, t, truth)
