"""Bead centres by a model fit of the blurred sphere projection.

A steel ball of radius r (px at the detector) projects to the chord profile
``2 √(r² − ρ²)`` (times μ), which the focal spot, the detector and the pixel area blur;
with a Gaussian blur of σ the radial profile is

    S(ρ) = ∫₀^r 2√(r² − ρ'²) · (ρ'/σ²) · exp(−(ρ² + ρ'²)/2σ²) · I₀(ρρ'/σ²) dρ'

(the 2-D convolution of a radial function with a Gaussian, Hankel form). With ρ' = r sin φ
the integrand is smooth on [0, π/2]; 16 Gauss–Legendre nodes give it to < 1e-3 relative for σ ≥ r/10.
Each candidate blob is fitted with ``b₀ + bₓ x + b_y y + A · S(|p − c|; r, σ)`` — centre c,
radius, blur, amplitude and a planar background — by Levenberg–Marquardt on the tabulated
profile's own slopes, iteratively reweighted with Tukey's biweight so that a wire butting
against the ball, or one passing under it, is treated as an outlier instead of pulling the
centre (a thresholded centroid, or an unweighted fit, moves toward the wire). All candidates
are fitted together (vectorised). Pixels clipped on the dense side are censored: the ball
there is at least as dense as they show. Where a pose says what lies under the balls — a
wire blurred into a band as wide as the ball, which the weights cannot reject — that shape
is fitted with them, its amplitude one more parameter (``background``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import i0e, roots_legendre

from .image import gaussian_kernels

_PHI, _WPHI = roots_legendre(16)
_PHI = (_PHI + 1) * np.pi / 4
_WPHI = _WPHI * np.pi / 4


def sphere_profile(rho: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Blurred sphere chord profile S(ρ; r, σ) (px units; peak 2r when σ → 0).
    ``rho`` (..., n), ``r`` and ``s`` (...,) broadcast against the leading axes."""
    r = np.asarray(r, float)[..., None, None]
    s = np.asarray(s, float)[..., None, None]
    rho = np.asarray(rho, float)[..., None]
    rp = r * np.sin(_PHI)
    c = r * np.cos(_PHI)
    z = rho * rp / (s * s)
    integrand = 2 * c * c * rp / (s * s) * np.exp(-0.5 * (rho - rp) ** 2 / (s * s)) * i0e(z)
    return integrand @ _WPHI if integrand.ndim == 1 else np.einsum("...k,k->...", integrand, _WPHI)


#: table of the unit-blur profile Ŝ(x; a) = S(x; a, 1) on x = ρ/σ ∈ [0, 48] (step 0.05; 0 beyond)
#: and ln a = ln(r/σ) ∈ [ln 0.2, ln 32] (160 rows); S(ρ; r, σ) = σ Ŝ(ρ/σ; r/σ) since
#: every length scales together. Built on first use (~0.2 s).
_TAB_DX = 0.05
_TAB_LA = (math.log(0.2), math.log(32.0), 160)
_tab: np.ndarray | None = None
#: the table as :func:`bilinear_table` reads it (float, flat, one zero after the last cell),
#: made once: remaking it on every look-up cost more than the look-up itself
_tab_flat: np.ndarray | None = None


def _table() -> np.ndarray:
    global _tab, _tab_flat
    if _tab is None:
        x = np.arange(0.0, 48.0 + _TAB_DX / 2, _TAB_DX)
        a = np.exp(np.linspace(*_TAB_LA))
        tab = np.concatenate(
            [sphere_profile(np.broadcast_to(x, (len(c), len(x))), c, 1.0) for c in np.array_split(a, 16)]
        ).astype(np.float32)
        _tab_flat = _padded(tab)
        _tab = tab
    return _tab


