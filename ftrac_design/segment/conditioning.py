"""From the pixels as stored to the density image the detectors work on, and where the image
can be read at all.

Images come in three formations: **linear** detector counts (dense = dark; the log of the
Beer–Lambert law makes a ball's contrast the same over any background), **log** /
line-integral images (linear in density already) and **display**-processed frames (window,
gamma, edge enhancement, 8 bits: a monotone map of either, in either polarity). Only linear
counts are logged: a display frame's black-clipped pixels would become −ln 0, and its gamma
is locally a gain that the local noise map (:func:`.image.noise_map`) takes out anyway.

Where an image holds no information — outside a round image-intensifier field or behind a
collimator that clipped it to black, in saturated or black-clipped regions of a display
frame — it is marked *invalid*: regions of pixels at the image's extreme values that are
wider than a ball (an opening with the top-hat's disc keeps balls and wires that happen to
be clipped), grown by a margin so that the field edge's blur and edge-enhancement overshoot
are left out too. Nothing is detected there, and a feature predicted there counts neither
for nor against a labelling.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

Formation = Literal["linear", "log", "display"]
FORMATIONS: tuple[str, ...] = ("linear", "log", "display")


@dataclass(frozen=True)
class Conditioned:
    """A density image (float32, dense = bright) and where it is valid."""

    density: np.ndarray
    #: True where the image holds information; None: everywhere
    valid: np.ndarray | None
    polarity: str
    formation: str


def formation_of(image: np.ndarray, polarity: str, hint: str | None = None) -> str:
    """The formation of ``image``: ``hint`` when given (a header's LIN / LOG / DISP), else
    "display" for 8-bit pixel values (0–255 integers: what a frame grabber or a screen
    capture holds), else "linear" for a dense-dark image (raw counts) and "log" for a
    dense-bright one."""
    if hint in FORMATIONS:
        return str(hint)
    a = np.asarray(image)
    if a.size and float(a.min()) >= 0 and float(a.max()) <= 255:
        if np.issubdtype(a.dtype, np.integer) or bool(np.all(a == np.round(a))):
            return "display"
    return "linear" if polarity == "dense-dark" else "log"


def to_density(image: np.ndarray, polarity: str, formation: str = "linear") -> np.ndarray:
    """The density image (float32, dense = bright) of ``image`` of known ``polarity``
    ("dense-dark" / "dense-bright") and ``formation`` (see :func:`formation_of`): linear
    dense-dark counts are logged (−ln), everything else is used as it is or negated."""
    img = np.asarray(image, dtype=np.float32)
    if polarity not in ("dense-dark", "dense-bright"):
        raise ValueError(f"polarity must be dense-dark or dense-bright, got {polarity!r}")
    if formation == "linear" and polarity == "dense-dark":
        lo = max(float(img.max()) * 1e-5, 1e-6)
        return -cv2.log(np.maximum(img, np.float32(lo)))
    if polarity == "dense-bright":
        return img
    return -img


def invalid_regions(image: np.ndarray, disc_px: int, margin_px: int) -> np.ndarray | None:
    """Pixels that hold no information (bool, True = invalid), or None when there are none:
    regions at the image's lowest or highest value (clipped: a shutter, black outside a round
    field, saturation) wider than the disc of radius ``disc_px``, grown by ``margin_px``."""
    a = np.asarray(image, dtype=np.float32)
    lo, hi = float(a.min()), float(a.max())
    if not hi > lo:
        return None
    # a display frame's black is rarely one exact value (analogue video noise, compression):
    # within 1 % of the range of the extremes is clipped
    tol = 0.01 * (hi - lo) if hi - lo <= 255.0 else 0.0
    ext = ((a <= lo + tol) | (a >= hi - tol)).astype(np.uint8)
    if ext.sum() < (2 * disc_px + 1) ** 2:
        return None
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * disc_px + 1, 2 * disc_px + 1))
    ext = cv2.morphologyEx(ext, cv2.MORPH_OPEN, k)
    if not ext.any():
        return None
    m = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1, 2 * margin_px + 1))
    return cv2.dilate(ext, m).astype(bool)


def condition(image: np.ndarray, polarity: str, formation: str | None, disc_px: int) -> Conditioned:
    """The density image of ``image`` and its valid pixels (see the module).

    Parameters
    ----------
    image : (H, W) pixels as stored.
    polarity : "dense-dark" or "dense-bright".
    formation : "linear", "log", "display" or None (found by :func:`formation_of`).
    disc_px : the top-hat's disc radius, px: clipped regions narrower than it are kept, and
        the margin left out beside a clipped region is this wide.

    Returns
    -------
    Conditioned
    """
    form = formation_of(image, polarity, formation)
    bad = invalid_regions(image, disc_px, disc_px + 2)
    return Conditioned(to_density(image, polarity, form), None if bad is None else ~bad, polarity, form)
