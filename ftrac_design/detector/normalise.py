"""The detector's fixed input: any image at its working scale, normalised the same way for
training and for use.

The working scale is an integer downsampling factor chosen from the design's ball size, so
that a ball reads about 1.7 px in radius whatever the design (ftrac_2005's 2 mm balls at half
size, ftrac_mini's 1 mm balls at full size). The input has two channels of local contrast (the
image less its Gaussian-smoothed self over the local RMS of that, at two scales), which read a
ball the same behind thin tissue and bone, after a display's window and gamma, in counts or line
integrals, in a whole 1024² frame or a crop of it — a scaling by the image's own range did not:
on a whole clean frame the fiducial saturated it and the noise looked like structure. Polarity
is left as the image has it: the network learned both.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..threads import beside

#: the ball radius (px) the network was trained to see, at the working scale
WORKING_BEAD_RADIUS_PX = 1.7
#: side of an output cell in working pixels
STRIDE = 2


def working_scale(bead_radius_px: float) -> int:
    """The integer downsampling factor that brings a ball of ``bead_radius_px`` (px of the
    image, at the tracker's assumed magnification) closest to the working radius, at least 1."""
    if not bead_radius_px > 0:
        return 1
    return max(1, int(math.floor(bead_radius_px / WORKING_BEAD_RADIUS_PX + 0.5)))


def downsample(image: np.ndarray, scale: int) -> np.ndarray:
    """``image`` (H, W) averaged over ``scale`` × ``scale`` blocks (float32, H // scale × W // scale)."""
    img = np.asarray(image, np.float32)
    if scale == 1:
        return np.ascontiguousarray(img)
    H, W = img.shape[0] // scale, img.shape[1] // scale
    return cv2.resize(img[: H * scale, : W * scale], (W, H), interpolation=cv2.INTER_AREA)


def _contrast(x: np.ndarray, sigma: float, valid: np.ndarray) -> np.ndarray:
    """``x`` less its Gaussian-smoothed self (σ ``sigma`` px) over the local RMS of that (σ
    2 ``sigma``), clipped to ±6; 0 where not ``valid``. The RMS is floored at a tenth of its
    median over the readable pixels, so that a flat, noiseless stretch does not blow up."""
    hp = x - cv2.GaussianBlur(x, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    rms = np.sqrt(cv2.GaussianBlur(hp * hp, (0, 0), 2 * sigma, borderType=cv2.BORDER_REFLECT))
    sample = rms[valid] if valid.any() else rms.reshape(-1)
    floor = np.float32(max(float(np.median(sample)) * 0.1, 1e-12))
    return np.where(valid, np.clip(hp / (rms + floor), -6, 6), 0).astype(np.float32)


def _both_scales(x: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_contrast` of ``x`` at σ 12 and σ 4, the second on a thread of its own
    (:func:`ftrac_design.threads.beside`): on a second core the finer scale costs no wall time
    (24 → 19 ms per 512² input on the 2-core machine)."""
    fine = beside(_contrast, x, 4.0, valid)
    try:
        coarse = _contrast(x, 12.0, valid)
    finally:
        fine_map = fine.result()
    return coarse, fine_map


def network_input(
    image: np.ndarray, scale: int, valid: np.ndarray | None = None, side_by_side: bool = True
) -> np.ndarray:
    """The network's input (2, h, w) float32 for ``image`` (H, W), any dtype and formation.

    Two channels of local contrast — the image less its smoothed self over the local RMS of
    that — at σ 12 and σ 4 working px (:func:`_contrast`): the same for a·I + b as for I
    (a > 0; negated for a < 0: the other polarity), and for a crop as for the whole image
    (nothing is measured over the whole field of view but the RMS floor).

    Parameters
    ----------
    image : (H, W) ndarray
        The pixels as stored.
    scale : int
        The working scale (:func:`working_scale`); h = H // scale, w = W // scale, padded with
        zeros to multiples of 8 so that the network's strides divide them.
    valid : (H, W) bool ndarray, optional
        Where the image can be read (a round field, outside the blades); elsewhere the image is
        set to the median of the readable pixels before the contrast is taken, and the input
        is 0.

    side_by_side : bool
        The two scales on two threads (:func:`_both_scales`); False: one after the other, for
        a process that shares the cores with as many others (the same values either way).

    Returns
    -------
    (2, h8, w8) float32 ndarray
    """
    g = downsample(image, scale)
    v = np.isfinite(g)
    if valid is not None:
        v &= downsample(np.asarray(valid, np.float32), scale) > 0.5
    fill = np.float32(np.median(g[v])) if v.any() else np.float32(0)
    x = np.where(v, g, fill).astype(np.float32)
    step = max(1, int(math.sqrt(g.size / 65536)))
    sample = g[::step, ::step][v[::step, ::step]]
    if sample.size:
        # a stray pixel ten thousand times the image's own scale (a corrupt value, 1e38) would
        # overflow the squares of the local RMS; it is held there, where it still stands out,
        # and every pixel of a real image passes unchanged, bit for bit
        bound = np.float32(1e4 * np.abs(np.percentile(sample, [0.5, 99.5])).max())
        np.clip(x, -bound, bound, out=x)
    x -= fill  # float32 keeps its digits near zero: counts of 10⁴ carry noise of 10²
    h, w = x.shape
    H8, W8 = -(-h // 8) * 8, -(-w // 8) * 8
    out = np.zeros((2, H8, W8), np.float32)
    if side_by_side:
        out[0, :h, :w], out[1, :h, :w] = _both_scales(x, v)
    else:
        out[0, :h, :w], out[1, :h, :w] = _contrast(x, 12.0, v), _contrast(x, 4.0, v)
    return out
