"""Intensifier distortion from one image of a regular bead grid (a dewarping plate).

Steps:

1. **Beads.** The image becomes a density image (:func:`ftrac_design.segment.image.to_density`, polarity detected
   or given), its background is removed by a top-hat and every blob at the bead scale is fitted
   with the blurred-sphere model (:mod:`ftrac_design.segment.beads`). The bead radius is measured when not given
   (scale selection on the scale-normalised Laplacian). A round intensifier field is found as
   the bright (dense) surround of the opened background, when one stands out; beads whose
   fitting patch leaves the field or the image are dropped (a bead cut by the edge has a
   biased centre).
2. **Indexing.** The lattice's direction and pitch come from the beads' nearest-neighbour
   vectors (their angles folded modulo 90°); a bead near the image centre with its four
   neighbours in place seeds a breadth-first growth that predicts each neighbour by linear
   extrapolation from the beads already indexed (so the local pitch and direction follow the
   distortion) and takes the nearest bead within 0.3 pitch; a missing bead is stepped over
   (two pitches). Blobs off the lattice (clutter, dust) are never reached.
3. **Fit.** The plate's pose relative to the detector is unknown, so the ideal grid is known
   only up to a projective map: the model is q = D(H(i, j)), H a homography from the lattice
   indices to ideal pixels and D the distortion polynomial (ideal → distorted). The two are
   separated by a **gauge**: D's constant and linear parts at the image centre are the identity
   (the ideal image agrees with the distorted one to first order at the centre: same scale,
   orientation and position there), and D's quadratic part is L²-orthogonal, over the disc of
   the model's scale, to the two displacement fields a tilt of the plate adds to second order,
   p (g · p) — a plate tilt and an even distortion term look alike to second order, and the
   tilt takes them. H and D are fitted together (``scipy.optimize.least_squares``, a soft-L1
   loss first), then beads whose residual exceeds 5 robust σ are dropped and the fit redone
   by plain least squares.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from scipy.linalg import null_space
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from ..errors import InputError
from ..images.distortion import DistortionModel, design_matrix, identity_coefficients, monomial_exponents, n_terms
from ..segment.beads import blob_candidates, fit_beads, fit_patch_half_px
from ..segment.image import derivatives, detect_polarity, noise_sigma, to_density, top_hat

Polarity = Literal["auto", "dense-dark", "dense-bright"]

#: expected blur σ of a bead's image (px), the starting value of the fit
_BLUR_PX = 0.8
#: a neighbour is taken within this fraction of the pitch of its predicted place
_MATCH_TOL = 0.3
#: the bead fit's noise (its robust weights' scale) in units of the measured noise
_ROBUST_SCALE = 4.0


@dataclass(frozen=True)
class GridBeads:
    """Beads found on a grid image: centres ``uv`` (n, 2) px, fitted ``radius`` (n,) px, the
    polarity used, the beads' median fitted radius (px), whether a round field was found and
    how many blob candidates were fitted."""

    uv: np.ndarray
    radius: np.ndarray
    polarity: str
    bead_radius_px: float
    field_found: bool
    n_candidates: int


@dataclass(frozen=True)
class GridReport:
    """What :func:`estimate_distortion` measured. Arrays are per indexed bead (n rows):
    ``index`` (n, 2) lattice indices (i along the first lattice direction, j the second),
    ``detected_px`` the fitted centres, ``ideal_px`` H(i, j), ``fitted_px`` D(H(i, j)),
    ``used`` whether the bead survived the outlier test. ``residual_*`` are |detected − fitted|
    over the used beads, px and mm at the detector (× ``pixel_mm``). ``homography`` maps
    homogeneous (i, j, 1) to ideal pixels."""

    n_detected: int
    n_indexed: int
    n_used: int
    pitch_px: float
    bead_radius_px: float
    polarity: str
    field_found: bool
    rms_px: float
    max_px: float
    rms_mm: float
    max_mm: float
    index: np.ndarray
    detected_px: np.ndarray
    ideal_px: np.ndarray
    fitted_px: np.ndarray
    used: np.ndarray
    homography: np.ndarray

    def summary(self) -> str:
        """One paragraph for the command line."""
        return (
            f"{self.n_used} beads used ({self.n_indexed} indexed of {self.n_detected} detected; "
            f"pitch {self.pitch_px:.2f} px, bead radius {self.bead_radius_px:.2f} px, {self.polarity}"
            f"{', round field' if self.field_found else ''}); residual RMS {self.rms_px:.3f} px "
            f"({self.rms_mm:.4f} mm), max {self.max_px:.3f} px ({self.max_mm:.4f} mm)"
        )


# -- step 1: beads ----------------------------------------------------------------------


def _bead_scale(th: np.ndarray, pitch_px: float, expected: int) -> float:
    """Bead radius (px) by scale selection: the σ whose scale-normalised Laplacian −σ²∇²g is
    largest at the strongest ``expected`` local maxima; r = √2 σ (a disc's best scale)."""
    best, best_sigma = -np.inf, 1.0
    se = np.ones((3, 3), np.uint8)
    for sigma in np.geomspace(0.6, max(pitch_px / 5, 0.8), 12):
        d = derivatives(th, float(sigma), first=False)
        resp = -(d["xx"] + d["yy"]) * float(sigma * sigma)
        peaks = resp[(resp >= cv2.dilate(resp, se)) & (resp > 0)]
        if len(peaks) == 0:
            continue
        k = min(len(peaks), max(expected, 1))
        score = float(np.median(np.partition(peaks, -k)[-k:]))
        if score > best:
            best, best_sigma = score, float(sigma)
    return best_sigma * math.sqrt(2.0)


def _field_mask(bg: np.ndarray) -> np.ndarray | None:
    """The round intensifier field: where the opened density is well below a bright (dense)
    surround, when there is one (Otsu's split, accepted only if the surround covers ≥ 2 % of
    the image and stands ≥ 8 robust σ of the field's own variation above it)."""
    from skimage.filters import threshold_otsu

    small = np.asarray(bg[::4, ::4], float)
    t = threshold_otsu(small)
    lo, hi = small[small < t], small[small >= t]
    if hi.size < 0.02 * small.size or lo.size < 0.2 * small.size:
        return None
    spread = 1.4826 * float(np.median(np.abs(lo - np.median(lo))))
    if float(np.median(hi) - np.median(lo)) < 8 * max(spread, 1e-12):
        return None
    mask = (bg < t).astype(np.uint8)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=4)
    if n <= 1:
        return None
    keep = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return lab == keep


