"""Writing one image atomically: PNG and TIFF (8/16-bit, TIFF also float32), NumPy ``.npy``
and DICOM (a DX object through :func:`~ftrac_design.images.write_dicom.write_dicom`).

Integer images are stored as they are; float images are quantised to ``bit_depth`` bits with
a linear map whose slope and intercept are recorded (our note in PNG/TIFF, Rescale
Slope/Intercept in DICOM) so that ``value = stored × slope + intercept`` — intake applies
it. ``.npy`` keeps the array unchanged. The polarity, the camera and a free ``quantity``
label go into our note (PNG ``tEXt``, TIFF ImageDescription, DICOM ImageComments); DICOM
also states them in its own tags (Pixel Intensity Relationship and Sign, the geometry).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from ..fileio import atomic_file
from ..pose.camera import Camera
from .notes import NOTE_PREFIX

WRITE_SUFFIXES = {".png": "png", ".tif": "tiff", ".tiff": "tiff", ".npy": "npy", ".dcm": "dicom", ".dicom": "dicom"}
NotePolarity = Literal["dense_dark", "dense_bright"]
_POLARITIES: tuple[NotePolarity, ...] = get_args(NotePolarity)


def _quantise(image: np.ndarray, bit_depth: int, value_range: tuple[float, float] | None):
    """Integer pixels and (slope, intercept) with value = stored × slope + intercept."""
    if np.issubdtype(image.dtype, np.integer):
        if image.min() < 0 or image.max() > (1 << bit_depth) - 1:
            raise ValueError(f"integer pixels in 0 … {(1 << bit_depth) - 1}")
        return image.astype(np.uint8 if bit_depth <= 8 else np.uint16), None
    lo, hi = value_range if value_range is not None else (float(np.min(image)), float(np.max(image)))
    if not np.isfinite(lo) or not np.isfinite(hi):
        raise ValueError("finite pixel values")
    full = (1 << bit_depth) - 1
    slope = (hi - lo) / full if hi > lo else 1.0
    q = np.clip(np.rint((image - lo) / slope), 0, full)
    return q.astype(np.uint8 if bit_depth <= 8 else np.uint16), (slope, lo)


def write_image(
    path: str | Path,
    image: np.ndarray,
    camera: Camera | None = None,
    *,
    polarity: NotePolarity | None = None,
    bit_depth: int | None = None,
    value_range: tuple[float, float] | None = None,
    quantity: str | None = None,
) -> Path:
    """Write ``image`` (H, W) atomically; the format comes from the suffix (see the module).

    Parameters
    ----------
    path : ``.png``, ``.tif``/``.tiff``, ``.npy`` or ``.dcm``/``.dicom``.
    image : (H, W) integers or floats.
    camera : intrinsics recorded in our note (PNG/TIFF/DICOM) and DICOM's geometry tags;
        DICOM needs one.
    polarity : ``"dense_dark"``/``"dense_bright"``: how dense matter looks in ``image``.
    bit_depth : 8 or 16 (default: 8 for uint8 images, else 16) for PNG, TIFF and DICOM;
        TIFF keeps float32/float64 images as float32 unless it is given.
    value_range : the float range mapped onto the integers (default: the image's min–max).
    quantity : a free label (``"log"``, ``"raw"``, …) kept in the note; for DICOM ``log`` and
        ``raw`` also set Pixel Intensity Relationship LOG / LIN.

    Returns
    -------
    Path : ``path``.
    """
    path = Path(path)
    fmt = WRITE_SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise ValueError(f"an image suffix ({', '.join(WRITE_SUFFIXES)}), got {path.suffix!r}")
    image = np.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"a 2-D image, got shape {image.shape}")
    if polarity is not None and polarity not in _POLARITIES:
        raise ValueError(f"polarity: one of {_POLARITIES}")
    note: dict[str, Any] = {}
    if polarity:
        note["polarity"] = polarity
    if camera is not None:
        note["camera"] = camera.to_dict()
    if quantity:
        note["quantity"] = quantity
    if fmt == "npy":
        with atomic_file(path) as tmp:
            np.save(tmp, image, allow_pickle=False)
        # np.save appends .npy only when missing: the temporary name already ends in it
        return path
    if fmt == "tiff" and bit_depth is None and image.dtype in (np.float32, np.float64):
        import tifffile

        with atomic_file(path) as tmp:
            tifffile.imwrite(tmp, image.astype(np.float32), description=NOTE_PREFIX + json.dumps(note), metadata=None)
        return path
    if bit_depth is None:
        bit_depth = 8 if image.dtype == np.uint8 else 16
    if bit_depth not in (8, 16):
        raise ValueError(f"bit_depth: 8 or 16, got {bit_depth!r}")
    q, rescale = _quantise(image, bit_depth, value_range)
    if fmt == "dicom":
        return _write_dx(path, q, camera, rescale, note, bit_depth)
    if rescale is not None:
        note["rescale_slope"], note["rescale_intercept"] = rescale
    if fmt == "png":
        from PIL import Image
        from PIL.PngImagePlugin import PngInfo

        info = PngInfo()
        info.add_text("ftrac", json.dumps(note))
        with atomic_file(path) as tmp:
            Image.fromarray(q).save(tmp, format="PNG", pnginfo=info)
    else:
        import tifffile

        with atomic_file(path) as tmp:
            tifffile.imwrite(tmp, q, description=NOTE_PREFIX + json.dumps(note), metadata=None)
    return path


def _write_dx(path: Path, q: np.ndarray, camera: Camera | None, rescale, note: dict, bit_depth: int) -> Path:
    from .write_dicom import write_dicom

    if camera is None:
        raise ValueError("DICOM needs a camera (ImagerPixelSpacing, DistanceSourceToDetector)")
    raw = note.get("polarity") == "dense_dark"
    return write_dicom(
        path,
        q.astype(np.uint16),
        camera,
        kind="dx",
        relationship={"log": "LOG", "raw": "LIN"}.get(note.get("quantity")),
        relationship_sign={"dense_dark": 1, "dense_bright": -1}.get(note.get("polarity")),
        bits_stored=bit_depth if q.dtype == np.uint16 else 8,
        rescale=rescale,
        image_comments=NOTE_PREFIX + json.dumps(note),
        presentation_intent="FOR PROCESSING" if raw else "FOR PRESENTATION",
    )
