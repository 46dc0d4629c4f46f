"""The :class:`Frame` every reader yields, and the checks and conversions all formats share.

A frame's ``pixels`` are float32 on the detector's own pixel grid (SPEC §1 *Image
orientation*), in modality values: a DICOM Modality LUT or Rescale Slope/Intercept, or our
own note's linear map, applied; a VOI LUT or window never (it is for display).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Mapping

import numpy as np

from ..errors import InputError
from ..pose.camera import Camera

Formation = Literal["linear", "log", "display"]
Polarity = Literal["dense-dark", "dense-bright"]

#: the most pixels one frame may hold (a 4096 × 4096 detector); a header claiming more is
#: refused before anything is allocated
MAX_FRAME_PIXELS = 4096 * 4096
#: the most bytes one stored frame may take (4096² samples of 32 bits, or 4096² RGB bytes)
MAX_FRAME_BYTES = 4096 * 4096 * 4

REC709 = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class Frame:
    """One image of a file or a run, ready for measurement.

    Attributes
    ----------
    pixels : (H, W) float32 on the detector's grid (FOV rotation/flip undone), modality values.
    camera : intrinsics in the detector grid's pixels, or None (``need_camera=False``).
    camera_source : where each intrinsic came from: keys ``focal_length``, ``pixel_size``,
        ``principal_point``; values name the tag (e.g. ``"DistanceSourceToDetector (0018,1110)"``),
        ``"--camera"``, ``"ftrac note"`` or ``"image centre"``.
    formation : how the values relate to the beam intensity (DICOM LIN / LOG / DISP, or our
        note), None when the file does not say.
    polarity : how dense matter looks in ``pixels``, None when unknown.
    source : the file the frame came from.
    index : 0-based frame index within the file or the run.
    time_s : the frame's time in the run (s), None when the file gives none.
    notes : what intake did that a user should know.
    meta : bits, format, modality, SOP class, transfer syntax, our note, …
    """

    pixels: np.ndarray
    camera: Camera | None
    camera_source: dict[str, str]
    formation: Formation | None
    polarity: Polarity | None
    source: str
    index: int
    time_s: float | None = None
    notes: tuple[str, ...] = ()
    meta: Mapping[str, Any] = field(default_factory=dict)


def check_frame_size(path: str | Path, shape: tuple[int, ...], key: str, bytes_per_pixel: int = 2) -> None:
    """Refuse a frame of ``shape`` (rows, columns, …) before allocating it.

    Parameters
    ----------
    path : the file (for the error).
    shape : (rows, columns[, samples]) the header claims.
    key : the header key that claims it (named in the error).
    bytes_per_pixel : bytes one pixel takes as stored (all samples).
    """
    rows, cols = int(shape[0]), int(shape[1])
    if rows < 2 or cols < 2:
        raise InputError(path, key, f"an image of at least 2 × 2 pixels, got {rows} × {cols}")
    if rows * cols > MAX_FRAME_PIXELS or rows * cols * bytes_per_pixel > MAX_FRAME_BYTES:
        raise InputError(
            path, key, f"at most {MAX_FRAME_PIXELS} pixels ({MAX_FRAME_BYTES >> 20} MiB) a frame, got {rows} × {cols}"
        )


def to_grey(img: np.ndarray, path: str | Path) -> tuple[np.ndarray, tuple[str, ...]]:
    """A 2-D float64 grey image from a grey, grey+alpha, RGB or RGBA array, and the notes.

    RGB becomes Rec. 709 luminance (0.2126 R + 0.7152 G + 0.0722 B) unless the three channels
    are equal; an alpha channel is dropped. Anything else is an InputError.
    """
    notes: list[str] = []
    if img.ndim == 3 and img.shape[-1] in (2, 4):
        notes.append("alpha channel dropped")
        img = img[..., :-1]
    if img.ndim == 3 and img.shape[-1] == 1:
        img = img[..., 0]
    if img.ndim == 3 and img.shape[-1] == 3:
        rgb = img.astype(np.float64)
        if np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 1], rgb[..., 2]):
            notes.append("RGB with equal channels read as grey")
            return rgb[..., 0], tuple(notes)
        notes.append("RGB converted to grey (Rec. 709 luminance)")
        return rgb @ REC709, tuple(notes)
    if img.ndim != 2:
        raise InputError(path, "pixels", f"a 2-D grey-scale or RGB(A) image, got an array of shape {img.shape}")
    return img.astype(np.float64, copy=False), tuple(notes)


def finish_pixels(img: np.ndarray, path: str | Path) -> np.ndarray:
    """``img`` as a C-contiguous float32 (H, W) array, or InputError when it is too small,
    not finite, or beyond float32's range (the segmentation works in float32)."""
    if img.ndim != 2 or img.shape[0] < 2 or img.shape[1] < 2:
        raise InputError(path, "pixels", f"an image of at least 2 × 2 pixels, got shape {img.shape}")
    if img.dtype == np.bool_:
        img = img.astype(np.uint8)
    if img.dtype.kind in "iu":
        # every integer is finite and within float32's range: converted once, unchecked
        return np.ascontiguousarray(img, dtype=np.float32)
    with np.errstate(all="ignore"):
        big = float(np.max(np.abs(img.astype(np.float64, copy=False)))) if img.size else 0.0
    if not np.isfinite(big):
        raise InputError(path, "pixels", "finite pixel values")
    limit = float(np.finfo(np.float32).max)
    if big > limit:
        raise InputError(path, "pixels", f"pixel values within ±{limit:.3g} (float32), got {big:.3g}")
    return np.ascontiguousarray(img, dtype=np.float32)


def polarity_from_legacy(hint: Any) -> Polarity | None:
    """``"dense_dark"``/``"dense_bright"`` (our note, the old hint) → the Frame's spelling."""
    return (
        {
            "dense_dark": "dense-dark",
            "dense_bright": "dense-bright",
            "dense-dark": "dense-dark",
            "dense-bright": "dense-bright",
        }.get(hint)
        if isinstance(hint, str)
        else None
    )


def legacy_hint(polarity: Polarity | None) -> str | None:
    """The Frame's polarity in the old ``polarity_hint`` spelling (``"dense_dark"`` …)."""
    return polarity.replace("-", "_") if polarity else None


def flip_polarity(polarity: Polarity | None) -> Polarity | None:
    """The other polarity (a decreasing value map turns dense-dark into dense-bright)."""
    return {"dense-dark": "dense-bright", "dense-bright": "dense-dark"}.get(polarity) if polarity else None