def sphere_profile_fast(rho: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`sphere_profile` by bilinear interpolation in a table: ~20× faster, relative
    error < 1e-3 (tested). ``rho`` (n, m); ``r``, ``s`` (n,).

    The interpolation weights are the exact fractions of the cell (:func:`bilinear_table`),
    not a library's: OpenCV's ``remap`` rounded them to 1/32 of a cell up to 4.x and does
    not from 5.0, and the bead fit's finite-difference Jacobian (steps of 10⁻³ px) read
    that rounding as steps or zeros, so a ball's centre moved by up to 0.4 px with the
    OpenCV release and the CPU's instruction set."""
    tab = _table()
    lo, hi, n = _TAB_LA
    s = np.asarray(s, float)[:, None]
    ix = np.asarray(rho, float) / s / _TAB_DX
    ia = (np.log(np.clip(np.asarray(r, float)[:, None] / s, 0.2, 32.0)) - lo) / ((hi - lo) / (n - 1))
    # the row is one per ball: its cell and weight are worked out once, not once per pixel
    return bilinear_table(tab, ix, ia) * s


def sphere_profile_grad(
    dx: np.ndarray, dy: np.ndarray, r: np.ndarray, s: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`sphere_profile_fast` at the offsets (``dx``, ``dy``) (n, m) px of each pixel from
    its ball's centre, and its exact partial derivatives with respect to the centre (u, v), the
    radius r and the blur σ: ``(S, ∂S/∂u, ∂S/∂v, ∂S/∂r, ∂S/∂σ)``, each (n, m).

    The derivatives are those of the interpolant itself (each cell's slopes), so a Gauss–Newton
    step sees the model it is fitting; one look-up of the cell's corners gives all five, where
    forward differences took five look-ups. With Ŝ the unit-blur table at x = ρ/σ and
    a = ln(r/σ): S = σ Ŝ, ∂S/∂u = −Ŝₓ (dx/ρ), ∂S/∂r = Ŝₐ σ/r, ∂S/∂σ = Ŝ − x Ŝₓ − Ŝₐ (Ŝₓ, Ŝₐ per
    unit of x and a; Ŝₐ is 0 where r/σ is clipped to the table)."""
    tab = _table()
    lo, hi, n = _TAB_LA
    da = (hi - lo) / (n - 1)
    s = np.asarray(s, float)[:, None]
    r = np.asarray(r, float)[:, None]
    rho = np.hypot(dx, dy)
    x = rho / s
    ratio = r / s
    inside = (ratio > 0.2) & (ratio < 32.0)
    ia = (np.log(np.clip(ratio, 0.2, 32.0)) - lo) / da
    v, gx, ga = bilinear_table_grad(tab, x / _TAB_DX, ia)
    gx = gx / _TAB_DX
    ga = np.where(inside, ga / da, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        # the profile is even in ρ: no slope across the centre itself
        cu = np.where(rho > 0, dx / rho, 0.0)
        cv = np.where(rho > 0, dy / rho, 0.0)
    return v * s, -gx * cu, -gx * cv, ga * s / r, v - x * gx - ga


def _cell_corners(tab: np.ndarray, x: np.ndarray, y: np.ndarray):
    """The four corners (row, column offsets (0,0), (0,1), (1,0), (1,1)) of the cell of ``tab``
    each fractional (column ``x``, row ``y``) lies in, 0 outside the table, and the fractions."""
    flat = _tab_flat if tab is _tab else _padded(tab)
    rows, cols = tab.shape
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx, fy = x - x0, y - y0
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    base = y0 * cols + x0
    inx = ((x0 >= 0) & (x0 < cols), (x0 >= -1) & (x0 < cols - 1))
    iny = ((y0 >= 0) & (y0 < rows), (y0 >= -1) & (y0 < rows - 1))
    corners = [
        flat[np.where(inx[dx] & iny[dy], base + (dy * cols + dx), rows * cols)] for dy in (0, 1) for dx in (0, 1)
    ]
    return corners, fx, fy


def bilinear_table_grad(tab: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`bilinear_table` and its slopes along x and y (per unit of column and row) in the
    cell each point lies in; the same zero border."""
    (c00, c01, c10, c11), fx, fy = _cell_corners(tab, x, y)
    low = c00 + fx * (c01 - c00)
    high = c10 + fx * (c11 - c10)
    gx = (1 - fy) * (c01 - c00) + fy * (c11 - c10)
    return low + fy * (high - low), gx, high - low


def _padded(tab: np.ndarray) -> np.ndarray:
    """``tab`` flat, as float, with one zero after its last cell (where a look-up outside lands)."""
    return np.concatenate([tab.astype(float).reshape(-1), [0.0]])


def bilinear_table(tab: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``tab`` (rows, cols) at fractional column ``x`` and row ``y`` (broadcast against each
    other), bilinear with exact weights; 0 where a neighbouring cell lies outside the table (as
    a zero border)."""
    (c00, c01, c10, c11), fx, fy = _cell_corners(tab, x, y)
    out = c00 * ((1 - fx) * (1 - fy))
    out = out + c01 * (fx * (1 - fy))
    out = out + c10 * ((1 - fx) * fy)
    return out + c11 * (fx * fy)


@dataclass
class Beads:
    """Fitted beads: ``uv`` (n, 2) px centres, ``radius`` (n,) px, ``blur`` (n,) px,
    ``amplitude`` (n,) density per px of chord, ``sigma_px`` (n,) the centre's standard
    deviation from the fit (px, per axis), ``rms`` (n,) the fit's residual RMS over the
    noise (≈ 1 for a clean ball), ``response`` (n,) the detector's blob response, ``contrast``
    (n,) the fitted ball's peak over the noise σ (its amplitude × the blurred chord at its
    centre, at most the patch's rise above its background: how far above the noise it stands)."""

    uv: np.ndarray
    radius: np.ndarray
    blur: np.ndarray
    amplitude: np.ndarray
    sigma_px: np.ndarray
    rms: np.ndarray
    response: np.ndarray
    contrast: np.ndarray

    def take(self, keep) -> "Beads":
        """The beads selected by boolean or index array ``keep``."""
        return Beads(*(getattr(self, k)[keep] for k in self.__dataclass_fields__))

    def __len__(self) -> int:
        return len(self.uv)

    @property
    def second_moment_px2(self) -> np.ndarray:
        """Each ball's image's second moment per axis (px²): r²/5 from its projected chord,
        plus its blur σ². The image pins this sum better than its two parts, which trade off
        against each other in the fit."""
        return np.asarray(self.radius, float) ** 2 / 5.0 + np.asarray(self.blur, float) ** 2


def blob_response(
    img: np.ndarray, radius_px: float, noise: float | np.ndarray, sigma_px: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | float]:
    """The scale-normalised negative Laplacian of ``img`` at the bead scale and what white
    noise of pixel σ ``noise`` (a number or a map) gives it: ``(response, xx, yy, noise
    response)``; a ball of the design shows as a peak of ``response / noise response``.

    ``sigma_px``: the Laplacian's σ (px); None: r/√2 for balls of radius ``radius_px`` at the
    default blur (:func:`blob_sigma` for a blurrier image)."""
    # a float64 scale keeps the response in double precision (a float32 image alone gives float32)
    sb = np.float64(blob_sigma(radius_px) if sigma_px is None else sigma_px)
    g0, _, g2 = gaussian_kernels(sb)
    xx = cv2.sepFilter2D(img, cv2.CV_32F, g2, g0, borderType=cv2.BORDER_REPLICATE)
    yy = cv2.sepFilter2D(img, cv2.CV_32F, g0, g2, borderType=cv2.BORDER_REPLICATE)
    resp = -(xx + yy) * (sb * sb)
    noise_resp = noise * sb * sb * float(np.sqrt(2 * (g2.astype(float) ** 2).sum() * (g0.astype(float) ** 2).sum()))
    return resp, xx, yy, noise_resp


def blob_sigma(radius_px: float, extra_blur_px: float = 0.0) -> float:
    """The Laplacian-of-Gaussian σ (px) that finds balls of radius ``radius_px`` blurred by
    ``extra_blur_px`` beyond the default blur: r/√2 (at least 0.8), with the extra blur added
    in quadrature, as a blurred blob's scale grows. In white noise a 3.4 px ball under a 2 px
    blur reads 75 % of the matched filter's SNR at r/√2 and 93 % at this σ (at the default
    0.8 px the two σ are the same: 98 %)."""
    return float(np.hypot(max(radius_px / np.sqrt(2.0), 0.8), extra_blur_px))


def blob_candidates(
    img: np.ndarray,
    radius_px: float,
    noise: float | np.ndarray,
    max_count: int,
    min_snr: float = 8.0,
    min_isotropy: float = 0.3,
    sigma_px: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Local maxima (n, 2) (u, v) of the scale-normalised negative Laplacian at the bead
    scale σ = ``sigma_px`` (None: r/√2), strongest first, at most ``max_count``, each
    ≥ ``min_snr`` times the noise response; also requires both Hessian eigenvalues negative, the smaller at least
    ``min_isotropy`` of the larger (a blob, not a ridge: a cortical band as wide as a ball
    gave hundreds of maxima along its length). ``noise``: the pixel noise σ, one number or a
    map (H, W). Returns the maxima and their response in units of the noise response there."""
    sb = np.float64(blob_sigma(radius_px) if sigma_px is None else sigma_px)
    resp, xx, yy, noise_resp = blob_response(img, radius_px, noise, sb)
    k = max(int(round(radius_px)), 1)
    se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
    j, i = np.nonzero((resp > min_snr * noise_resp) & (xx < 0) & (yy < 0))
    if len(j) * int(se.sum()) < resp.size:
        # local maximum over the disc tested at the few strong pixels only (the dilation of
        # the whole image cost more than the rest of this function); pixels outside the
        # image do not count, as in cv2.dilate's default border
        P = cv2.copyMakeBorder(resp, k, k, k, k, cv2.BORDER_CONSTANT, value=-np.inf)
        v = resp[j, i]
        peak = np.ones(len(j), bool)
        for dy, dx in np.argwhere(se) - k:
            peak &= v >= P[j + k + dy, i + k + dx]
        j, i = j[peak], i[peak]
    else:
        dil = cv2.dilate(resp, se)
        j, i = np.nonzero((resp >= dil) & (resp > min_snr * noise_resp) & (xx < 0) & (yy < 0))
    if len(j) and min_isotropy > 0:
        g1 = gaussian_kernels(sb)[1]
        xy = cv2.sepFilter2D(img, cv2.CV_32F, -g1, -g1, borderType=cv2.BORDER_REPLICATE)[j, i]
        a, c = xx[j, i], yy[j, i]
        half, disc = 0.5 * (a + c), np.sqrt(0.25 * (a - c) ** 2 + xy * xy)
        iso = (half + disc < 0) & (half + disc <= min_isotropy * (half - disc))
        j, i = j[iso], i[iso]
    nr = noise_resp[j, i] if np.ndim(noise_resp) == 2 else noise_resp
    val = resp[j, i] / nr
    order = np.argsort(-val)[:max_count]
    return np.stack([i[order], j[order]], -1).astype(float), val[order]


def fit_patch_half_px(radius_px: float, blur_px: float) -> int:
    """Half the side (px) of the disc of pixels :func:`fit_beads` fits a ball of radius
    ``radius_px`` blurred by ``blur_px`` (σ, at least 0.5) on: the ball and three σ of its blur."""
    return int(np.ceil(radius_px + 3 * max(blur_px, 0.5) + 1.5))


def fit_beads(
    img: np.ndarray,
    starts: np.ndarray,
    radius_px: float,
    blur_px: float,
    noise: float | np.ndarray,
    response: np.ndarray | None = None,
    iterations: int = 6,
    exclude: np.ndarray | None = None,
    prior_scale: float = 1.0,
    censored: np.ndarray | None = None,
    background: np.ndarray | None = None,
) -> Beads:
    """Fit the blurred-sphere model at every start (n, 2) px in ``img`` (background
    removed, dense = bright). ``radius_px`` and ``blur_px`` are the expected ball radius and
    blur (starting values; both are fitted), ``noise`` the pixel noise σ (one number, or
    one per start). ``exclude``
    (H, W) bool marks pixels to leave out of every fit (where a pose predicts wires: a
    ball at the crossing of two wires is pulled ~0.4 px by them even with robust weights).
    ``prior_scale`` multiplies the weights of the radius and blur priors. ``censored`` (H, W)
    bool marks pixels whose true value is at least what ``img`` shows (clipped on the dense
    side: a display window's black under a ball's core, no photons left): a model above such
    a pixel fits it, one below it is a misfit as usual (a censored likelihood), so a ball whose
    core was clipped flat is fitted to its flanks rather than flattened into a wider, weaker
    ball. ``background`` (H, W) float: the shape of a known structure under the balls at unit
    amplitude (the wires a pose predicts, blurred: :func:`.body.wire_profile`), its amplitude
    fitted per ball with the plane — a blurred wire beside a ball is a broad band that the
    plane cannot take up and the robust weights do not reject, and it pulls the centre."""
    H, W = img.shape
    half = fit_patch_half_px(radius_px, blur_px)
    n = len(starts)
    # an image narrower than one ball's patch holds no ball that can be fitted (and the
    # patch could not be placed inside it)
    if n == 0 or min(H, W) < 2 * half + 1:
        z = np.zeros(0)
        return Beads(np.zeros((0, 2)), z, z, z, z, z, z, z)
    y, X, Y, (cx, cy), (py, px) = _patches(img, starts, half)
    tpl = None if background is None else np.asarray(background, float)[py, px]
    # params: u, v (relative), r, s, A, b0, bx, by (, the background's amplitude)
    p = np.zeros((n, 8 if tpl is None else 9))
    p[:, 0] = starts[:, 0] - cx
    p[:, 1] = starts[:, 1] - cy
    p[:, 2] = radius_px
    p[:, 3] = max(blur_px, 0.5)
    p[:, 5] = np.percentile(y, 10, axis=1)
    seen = y.max(1) - p[:, 5]  # the patch's rise above its background
    peak = sphere_profile(np.zeros((n, 1)), p[:, 2], p[:, 3])[:, 0]
    p[:, 4] = np.maximum(seen, 1e-6) / np.maximum(peak, 1e-9)
    w0 = np.ones_like(y) if exclude is None else (~np.asarray(exclude, bool)[py, px]).astype(float)
    cen = None
    if censored is not None:
        cen = np.asarray(censored, bool)[py, px]
        cen = cen if cen.any() else None
    if cen is not None:
        _start_above_the_clip(p, y, X, Y, w0, cen, tpl)
    sn = np.maximum(np.broadcast_to(np.asarray(noise, float), (n,)), 1e-12)
    # prior weights in the fit's units (residuals in density, unit weights): noise² / σ_prior²
    # with σ_prior = 25 % of the expected radius and 0.5 px of blur
    prior_w = (prior_scale * sn**2 / max(0.25 * radius_px, 1e-6) ** 2, prior_scale * sn**2 / 0.5**2)
    w, J, S = _iterate(p, y, X, Y, w0, sn, prior_w, radius_px, max(blur_px, 0.5), iterations, cen, tpl)
    sd, rms = _spread(p, S, y, X, Y, w, J, sn, cen, tpl)
    uv = np.stack([p[:, 0] + cx, p[:, 1] + cy], -1)
    return Beads(
        uv,
        p[:, 2],
        p[:, 3],
        p[:, 4],
        sd,
        rms,
        np.asarray(response, float) if response is not None else np.full(n, np.nan),
        # no more than the patch shows: a fit run off to a tiny, huge-amplitude ball (a glyph's
        # strokes) would otherwise claim a contrast of thousands of σ
        np.minimum(p[:, 4] * sphere_profile(np.zeros((n, 1)), p[:, 2], p[:, 3])[:, 0], seen) / sn,
    )


def _iterate(p, y, X, Y, w0, sn, prior_w, radius_px: float, s0: float, iterations: int, cen, tpl=None):
    """The fits' iterations from start values ``p`` (n, k, updated in place; k = 8, or 9 with
    a background shape ``tpl`` (n, m)): the last weights (n, m) and Jacobian (n, m, k), and the
    profile at the final ``p`` (n, m)."""
    # Levenberg–Marquardt, one damping per fit: under a 2 px blur the radius, blur and
    # amplitude trade along a shallow valley, and undamped Gauss–Newton steps crossed it back
    # and forth (a ball's centre still moved by 0.04 px at the 90th percentile, and the
    # image's blur read from the balls by ±0.2 px, between 8 and 30 iterations)
    w, J = w0.copy(), None
    lam = np.full(len(p), 1e-3)
    prof = _profile(p, X, Y)
    for it in range(iterations):
        dp, w, J, cost = _step(p, prof, y, X, Y, w0, w, 4.685 * sn[:, None], it, prior_w, radius_px, s0, lam, cen, tpl)
        # keep the shape parameters physical and the steps modest
        dp[:, :2] = np.clip(dp[:, :2], -1.0, 1.0)
        dp[:, 2] = np.clip(dp[:, 2], -0.25 * radius_px, 0.25 * radius_px)
        dp[:, 3] = np.clip(dp[:, 3], -0.3, 0.3)
        trial = p + dp
        trial[:, 2] = np.clip(trial[:, 2], 0.3 * radius_px, 3.0 * radius_px)
        trial[:, 3] = np.clip(trial[:, 3], 0.2, 4.0)
        tprof = _profile(trial, X, Y)
        better = _cost(trial, tprof[0], y, X, Y, w, prior_w, radius_px, s0, cen=cen, tpl=tpl) <= cost
        p[better] = trial[better]
        prof = tprof if better.all() else tuple(np.where(better[:, None], a, b) for a, b in zip(tprof, prof))
        lam = np.where(better, np.maximum(lam * 0.3, 1e-7), np.minimum(lam * 10.0, 1e7))
    return w, J, prof[0]


def _start_above_the_clip(
    p: np.ndarray, y: np.ndarray, X: np.ndarray, Y: np.ndarray, w0: np.ndarray, cen, tpl=None
) -> None:
    """Start values (in ``p``, in place) for the patches with censored pixels ``cen`` (n, m):
    the amplitude and plane that the pixels left uncensored give the ball of the start's
    centre, radius and blur, by linear least squares. The rise a clipped core shows is less
    than the ball's: from it, a ball clipped at half its height was still a wider, flatter
    ball after eight iterations (a local minimum the flanks alone do not leave)."""
    rows = np.flatnonzero(cen.any(1))
    S = sphere_profile_fast(np.hypot(X[rows] - p[rows, 0:1], Y[rows] - p[rows, 1:2]), p[rows, 2], p[rows, 3])
    A = np.stack([S, np.ones_like(S), X[rows], Y[rows]] + ([] if tpl is None else [tpl[rows]]), -1)
    w = w0[rows] * ~cen[rows]
    Aw = A * w[..., None]
    with np.errstate(all="ignore"):
        M = Aw.transpose(0, 2, 1) @ A + 1e-9 * np.eye(A.shape[-1])
        b = (Aw.transpose(0, 2, 1) @ y[rows][..., None])[..., 0]
        try:
            x = np.linalg.solve(M, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return
    ok = np.isfinite(x).all(1) & (x[:, 0] > p[rows, 4])
    p[rows[ok], 4:] = x[ok]


def _patches(img: np.ndarray, starts: np.ndarray, half: int):
    """The disc of radius ``half`` px around each start (n, 2), inside ``img``: the values
    (n, m), the coordinates relative to the patch centres (n, m) X and Y, the centres (cx, cy)
    and the pixels' (rows, columns)."""
    H, W = img.shape
    off = np.arange(-half, half + 1)
    oy, ox = np.meshgrid(off, off, indexing="ij")
    inside = (ox**2 + oy**2) <= half * half
    ox, oy = ox[inside].astype(float), oy[inside].astype(float)
    c0 = np.round(starts).astype(int)
    cx = np.clip(c0[:, 0], half, W - 1 - half)
    cy = np.clip(c0[:, 1], half, H - 1 - half)
    px = cx[:, None] + ox[None].astype(int)
    py = cy[:, None] + oy[None].astype(int)
    y = img[py, px].astype(float)  # (n, m)
    X = px - cx[:, None].astype(float)  # coordinates relative to the patch centre
    Y = py - cy[:, None].astype(float)
    return y, X, Y, (cx, cy), (py, px)


def _profile(p, X, Y) -> tuple[np.ndarray, ...]:
    """The ball profile and its derivatives (:func:`sphere_profile_grad`) at parameters ``p``."""
    return sphere_profile_grad(X - p[:, 0:1], Y - p[:, 1:2], p[:, 2], p[:, 3])


def _cost(p, S, y, X, Y, w, prior_w, radius_px: float, blur_px: float, res=None, cen=None, tpl=None) -> np.ndarray:
    """Each fit's weighted squared residual at parameters ``p`` (n, k), its profile ``S``
    (n, m) or its residuals ``res`` (n, m) when known (censored pixels ``cen`` already
    counted; ``tpl`` the background's shape, see :func:`_residuals`), with the priors' terms."""
    if res is None:
        res = _residuals(p, S, y, X, Y, cen, tpl)[0]
    return (w * res * res).sum(1) + prior_w[0] * (p[:, 2] - radius_px) ** 2 + prior_w[1] * (p[:, 3] - blur_px) ** 2


def _step(
    p, prof, y, X, Y, w0, w, cost_scale, it: int, prior_w, radius_px: float, blur_px: float, lam, cen=None, tpl=None
):
    """One robust Levenberg–Marquardt step of :func:`fit_beads` from parameters ``p`` (n, k)
    with the profile there ``prof`` (:func:`_profile`), damped by ``lam`` (n,): the step
    (n, k), the weights it used, the Jacobian (n, m, k) and the cost at ``p`` under those
    weights (:func:`_cost`). ``cen`` (n, m) bool: the censored pixels (None: none); ``tpl``
    (n, m): the background's shape, whose amplitude is the ninth parameter (None: k = 8)."""
    S, Su, Sv, Sr, Ss = prof
    res, free = _residuals(p, S, y, X, Y, cen, tpl)
    if free is not None and it < 2:
        w = w0 * free
    nk = p.shape[1]
    J = np.empty(y.shape + (nk,))
    for k, d in enumerate((Su, Sv, Sr, Ss)):
        J[..., k] = p[:, 4:5] * d
    J[..., 4] = S
    J[..., 5] = 1.0
    J[..., 6] = X
    J[..., 7] = Y
    if tpl is not None:
        J[..., 8] = tpl
    if it >= 2:
        # Tukey biweight on the residuals: a wire touching the ball is an outlier
        # one scale pooled over the candidates fitted together: a ball's own handful of
        # pixels (a 1 mm ball's patch, less the wires masked out) gives too unstable a
        # scale, and its centre moved by 0.6 px
        scale = np.maximum(cost_scale, 4.685 * 1.4826 * float(np.median(np.abs(res))))
        u = np.clip(np.abs(res) / scale, 0, 1)
        w = (1 - u * u) ** 2 * w0 * (1.0 if free is None else free)
    # batched matrix products (BLAS): einsum's loop over these small sums was 20–30 × slower
    Jw_t = (J * w[..., None]).transpose(0, 2, 1)
    A = Jw_t @ J + 1e-9 * np.eye(nk)
    g = (Jw_t @ res[..., None])[..., 0]
    # weak priors on the radius and the blur: for a ball of a few pixels the blurred
    # profile is nearly Gaussian and r, σ and A trade off against each other (the
    # unregularised fit ran off to r → 0.3 r₀ or σ → 4 px on ftrac_mini's 1 mm balls)
    A[:, 2, 2] += prior_w[0]
    A[:, 3, 3] += prior_w[1]
    g[:, 2] += prior_w[0] * (radius_px - p[:, 2])
    g[:, 3] += prior_w[1] * (blur_px - p[:, 3])
    cost = _cost(p, S, y, X, Y, w, prior_w, radius_px, blur_px, res)
    d = np.diagonal(A, axis1=1, axis2=2)
    A = A + lam[:, None, None] * (d[:, :, None] * np.eye(nk))
    try:
        dp = np.linalg.solve(A, g[..., None])[..., 0]
    except np.linalg.LinAlgError:
        dp = (np.linalg.pinv(A) @ g[..., None])[..., 0]
    return dp, w, J, cost


def _residuals(p, S, y, X, Y, cen, tpl=None) -> tuple[np.ndarray, np.ndarray | None]:
    """The data ``y`` less the model (n, m) at parameters ``p`` with profile ``S`` — amplitude ×
    profile plus the planar background (plus ``p[:, 8]`` × the known background's shape ``tpl``
    (n, m), when given) — 0 at a censored pixel the model lies above; and where the residuals
    count (:func:`_uncensored`; None: no censored pixels)."""
    res = y - (p[:, 4:5] * S + p[:, 5:6] + p[:, 6:7] * X + p[:, 7:8] * Y)
    if tpl is not None:
        res -= p[:, 8:9] * tpl
    free = _uncensored(res, cen)
    return (res if free is None else res * free), free


def _uncensored(res: np.ndarray, cen: np.ndarray | None) -> np.ndarray | None:
    """1 where a residual counts, 0 at a censored pixel the model lies above (None: no
    censored pixels)."""
    return None if cen is None else (~(cen & (res < 0))).astype(float)


def _spread(p, S, y, X, Y, w, J, sn, cen=None, tpl=None) -> tuple[np.ndarray, np.ndarray]:
    """Each fit's centre standard deviation (px) and its weighted RMS residual in noise units
    at parameters ``p``, whose profile is ``S`` (a censored pixel the model lies above counts
    for neither)."""
    res, free = _residuals(p, S, y, X, Y, cen, tpl)
    if free is not None:
        w = w * free
    k = p.shape[1]
    wsum = np.maximum(w.sum(1), 1.0)
    rms = np.sqrt((w * res * res).sum(1) / np.maximum(wsum - k, 1)) / sn
    sig2 = sn**2 * np.maximum(rms, 1.0) ** 2
    with np.errstate(all="ignore"):
        cov = np.linalg.pinv((J * w[..., None]).transpose(0, 2, 1) @ J + 1e-12 * np.eye(k)) * sig2[:, None, None]
    return np.sqrt(np.abs(0.5 * (cov[:, 0, 0] + cov[:, 1, 1]))), rms