def find_grid_beads(
    image: np.ndarray, pitch_px: float, polarity: Polarity = "auto", bead_radius_px: float | None = None
) -> GridBeads:
    """Bead centres (px) on a grid image (see the module, step 1). ``pitch_px`` is the expected
    lattice pitch in pixels (only to size the filters); ``bead_radius_px`` the expected bead
    radius in the image (measured when None)."""
    img = np.asarray(image, np.float32)
    H, W = img.shape
    wide = max(3, int(round(0.45 * pitch_px)))
    if polarity == "auto":
        polarity = detect_polarity(img, max(2, int(round(bead_radius_px or pitch_px / 6))))
    g = to_density(img, polarity)
    th_wide = top_hat(g, wide)
    field = _field_mask(g - th_wide)
    expected = max(int(H * W / pitch_px**2 * (0.7 if field is not None else 1.0)), 4)
    if bead_radius_px is None:
        probe = th_wide if field is None else np.where(field, th_wide, 0).astype(np.float32)
        bead_radius_px = _bead_scale(probe, pitch_px, expected // 2)
    r = float(bead_radius_px)
    disc = max(int(math.ceil(r + 3 * _BLUR_PX + 2)), 3)
    th = top_hat(g, disc) if disc < wide else th_wide
    half = fit_patch_half_px(r, _BLUR_PX)
    inside = np.ones((H, W), bool)
    if field is not None:
        dist = cv2.distanceTransform(field.astype(np.uint8), cv2.DIST_L2, 5)
        # a bead is kept only if its whole fitting patch (and 3 px of the edge's blur) lies in
        # the field; the surround takes the field's median top-hat level, so that its noise
        # makes no blobs and no step remains at the edge for a fit to see
        inside = dist >= half + 3
        th = np.where(field, th, np.median(th[field])).astype(np.float32)
        # the noise of the field alone: a square well inside it (the zeros outside would
        # lower the estimate, the dark surround's noise raise it)
        vs, us = np.nonzero(inside)
        cv, cu, h = int(vs.mean()), int(us.mean()), max(int(0.6 * math.sqrt(len(vs) / math.pi)), 4)
        noise = max(noise_sigma(th[max(cv - h, 0) : cv + h, max(cu - h, 0) : cu + h]), 1e-12)
    else:
        noise = noise_sigma(th)
    # a noise-free (synthetic) image: the fit's robust weights need a non-zero scale
    noise = max(noise, 1e-3 * float(np.percentile(th, 99.9)), 1e-12)
    cand, resp = blob_candidates(th, r, noise, 2 * expected + 50, 8.0)
    # the plate has no wires for the fit's robust (Tukey) weights to reject, and their scale is
    # pooled over all the beads fitted together: on a resampled image (an intensifier's, or
    # one already undistorted) it cut the cores of beads that depart from the sphere model
    # and dragged a few by up to 1 px. Four times the noise keeps every pixel of a bead in
    # (the priors' weights, ∝ noise², are scaled back by 1/16).
    k = _ROBUST_SCALE
    beads = fit_beads(th, cand, r, _BLUR_PX, k * noise, resp, prior_scale=1 / k**2)
    if len(beads):
        med = float(np.median(beads.radius))
        beads = fit_beads(
            th, beads.uv, med, float(np.median(beads.blur)), k * noise, beads.response, prior_scale=1 / k**2
        )
    uv = beads.uv
    ok = np.all(np.isfinite(uv), 1) & np.isfinite(beads.sigma_px) & (beads.amplitude > 0)
    ok &= (uv[:, 0] >= half) & (uv[:, 0] <= W - 1 - half) & (uv[:, 1] >= half) & (uv[:, 1] <= H - 1 - half)
    iu = np.clip(np.round(uv[:, 0]).astype(int), 0, W - 1)
    iv = np.clip(np.round(uv[:, 1]).astype(int), 0, H - 1)
    ok &= inside[iv, iu]
    rad = float(np.median(beads.radius[ok])) if ok.any() else r
    return GridBeads(uv[ok], beads.radius[ok], polarity, rad, field is not None, len(cand))


# -- step 2: indexing -------------------------------------------------------------------


def lattice_vectors(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The square lattice's two step vectors (px) and pitch from the beads' nearest-neighbour
    vectors: pitch = the median nearest-neighbour distance; direction = the mean of the
    neighbour vectors' angles folded modulo 90° (4θ averaged on the circle)."""
    tree = cKDTree(uv)
    d, j = tree.query(uv, k=min(5, len(uv)))
    pitch = float(np.median(d[:, 1]))
    vec = uv[j[:, 1:]] - uv[:, None, :]
    dist = d[:, 1:]
    sel = (dist > 0.7 * pitch) & (dist < 1.3 * pitch)
    ang = np.arctan2(vec[..., 1], vec[..., 0])[sel]
    theta = float(np.angle(np.mean(np.exp(4j * ang)))) / 4
    a = pitch * np.array([math.cos(theta), math.sin(theta)])
    b = pitch * np.array([-math.sin(theta), math.cos(theta)])
    return a, b, pitch


def index_grid(uv: np.ndarray, centre: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, float]:
    """Lattice indices (n, 2) of beads ``uv`` (n, 2) px, whether each bead is on the lattice
    grown from a seed near ``centre`` (n,) bool (see the module, step 2), and the pitch (px).
    Indices are relative to the seed (0, 0) and may be negative; off-lattice rows are 0."""
    n = len(uv)
    idx = np.zeros((n, 2), int)
    on = np.zeros(n, bool)
    if n < 5:
        return idx, on, float("nan")
    a, b, pitch = lattice_vectors(uv)
    tree = cKDTree(uv)
    tol = _MATCH_TOL * pitch
    steps = {(1, 0): a, (-1, 0): -a, (0, 1): b, (0, -1): -b}

    def nearest(p: np.ndarray) -> int | None:
        d, k = tree.query(p)
        return int(k) if d <= tol else None

    seed = None
    for k in np.argsort(np.hypot(*(uv - np.asarray(centre)).T))[:50]:
        if sum(nearest(uv[k] + s) is not None for s in steps.values()) >= 3:
            seed = int(k)
            break
    if seed is None:
        return idx, on, pitch
    at: dict[tuple[int, int], int] = {(0, 0): seed}
    on[seed] = True
    queue = deque([seed])
    while queue:
        k = queue.popleft()
        i, j = idx[k]
        for (di, dj), fallback in steps.items():
            step = _local_step(uv, at, (i, j), (di, dj), fallback)
            for mult in (1, 2):
                t = (i + mult * di, j + mult * dj)
                if t in at:
                    break
                m = nearest(uv[k] + mult * step)
                if m is None:
                    continue
                if not on[m]:
                    idx[m], on[m] = t, True
                    at[t] = m
                    queue.append(m)
                break
    return idx, on, pitch


def _local_step(uv: np.ndarray, at: dict, ij: tuple[int, int], e: tuple[int, int], fallback: np.ndarray) -> np.ndarray:
    """The lattice step along index direction ``e`` at index ``ij``: from the bead behind
    (linear extrapolation), else from a side neighbour's step, else ``fallback``."""
    i, j = ij
    back = at.get((i - e[0], j - e[1]))
    if back is not None:
        return uv[at[ij]] - uv[back]
    for f in ((e[1], e[0]), (-e[1], -e[0])):
        s0, s1 = at.get((i + f[0], j + f[1])), at.get((i + f[0] + e[0], j + f[1] + e[1]))
        if s0 is not None and s1 is not None:
            return uv[s1] - uv[s0]
    return fallback


# -- step 3: the fit --------------------------------------------------------------------


def gauge_basis(degree: int) -> np.ndarray:
    """Columns spanning D's free coefficients (terms of degree ≥ 2 of u then v) under the
    gauge: L²-orthogonal over the unit disc to the tilt fields (x², xy) and (xy, y²), i.e.
    3 a₂₀ + a₀₂ + b₁₁ = 0 and a₁₁ + b₂₀ + 3 b₀₂ = 0 (∫x⁴ = 3 ∫x²y² over a disc)."""
    e = [tuple(t) for t in monomial_exponents(degree)][3:]
    m = len(e)
    if degree < 2:
        return np.zeros((0, 0))
    C = np.zeros((2, 2 * m))
    pos = {t: k for k, t in enumerate(e)}
    C[0, pos[(2, 0)]], C[0, pos[(0, 2)]], C[0, m + pos[(1, 1)]] = 3, 1, 1
    C[1, pos[(1, 1)]], C[1, m + pos[(2, 0)]], C[1, m + pos[(0, 2)]] = 1, 1, 3
    return null_space(C)


def _coefficients(z: np.ndarray, basis: np.ndarray, degree: int) -> np.ndarray:
    a, b = identity_coefficients(degree)
    coef = np.stack([a, b], -1)
    if basis.size:
        w = basis @ z
        m = n_terms(degree) - 3
        coef[3:, 0] += w[:m]
        coef[3:, 1] += w[m:]
    return coef


def _homography(h: np.ndarray, n: np.ndarray) -> np.ndarray:
    Hm = np.append(h, 1.0).reshape(3, 3)
    w = np.c_[n, np.ones(len(n))] @ Hm.T
    return w[:, :2] / w[:, 2:3]


def fit_grid(
    index: np.ndarray, detected: np.ndarray, model: DistortionModel, robust: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit q = D(H(i, j)) (see the module, step 3) to beads at lattice ``index`` (n, 2) seen at
    ``detected`` (n, 2) px, D in ``model``'s normalisation and degree. Returns D's coefficients
    (n_terms, 2), the homography (3 × 3, index → ideal px) and the ideal pixels H(i, j) (n, 2).

    With one BLAS thread: the least-squares problems are small (~1300 × 42), and with the
    cores busy a multi-threaded BLAS took 0.6 s for one SVD instead of a millisecond (an
    estimate 11.5 s instead of 0.55 s)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, "blas"):
        return _fit_grid(index, detected, model, robust)


def _fit_grid(
    index: np.ndarray, detected: np.ndarray, model: DistortionModel, robust: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`fit_grid`'s work."""
    c, s = np.asarray(model.centre_px), model.scale_px
    qn = (detected - c) / s
    mu, sd = index.mean(0), float(index.std()) or 1.0
    n = (index - mu) / sd
    H0, _ = cv2.findHomography(n.astype(np.float64), qn.astype(np.float64), 0)
    H0 = H0 / H0[2, 2]
    basis = gauge_basis(model.degree)
    p0 = np.r_[H0.ravel()[:8], np.zeros(basis.shape[1])]

    def residual(p: np.ndarray) -> np.ndarray:
        x = _homography(p[:8], n)
        coef = _coefficients(p[8:], basis, model.degree)
        return (s * (design_matrix(x[:, 0], x[:, 1], model.degree) @ coef - qn)).ravel()

    sol = least_squares(residual, p0, loss="soft_l1" if robust else "linear", f_scale=0.5, x_scale="jac", method="trf")
    p = sol.x
    coef = _coefficients(p[8:], basis, model.degree)
    # homography in pixels: ideal = c + s · Hn((index − mu) / sd)
    Hn = np.append(p[:8], 1.0).reshape(3, 3)
    to_n = np.array([[1 / sd, 0, -mu[0] / sd], [0, 1 / sd, -mu[1] / sd], [0, 0, 1]])
    to_px = np.array([[s, 0, c[0]], [0, s, c[1]], [0, 0, 1]])
    Hpx = to_px @ Hn @ to_n
    return coef, Hpx / Hpx[2, 2], c + s * _homography(p[:8], n)


def parameter_count(degree: int) -> int:
    """Unknowns of the joint fit: 8 (homography) + D's free coefficients under the gauge."""
    return 8 + (2 * (n_terms(degree) - 3) - 2 if degree >= 2 else 0)


def estimate_distortion(
    image: np.ndarray,
    pitch_mm: float,
    pixel_mm: float,
    *,
    polarity: Polarity = "auto",
    degree: int = 5,
    bead_diameter_mm: float | None = None,
    origin: str | None = None,
) -> tuple[DistortionModel, GridReport]:
    """Distortion model (ideal → distorted px) of the image-intensifier from one ``image`` (H, W)
    of a regular square bead grid of pitch ``pitch_mm`` (see the module).

    ``pixel_mm`` is the detector's pixel pitch (mm); with the plate on the intensifier's face
    (magnification ≈ 1) ``pitch_mm / pixel_mm`` and ``bead_diameter_mm / pixel_mm`` size the
    filters (the true magnification is fitted); residuals are reported in px and in mm at the
    detector. ``bead_diameter_mm`` None: the bead size is measured on the image. ``origin``
    names the image in errors.

    Returns the model (centre: the image centre; scale max(H, W)/2; support: the used beads'
    farthest distance from the centre, plus half a pitch) and a :class:`GridReport`. Raises
    InputError on bad arguments and when too few beads are indexed for ``degree``: at least
    1.5 × the fit's unknowns (:func:`parameter_count`: 42 for degree 5, so 63 beads).
    """
    _check_args(image, pitch_mm, pixel_mm, degree, bead_diameter_mm, polarity, origin)
    img = np.asarray(image, float)
    pitch_px = pitch_mm / pixel_mm
    found = find_grid_beads(
        img, pitch_px, polarity, None if bead_diameter_mm is None else bead_diameter_mm / 2 / pixel_mm
    )
    model = DistortionModel.identity(img.shape, degree)
    need = int(math.ceil(1.5 * parameter_count(degree)))
    idx, on, pitch = index_grid(found.uv, model.centre_px)
    # the lattice must span the degree in both directions, not only hold enough beads
    span = min(len(np.unique(idx[on, 0])), len(np.unique(idx[on, 1])))
    if on.sum() < need or span < degree + 1:
        raise InputError(
            origin,
            "image",
            f"a bead-grid image with at least {need} grid beads, in at least "
            f"{degree + 1} rows and columns, indexed for a degree-{degree} fit; "
            f"found {int(on.sum())} in {span} ({len(found.uv)} beads detected)",
        )
    index, det = idx[on].astype(float), found.uv[on]
    coef, Hpx, used = _fit_dropping_outliers(index, det, model, need)
    ideal = np.c_[index, np.ones(len(index))] @ Hpx.T
    ideal = ideal[:, :2] / ideal[:, 2:3]
    fitted = _apply(model, coef, Hpx, index)
    err = np.hypot(*(det - fitted)[used].T)
    rms, mx = float(np.sqrt(np.mean(err**2))), float(err.max())
    support = float(np.max(np.hypot(*(det[used] - np.asarray(model.centre_px)).T))) + pitch / 2
    model = model.with_coefficients(
        coef[:, 0],
        coef[:, 1],
        rms_residual_px=rms,
        max_residual_px=mx,
        support_radius_px=support,
        source=f"bead grid{' ' + str(origin) if origin else ''}: pitch {pitch_mm:g} mm, {int(used.sum())} beads, "
        f"pixel {pixel_mm:g} mm",
    )
    report = GridReport(
        len(found.uv),
        int(on.sum()),
        int(used.sum()),
        pitch,
        found.bead_radius_px,
        found.polarity,
        found.field_found,
        rms,
        mx,
        rms * pixel_mm,
        mx * pixel_mm,
        index.astype(int),
        det,
        ideal,
        fitted,
        used,
        Hpx,
    )
    return model, report


def _fit_dropping_outliers(
    index: np.ndarray, det: np.ndarray, model: DistortionModel, need: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A robust (soft-L1) fit first, then plain least squares without the beads beyond 5 σ (σ
    per axis from the median residual, Rayleigh), until the set of beads settles; returns the
    coefficients, the homography and the beads used."""
    used, robust = np.ones(len(det), bool), True
    for _ in range(6):
        coef, Hpx, _ = fit_grid(index[used], det[used], model, robust)
        err = np.hypot(*(det - _apply(model, coef, Hpx, index)).T)
        new = err <= max(5 * float(np.median(err[used])) / math.sqrt(math.log(4.0)), 1e-3)
        if new.sum() < need or (not robust and np.array_equal(new, used)):
            break
        used, robust = new, False
    else:
        coef, Hpx, _ = fit_grid(index[used], det[used], model, robust=False)
    return coef, Hpx, used


def _apply(model: DistortionModel, coef: np.ndarray, Hpx: np.ndarray, index: np.ndarray) -> np.ndarray:
    w = np.c_[index, np.ones(len(index))] @ Hpx.T
    ideal = w[:, :2] / w[:, 2:3]
    return model.with_coefficients(coef[:, 0], coef[:, 1]).distort(ideal)


def _check_args(image, pitch_mm, pixel_mm, degree, bead_diameter_mm, polarity, origin) -> None:
    img = np.asarray(image)
    if img.ndim != 2 or min(img.shape) < 16:
        raise InputError(origin, "image", f"a 2-D grey-scale image of at least 16 × 16 pixels, got shape {img.shape}")
    if not np.issubdtype(img.dtype, np.number) or np.iscomplexobj(img) or not np.all(np.isfinite(img)):
        raise InputError(origin, "image", f"finite, real, numeric pixel values (got {img.dtype})")
    for key, v in (("pitch_mm", pitch_mm), ("pixel_mm", pixel_mm)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(origin, key, f"a positive number of millimetres, got {v!r}")
    if bead_diameter_mm is not None and not (math.isfinite(bead_diameter_mm) and 0 < bead_diameter_mm < pitch_mm):
        raise InputError(origin, "bead_diameter_mm", "a positive number of millimetres smaller than the pitch")
    if pitch_mm / pixel_mm < 4:
        raise InputError(
            origin, "pitch_mm", f"a grid pitch of at least 4 pixels (pitch / pixel = {pitch_mm / pixel_mm:.3g})"
        )
    if pitch_mm / pixel_mm > min(img.shape) / 4:
        raise InputError(
            origin,
            "pitch_mm",
            f"a grid pitch of at most a quarter of the image "
            f"({min(img.shape) // 4} px; pitch / pixel = {pitch_mm / pixel_mm:.3g})",
        )
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or not 1 <= degree <= 8:
        raise InputError(origin, "degree", f"an integer 1–8, got {degree!r}")
    if polarity not in ("auto", "dense-dark", "dense-bright"):
        raise InputError(origin, "polarity", f"auto, dense-dark or dense-bright, got {polarity!r}")
