"""Image conditioning before segmentation: polarity, density domain, background, noise.

Everything downstream works on a *density* image ``g`` — larger where the beam crossed
more material (dense = bright), additive in the line integral where that is known:

- a raw detector image (dense = dark, counts ∝ I) becomes ``g = −ln(I)`` (+ a constant,
  which the background removal takes away), the log image of the Beer–Lambert law;
- a display or log image (dense = bright) is used as it is.

The fiducial's wires and beads are thin, bright structures on a background that varies
slowly except at the acetal body's steep silhouette. A grey *opening* with a flat disc wider
than any bead removes exactly the structures narrower than the disc and keeps every
monotone ramp (the body's edge) unchanged, so the white top-hat ``g − open(g)`` leaves the
wires and beads on a flat zero background (Serra's top-hat; OpenCV's morphology is ~10×
faster than scipy's for the same operator).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

POLARITIES = ("auto", "dense-dark", "dense-bright")


def to_density(image: np.ndarray, polarity: str) -> np.ndarray:
    """The density image (float32, dense = bright) of ``image`` with known ``polarity``
    ("dense-dark": raw counts, logged; "dense-bright": used as it is)."""
    img = np.asarray(image, dtype=np.float32)
    if polarity == "dense-dark":
        lo = max(float(img.max()) * 1e-5, 1e-6)
        return -cv2.log(np.maximum(img, np.float32(lo)))
    if polarity == "dense-bright":
        return img
    raise ValueError(f"polarity must be dense-dark or dense-bright, got {polarity!r}")


def detect_polarity(image: np.ndarray, disc_px: int) -> str:
    """ "dense-dark" or "dense-bright": the sign in which thin compact structures (the
    fiducial's wires and beads) stand out most. Compares the strongest responses of the
    white and black top-hats of a normalised image; metal is the most compact, most
    contrasted thing in a radiograph of the fiducial, whatever the anatomy around it."""
    img = np.asarray(image, dtype=np.float32)
    # blob strength of each sign at the bead scale: the smaller-magnitude Hessian
    # eigenvalue where both have the same sign. A top-hat was fooled by the bright gap
    # between two dark balls (a saddle, not a blob) and by noise extremes — ftrac_mini's
    # nine 1 mm balls cover < 100 of 10⁶ pixels — and gave the wrong polarity on a third
    # of ftrac_mini's raw images
    d = derivatives(img, max(disc_px / 4.0, 1.0), first=False)
    half_tr = 0.5 * (d["xx"] + d["yy"])
    disc = np.sqrt(0.25 * (d["xx"] - d["yy"]) ** 2 + d["xy"] ** 2)
    bright = np.maximum(-(half_tr + disc), 0)  # both eigenvalues < 0: a bright blob
    dark = np.maximum(half_tr - disc, 0)  # both > 0: a dark blob
    w, b = _kth_largest(bright, 16), _kth_largest(dark, 16)
    return "dense-bright" if w >= b else "dense-dark"


def _kth_largest(a: np.ndarray, k: int) -> float:
    """The k-th largest value of a non-negative array (0 if fewer than k are positive);
    the zeros are left out first (introselect is slow on many ties)."""
    a = np.asarray(a)
    if a.ndim == 2 and a.shape[0] >= 8 and a.shape[1] >= 8:
        # the k-th largest of 8 × 8 block maxima is k distinct values, so at most the k-th
        # largest of all: only the few values above it need sorting (exact, ~10× faster)
        H, W = a.shape[0] // 8 * 8, a.shape[1] // 8 * 8
        b = a[:H, :W]
        r = b[0::8].copy()
        for i in range(1, 8):
            np.maximum(r, b[i::8], out=r)
        bm = r[:, 0::8].copy()
        for i in range(1, 8):
            np.maximum(bm, r[:, i::8], out=bm)
        bm = bm.ravel()
        if len(bm) >= k:
            thr = np.partition(bm, -k)[-k]
            if thr > 0:
                v = a[a >= thr]
                return float(np.partition(v, -k)[-k])
    v = a.ravel()
    v = v[v > 0]
    return float(np.partition(v, -k)[-k]) if len(v) >= k else 0.0


def top_hat(g: np.ndarray, disc_px: int) -> np.ndarray:
    """White top-hat of the density image with a flat disc of radius ``disc_px`` pixels."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * disc_px + 1, 2 * disc_px + 1))
    return cv2.morphologyEx(np.ascontiguousarray(g, dtype=np.float32), cv2.MORPH_TOPHAT, k)


def noise_sigma(g: np.ndarray) -> float:
    """Robust standard deviation of the pixel noise: the MAD of the difference of
    neighbouring pixels (structure-free where the image is smooth), divided by √2."""
    d = np.diff(np.asarray(g, np.float32)[::2, :], axis=1).ravel()
    mad = float(_median(np.abs(d - _median(d))))
    return 1.4826 * mad / math.sqrt(2.0)


def _median(v: np.ndarray) -> np.floating:
    """``np.median`` of a flat float32 array, the same number: the values are binned (the
    bin index is monotone in the value), and only the bin holding the middle rank(s) is
    partitioned — selecting among all ~10⁵ values twice per image cost ~2 ms."""
    n = len(v)
    if n < 4096 or not np.isfinite(v).all():
        return np.median(v)
    lo, hi = float(v.min()), float(v.max())
    if not hi > lo:
        return np.median(v)
    nb = 1024
    b = ((v - np.float32(lo)) * np.float32(nb / (hi - lo))).astype(np.int64)
    np.clip(b, 0, nb - 1, out=b)
    cum = np.cumsum(np.bincount(b, minlength=nb))
    ks = (n // 2 - 1, n // 2) if n % 2 == 0 else (n // 2,)
    bins = sorted({int(np.searchsorted(cum, k, side="right")) for k in ks})
    sel = v[(b >= bins[0]) & (b <= bins[-1])]
    below = int(cum[bins[0] - 1]) if bins[0] > 0 else 0
    part = np.partition(sel, [k - below for k in ks])
    return np.mean(part[[k - below for k in ks]])


def gaussian_kernels(sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampled Gaussian and its first and second derivatives (float32, read-only), radius 4σ."""
    return _kernels(float(sigma))


@functools.lru_cache(maxsize=64)
def _kernels(sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # made once per scale: an image's filters ask for a few scales dozens of times
    r = max(int(math.ceil(4 * sigma)), 2)
    x = np.arange(-r, r + 1, dtype=np.float64)
    g0 = np.exp(-0.5 * (x / sigma) ** 2)
    g0 /= g0.sum()
    g1 = -x / sigma**2 * g0
    g2 = (x * x / sigma**4 - 1.0 / sigma**2) * g0
    # exact moments on the grid: Σ g1·x = −1, Σ g2·x²/2 = 1 (derivative filters of a ramp/parabola)
    g1 /= -(g1 * x).sum()
    g2 -= g2.mean()
    g2 /= (g2 * x * x).sum() / 2
    out = g0.astype(np.float32), g1.astype(np.float32), g2.astype(np.float32)
    for k in out:
        k.flags.writeable = False
    return out


def derivatives(img: np.ndarray, sigma: float, first: bool = True) -> dict[str, np.ndarray]:
    """Gaussian-smoothed derivatives of ``img`` at scale ``sigma`` px: keys x, y (unless
    ``first`` is False), xx, xy, yy (x = column, y = row)."""
    g0, g1, g2 = gaussian_kernels(sigma)

    def f(kx, ky):
        return cv2.sepFilter2D(img, cv2.CV_32F, kx, ky, borderType=cv2.BORDER_REPLICATE)

    # sepFilter2D correlates; a derivative kernel must be flipped to convolve (g1 is odd)
    d = {"xx": f(g2, g0), "yy": f(g0, g2), "xy": f(-g1, -g1)}
    if first:
        d.update(x=f(-g1, g0), y=f(g0, -g1))
    return d


@dataclass(frozen=True)
class NoiseLevels:
    """An image's noise level function at one detector scale: the white-noise pixel σ
    (density units) at each local background level (see :func:`noise_map`).

    Attributes
    ----------
    level : (k,) increasing background levels (density units).
    sigma : (k,) the pixel σ at each level; interpolated between them, constant beyond.
    """

    level: np.ndarray
    sigma: np.ndarray


def _background_level(g: np.ndarray, structure_px: int) -> np.ndarray:
    """The local background level of ``g``: eroded with a disc of radius ``structure_px``
    (balls and wires narrower than it taken away) and smoothed over 3 px."""
    base = g
    if structure_px > 0:
        disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * structure_px + 1, 2 * structure_px + 1))
        base = cv2.erode(g, disc, borderType=cv2.BORDER_REPLICATE)
    return cv2.GaussianBlur(base, (0, 0), 3.0, borderType=cv2.BORDER_REPLICATE)


def _laplacian(g: np.ndarray, sigma: float) -> tuple[np.ndarray, float]:
    """The Laplacian of Gaussian of ``g`` at ``sigma`` px and its gain for unit white noise."""
    g0, _, g2 = gaussian_kernels(sigma)
    lap = cv2.sepFilter2D(g, cv2.CV_32F, g2, g0, borderType=cv2.BORDER_REPLICATE) + cv2.sepFilter2D(
        g, cv2.CV_32F, g0, g2, borderType=cv2.BORDER_REPLICATE
    )
    k = np.outer(g0.astype(np.float64), g2) + np.outer(g2.astype(np.float64), g0)
    return lap, float(np.sqrt((k * k).sum()))


def _measured_levels(
    level: np.ndarray, lap: np.ndarray, gain: float, valid: np.ndarray | None, bins: int
) -> NoiseLevels | None:
    """The noise level function measured on the Laplacian ``lap`` grouped by ``level`` (see
    :func:`noise_map`), or None with fewer than 64 samples."""
    H, W = level.shape
    # ~16 000 samples: each of 32 groups' quartile to ~5 %, the sort under a millisecond
    step = max(1, int(math.sqrt(H * W / 16384.0)))
    lv = level[::step, ::step].ravel()
    r = lap[::step, ::step].ravel()
    if valid is not None:
        m = np.asarray(valid, bool)[::step, ::step].ravel()
        lv, r = lv[m], r[m]
    nb = int(max(1, min(bins, len(lv) // 256)))
    if len(lv) < 64:
        return None
    order = np.argsort(lv, kind="stable")
    lv, r = lv[order], r[order]
    cuts = np.linspace(0, len(lv), nb + 1).astype(int)
    centre = np.empty(nb)
    sig = np.empty(nb)
    for b in range(nb):
        rb = r[cuts[b] : cuts[b + 1]]
        centre[b] = float(np.median(lv[cuts[b] : cuts[b + 1]]))
        # the lower quartile of |r − median| over its Gaussian value (Φ⁻¹(5/8) σ)
        sig[b] = float(np.percentile(np.abs(rb - np.median(rb)), 25)) / 0.31864 / gain
    if nb >= 3:
        low = np.minimum(sig, np.minimum(np.r_[sig[1:], np.inf], np.r_[np.inf, sig[:-1]]))
        sig = low
    return NoiseLevels(centre, np.maximum(sig, 1e-9))


def noise_levels(
    g: np.ndarray, sigma: float, valid: np.ndarray | None = None, bins: int = 32, structure_px: int = 0
) -> NoiseLevels | None:
    """The noise level function of the density image ``g`` at scale ``sigma`` px, as
    :func:`noise_map` measures it (same arguments); None when ``g`` has too few readable
    pixels to measure one (fewer than 64 samples).

    Returns
    -------
    NoiseLevels or None
    """
    g = np.ascontiguousarray(g, dtype=np.float32)
    lap, gain = _laplacian(g, sigma)
    return _measured_levels(_background_level(g, structure_px), lap, gain, valid, bins)


def noise_map(
    g: np.ndarray,
    sigma: float,
    valid: np.ndarray | None = None,
    bins: int = 32,
    structure_px: int = 0,
    levels: NoiseLevels | None = None,
) -> np.ndarray:
    """Local noise σ (H, W) float32 of the density image ``g``, as the white-noise pixel σ
    that gives the noise the detectors actually see at scale ``sigma`` px.

    The noise of a radiograph is not one number: behind dense anatomy the log image's
    quantum noise is several times that of the thin parts (σ ∝ 1/√N, and N falls as e^{−p}),
    and a display chain's window and gamma scale it by their local slope. Both make the noise
    a function of the local signal level — the image's *noise level function* (C. Liu et
    al., *Automatic estimation and removal of noise from a single image*, IEEE PAMI 30(2),
    2008). It is measured here from the whole image at once: the pixels are grouped by their
    local background level into ``bins`` groups of equal size, and
    each group's noise is the robust spread of the Laplacian of Gaussian at ``sigma`` (a
    linear, zero-mean response on a flat background; the lower quartile of its absolute
    deviations over its Gaussian value, which thin structures hardly move) divided by that
    filter's gain for unit white noise — so a threshold in units of this σ means the same on
    correlated noise (a detector's blur, edge enhancement) as on white. A level that only
    the fiducial's own body has (an image with nothing else in it) would be measured on the
    fiducial's wires and balls: each group's value is therefore the lowest of it and its two
    neighbours'. Only ``valid`` pixels are used.

    The local background level is ``g`` eroded with a disc of radius ``structure_px`` (the
    bright balls and wires narrower than it taken away) and smoothed over 3 px: a ball's own
    density must not decide the noise it is judged against (it put a ball in the group of
    the densest bone).

    ``levels``: a noise level function measured before (:func:`noise_levels`, on a larger
    image of the same imaging chain) used instead of measuring one on ``g``; the clutter
    term is still measured on ``g``.
    """
    return noise_map_and_levels(g, sigma, valid, bins, structure_px, levels)[0]


def noise_map_and_levels(
    g: np.ndarray,
    sigma: float,
    valid: np.ndarray | None = None,
    bins: int = 32,
    structure_px: int = 0,
    levels: NoiseLevels | None = None,
) -> tuple[np.ndarray, NoiseLevels | None]:
    """:func:`noise_map` and the noise level function it used (``levels`` when given, the
    one measured on ``g`` otherwise; None where too few pixels could be read to measure one)."""
    g = np.ascontiguousarray(g, dtype=np.float32)
    H, W = g.shape
    lap, gain = _laplacian(g, sigma)
    level = _background_level(g, structure_px)
    if levels is None:
        levels = _measured_levels(level, lap, gain, valid, bins)
        if levels is None:
            return np.full((H, W), max(noise_sigma(g), 1e-9), np.float32), None
    centre, sig = levels.level, levels.sigma
    if len(centre) == 1 or not np.ptp(centre) > 0:
        out = np.full((H, W), float(np.median(sig)), np.float32)
    elif H * W > 65536:
        # the level is smooth over ~3 px: looked up on every 4th pixel and interpolated
        small = np.interp(level[::4, ::4], centre, sig).astype(np.float32)
        out = cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)
    else:
        out = np.interp(level, centre, sig).astype(np.float32)
    clutter = _clutter_map(lap, valid, gain)
    return (out if clutter is None else np.maximum(out, clutter)), levels


def _sorted_median(v: np.ndarray, cnt: np.ndarray) -> np.ndarray:
    """The median over the last axis of ``v``, whose first ``cnt`` values (per row, after
    sorting; NaN sort last) are the valid ones: one vectorised sort, not a loop of nanmedian."""
    srt = np.sort(v, axis=-1)
    c = np.maximum(cnt, 1)
    lo = np.take_along_axis(srt, ((c - 1) // 2)[..., None], axis=-1)[..., 0]
    hi = np.take_along_axis(srt, (c // 2)[..., None], axis=-1)[..., 0]
    return 0.5 * (lo + hi)


def _sorted_quantile(v: np.ndarray, cnt: np.ndarray, q: float) -> np.ndarray:
    """The ``q`` quantile (nearest rank) over the last axis of ``v`` with ``cnt`` valid values
    per row (NaN sort last)."""
    srt = np.sort(v, axis=-1)
    k = np.clip(np.round(q * (np.maximum(cnt, 1) - 1)).astype(int), 0, v.shape[-1] - 1)
    return np.take_along_axis(srt, k[..., None], axis=-1)[..., 0]


#: side (px) of the tiles the clutter term of :func:`noise_map` is measured in, from the image's corner
CLUTTER_TILE_PX = 64


def _clutter_map(
    lap: np.ndarray, valid: np.ndarray | None, gain: float, tile: int = CLUTTER_TILE_PX
) -> np.ndarray | None:
    """The robust spread of the Laplacian response ``lap`` in tiles of ``tile`` px,
    over the white-noise ``gain``, interpolated to every pixel: what the level function
    misses where anatomy rather than quanta makes the clutter at the detectors' scale (the
    texture of a vertebral body: blobs at the ball's scale by the hundred, 8–30 σ of the
    quantum noise). None for an image of fewer than 2 × 2 tiles."""
    H, W = lap.shape
    ny, nx = H // tile, W // tile
    if ny < 2 or nx < 2:
        return None
    v = lap[: ny * tile : 2, : nx * tile : 2].reshape(ny, tile // 2, nx, tile // 2).transpose(0, 2, 1, 3)
    v = v.reshape(ny, nx, -1).astype(np.float64)
    if valid is not None:
        m = np.asarray(valid, bool)[: ny * tile : 2, : nx * tile : 2].reshape(ny, tile // 2, nx, tile // 2)
        m = m.transpose(0, 2, 1, 3).reshape(ny, nx, -1)
        v = np.where(m, v, np.nan)
        cnt = m.sum(-1)
    else:
        cnt = np.full((ny, nx), v.shape[-1])
    few = cnt < 0.25 * v.shape[-1]
    med = _sorted_median(v, cnt)
    # the lower quartile of the absolute deviations (as the level function's): texture
    # fills a tile and moves every quantile, the fiducial's wires and balls in it hardly this one
    t = _sorted_quantile(np.abs(v - med[..., None]), cnt, 0.25) / 0.31864 / gain
    t[few | ~np.isfinite(t)] = 0.0
    return cv2.resize(t.astype(np.float32), (W, H), interpolation=cv2.INTER_LINEAR)


def second_derivative_gain(sigma: float) -> float:
    """Standard deviation of a Gaussian second derivative at scale ``sigma`` px (in any
    direction: the Gaussian's derivatives are steerable and the norm rotation-invariant)
    applied to unit white noise."""
    return _second_derivative_gain(float(sigma))


@functools.lru_cache(maxsize=64)
def _second_derivative_gain(sigma: float) -> float:
    g0, _, g2 = gaussian_kernels(sigma)
    return float(np.sqrt((g2.astype(np.float64) ** 2).sum() * (g0.astype(np.float64) ** 2).sum()))


class NoiseField:
    """The local noise of one density image at any detector scale (:func:`noise_map`),
    computed once per scale on the whole image and shared by its crops: a crop's own noise
    level function would be measured mostly on the fiducial that fills it.

    ``levels``: noise level functions measured before, by scale (px), used instead of
    measuring them (a crop of a run's frame with the frame's own function)."""

    def __init__(
        self,
        g: np.ndarray,
        valid: np.ndarray | None,
        structure_px: int,
        box: tuple[int, int, int, int] | None = None,
        cache: dict | None = None,
        levels: dict[float, NoiseLevels] | None = None,
    ):
        self._g, self._valid, self._structure = g, valid, int(structure_px)
        self._box = box
        # maps by scale, and ("levels", scale) → the level function: shared with the crops
        self._cache = {} if cache is None else cache
        for k, v in (levels or {}).items():
            self._cache[("levels", round(float(k), 3))] = v

    def at(self, sigma: float) -> np.ndarray:
        """The noise map (float32) at scale ``sigma`` px over this field's box."""
        key = round(float(sigma), 3)
        full = self._cache.get(key)
        if full is None:
            full, used = noise_map_and_levels(
                self._g, sigma, self._valid, structure_px=self._structure, levels=self._cache.get(("levels", key))
            )
            self._cache[key] = full
            self._cache[("levels", key)] = used
        if self._box is None:
            return full
        r0, r1, c0, c1 = self._box
        return full[r0:r1, c0:c1]

    def levels(self, sigma: float) -> NoiseLevels | None:
        """The noise level function at scale ``sigma`` px: the one given, or the one measured
        when the map at that scale was made; None before (or where none could be measured)."""
        return self._cache.get(("levels", round(float(sigma), 3)))

    def crop(self, r0: int, r1: int, c0: int, c1: int) -> "NoiseField":
        """The same field over rows r0:r1 and columns c0:c1 (of this field's box)."""
        if self._box is not None:
            br0, _, bc0, _ = self._box
            r0, r1, c0, c1 = r0 + br0, r1 + br0, c0 + bc0, c1 + bc0
        return NoiseField(self._g, self._valid, self._structure, (r0, r1, c0, c1), self._cache)
