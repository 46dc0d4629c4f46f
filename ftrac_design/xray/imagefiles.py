"""Image files: PNG and TIFF (8/16-bit), NumPy ``.npy`` and DICOM, read and written.

Reading returns the pixel values as stored (float64, no polarity change, no rescale), the
camera when the file says it (DICOM: ImagerPixelSpacing (0018,1164) = [row, column]
spacing = [s_y, s_x] mm and DistanceSourceToDetector (0018,1110) = f mm; principal point
from our own header note when present, else the image centre ((W − 1)/2, (H − 1)/2)), and
metadata ``{"format", "bits", "polarity_hint", ...}``. ``polarity_hint`` says how dense
matter looks in the stored values: ``"dense_dark"`` (raw detector counts), ``"dense_bright"``
(flat-field/log or display images) or None when the file does not say.

Writing picks the format from the suffix (``.png``, ``.tif``/``.tiff``, ``.npy``,
``.dcm``/``.dicom``) and is atomic. Integer images are stored as they are (8- or 16-bit);
float images are quantised to ``bit_depth`` bits with a linear map whose slope and
intercept are recorded (PNG text, TIFF description, DICOM RescaleSlope/RescaleIntercept)
so that ``value = stored × slope + intercept``. ``.npy`` keeps the array unchanged. The
polarity (and for PNG/TIFF the camera) goes into the file's metadata: PNG ``tEXt`` chunks,
the TIFF ImageDescription (JSON), DICOM ImageComments.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..fileio import atomic_file
from ..pose.camera import Camera

SUFFIXES = {".png": "png", ".tif": "tiff", ".tiff": "tiff", ".npy": "npy", ".dcm": "dicom", ".dicom": "dicom"}
_POLARITIES = ("dense_dark", "dense_bright")
_NOTE = "ftrac:"


def _format_of(path: Path) -> str:
    fmt = SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        try:
            with open(path, "rb") as fh:
                head = fh.read(132)
            if head[128:132] == b"DICM":
                return "dicom"
        except OSError:
            pass
        raise InputError(path, None, f"an image file ({', '.join(SUFFIXES)})")
    return fmt


def _gray(img: np.ndarray, path: Path) -> np.ndarray:
    if img.ndim == 3 and img.shape[-1] in (3, 4):
        rgb = img[..., :3].astype(np.float64)
        if np.all(rgb[..., 0] == rgb[..., 1]) and np.all(rgb[..., 1] == rgb[..., 2]):
            return rgb[..., 0]
        return rgb @ np.array([0.2126, 0.7152, 0.0722])        # Rec. 709 luminance
    if img.ndim == 3 and img.shape[-1] == 2:                     # grey + alpha
        return img[..., 0].astype(np.float64)
    if img.ndim != 2:
        raise InputError(path, "pixels", f"a 2-D grey-scale image, got an array of shape {img.shape}")
    return img.astype(np.float64)


def _camera_from_dict(d: Any) -> Camera | None:
    try:
        return Camera(float(d["focal_length_mm"]), tuple(float(x) for x in d["pixel_size_mm"]),
                      tuple(float(x) for x in d["principal_point_px"]))
    except (KeyError, TypeError, ValueError):
        return None


def read_image(path: str | Path, camera: Camera | None = None) -> tuple[np.ndarray, Camera | None, dict]:
    """Read an image: (pixels (H, W) float64 as stored, camera, metadata) — see the module.

    ``camera`` overrides what the file says (``--camera C.json``); without it a DICOM file
    must carry ImagerPixelSpacing (0018,1164) and DistanceSourceToDetector (0018,1110), else
    InputError names the missing tag. Other formats return their camera as None (metadata
    ``"camera"`` holds what our own writer noted). Unreadable or malformed files raise
    :class:`~ftrac_design.errors.InputError` (file, key, expected).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "an existing image file")
    fmt = _format_of(path)
    reader = {"png": _read_png, "tiff": _read_tiff, "npy": _read_npy, "dicom": _read_dicom}[fmt]
    img, cam, meta = reader(path, camera is not None)
    if img.size == 0 or img.shape[0] < 2 or img.shape[1] < 2:
        raise InputError(path, "pixels", f"an image of at least 2 × 2 pixels, got shape {img.shape}")
    if not np.all(np.isfinite(img)):
        raise InputError(path, "pixels", "finite pixel values")
    # the segmentation works in float32: a value beyond its range becomes inf there
    if np.abs(img).max() > np.finfo(np.float32).max:
        raise InputError(path, "pixels", f"pixel values within ±{np.finfo(np.float32).max:.3g} (float32), "
                                         f"got {np.abs(img).max():.3g}")
    meta.setdefault("polarity_hint", None)
    meta["format"] = fmt
    return img, (camera if camera is not None else cam), meta


def _note_meta(text: str | None) -> dict:
    """Our JSON note from a header text (PNG tEXt, TIFF description, DICOM comment)."""
    if not text:
        return {}
    i = text.find(_NOTE)
    blob = text[i + len(_NOTE):] if i >= 0 else text
    try:
        d = json.loads(blob)
    except ValueError:
        return {}
    return d if isinstance(d, dict) else {}


def _apply_note(meta: dict, note: dict) -> None:
    if note.get("polarity") in _POLARITIES:
        meta["polarity_hint"] = note["polarity"]
    for k in ("rescale_slope", "rescale_intercept", "camera", "quantity"):
        if k in note:
            meta[k] = note[k]


def _read_png(path: Path, _override: bool):
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(path) as im:
            im.load()
            text = dict(getattr(im, "text", {}) or {})
            mode = im.mode
            arr = np.array(im)
    except (UnidentifiedImageError, Image.DecompressionBombError, OSError, EOFError, SyntaxError, ValueError) as exc:
        raise InputError(path, None, f"a readable PNG image ({exc})") from None
    bits = 16 if arr.dtype in (np.uint16, np.int32) and mode.startswith("I") else 8 * arr.dtype.itemsize
    meta: dict[str, Any] = {"bits": int(bits)}
    _apply_note(meta, _note_meta(text.get("ftrac")))
    return _gray(arr, path), None, meta


def _read_tiff(path: Path, _override: bool):
    import tifffile
    try:
        with tifffile.TiffFile(path) as tf:
            page = tf.pages[0]
            arr = page.asarray()
            desc = page.description or ""
            bits = int(page.bitspersample)
    except Exception as exc:          # tifffile raises many types for malformed files
        raise InputError(path, None, f"a readable TIFF image ({type(exc).__name__}: {exc})") from None
    meta: dict[str, Any] = {"bits": bits}
    note = _note_meta(desc)
    _apply_note(meta, note.get("ftrac", note) if isinstance(note.get("ftrac"), dict) else note)
    return _gray(arr, path), None, meta


def _read_npy(path: Path, _override: bool):
    try:
        arr = np.load(path, allow_pickle=False)
    except Exception as exc:  # np.load raises many types for malformed files (EOFError, TokenError, …)
        raise InputError(path, None, f"a NumPy .npy array ({type(exc).__name__}: {exc})") from None
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise InputError(path, "dtype", f"a real numeric array, got {arr.dtype}")
    bits = 8 * arr.dtype.itemsize
    return _gray(arr, path), None, {"bits": int(bits)}


def _read_dicom(path: Path, override: bool):
    import pydicom
    try:
        ds = pydicom.dcmread(path)
        arr = ds.pixel_array
    except Exception as exc:  # pydicom raises many types for malformed files (NotImplementedError for an
        # unknown transfer syntax, InvalidDicomError, KeyError, EOFError, …)
        raise InputError(path, None, f"a readable DICOM image with pixel data ({type(exc).__name__}: {exc})") from None
    if arr.ndim == 3 and getattr(ds, "SamplesPerPixel", 1) == 1:
        arr = arr[0]                                     # first frame of a multi-frame image
    meta: dict[str, Any] = {"bits": int(getattr(ds, "BitsStored", 8 * arr.dtype.itemsize)),
                            "photometric": str(getattr(ds, "PhotometricInterpretation", ""))}
    if "RescaleSlope" in ds or "RescaleIntercept" in ds:
        meta["rescale_slope"] = float(getattr(ds, "RescaleSlope", 1.0))
        meta["rescale_intercept"] = float(getattr(ds, "RescaleIntercept", 0.0))
    note = _note_meta(str(getattr(ds, "ImageComments", "") or ""))
    # without our note, DICOM's own conventions: MONOCHROME1 displays low values white, so
    # dense matter (shown white) is stored low; a MONOCHROME2 image meant for presentation
    # shows it white (stored high), one meant for processing holds detector signal (low)
    if meta["photometric"] == "MONOCHROME1":
        meta["polarity_hint"] = "dense_dark"
    elif meta["photometric"] == "MONOCHROME2":
        intent = str(getattr(ds, "PresentationIntentType", "")).upper()
        meta["polarity_hint"] = {"FOR PRESENTATION": "dense_bright", "FOR PROCESSING": "dense_dark"}.get(intent)
    _apply_note(meta, note)
    img = _gray(np.asarray(arr), path)
    cam = None
    missing = [f"{name} ({tag})" for name, tag in (("ImagerPixelSpacing", "0018,1164"),
                                                    ("DistanceSourceToDetector", "0018,1110")) if name not in ds]
    if missing and not override:
        raise InputError(path, missing[0], "the DICOM tag giving the camera geometry, or a --camera C.json "
                                           "(SPEC §3 camera object) that supplies it")
    if not missing:
        try:
            sy, sx = (float(x) for x in ds.ImagerPixelSpacing)
            f = float(ds.DistanceSourceToDetector)
        except (TypeError, ValueError):
            if not override:
                raise InputError(path, "ImagerPixelSpacing (0018,1164)", "two positive numbers (row, column "
                                 "spacing, mm) and a DistanceSourceToDetector (0018,1110) in mm") from None
        else:
            H, W = img.shape
            pp = ((W - 1) / 2.0, (H - 1) / 2.0)
            noted = _camera_from_dict(note.get("camera")) if note.get("camera") else None
            if noted is not None:
                pp = noted.principal_point_px
            cam = Camera(f, (sx, sy), pp)
            try:
                cam.validate()
            except ValueError as exc:
                if not override:
                    raise InputError(path, "ImagerPixelSpacing (0018,1164)", f"positive spacing and distance ({exc})") from None
                cam = None
    return img, cam, meta


# ----------------------------------------------------------------------------- writing
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


def write_image(path: str | Path, image: np.ndarray, camera: Camera | None = None, *,
                polarity: str | None = None, bit_depth: int | None = None,
                value_range: tuple[float, float] | None = None, quantity: str | None = None) -> Path:
    """Write ``image`` (H, W) atomically; the format comes from the suffix (see module).

    ``bit_depth`` (8 or 16; default: 8 for uint8 images, else 16) applies to PNG, TIFF and
    DICOM; float images are mapped linearly from ``value_range`` (default: their min–max).
    TIFF keeps float32/float64 images as floats unless ``bit_depth`` is given. ``polarity``
    (``"dense_dark"``/``"dense_bright"``) and ``camera`` are recorded where the format allows;
    DICOM needs ``camera`` (its ImagerPixelSpacing and DistanceSourceToDetector).
    ``quantity`` is a free label (e.g. ``"log"``, ``"raw"``) kept in the metadata.
    """
    path = Path(path)
    fmt = SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise ValueError(f"an image suffix ({', '.join(SUFFIXES)}), got {path.suffix!r}")
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
            tifffile.imwrite(tmp, image.astype(np.float32), description=_NOTE + json.dumps(note), metadata=None)
        return path
    if bit_depth is None:
        bit_depth = 8 if image.dtype == np.uint8 else 16
    if bit_depth not in (8, 16):
        raise ValueError(f"bit_depth: 8 or 16, got {bit_depth!r}")
    q, rescale = _quantise(image, bit_depth, value_range)
    if rescale is not None:
        note["rescale_slope"], note["rescale_intercept"] = rescale
    if fmt == "png":
        from PIL import Image
        from PIL.PngImagePlugin import PngInfo
        info = PngInfo()
        info.add_text("ftrac", json.dumps(note))
        im = Image.fromarray(q) if q.dtype == np.uint8 else Image.fromarray(q.astype(np.uint16))
        with atomic_file(path) as tmp:
            im.save(tmp, format="PNG", pnginfo=info)
    elif fmt == "tiff":
        import tifffile
        with atomic_file(path) as tmp:
            tifffile.imwrite(tmp, q, description=_NOTE + json.dumps(note), metadata=None)
    else:
        if camera is None:
            raise ValueError("DICOM needs a camera (ImagerPixelSpacing, DistanceSourceToDetector)")
        _write_dicom(path, q, camera, rescale, note, bit_depth)
    return path


def _write_dicom(path: Path, q: np.ndarray, camera: Camera, rescale, note: dict, bit_depth: int) -> None:
    import datetime

    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    dx_presentation = "1.2.840.10008.5.1.4.1.1.1.1"
    dx_processing = "1.2.840.10008.5.1.4.1.1.1.1.1"
    raw = note.get("polarity") == "dense_dark"
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = dx_processing if raw else dx_presentation
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
    now = datetime.datetime.now(datetime.timezone.utc)
    ds.SOPClassUID = meta.MediaStorageSOPClassUID
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.StudyInstanceUID = generate_uid()
    ds.SeriesInstanceUID = generate_uid()
    ds.Modality = "DX"
    ds.PresentationIntentType = "FOR PROCESSING" if raw else "FOR PRESENTATION"
    ds.ContentDate = now.strftime("%Y%m%d")
    ds.ContentTime = now.strftime("%H%M%S")
    ds.PatientName = "FTRAC^PHANTOM"
    ds.PatientID = "ftrac-sim"
    ds.Manufacturer = "ftrac_design (simulated)"
    ds.ImageType = ["DERIVED", "SECONDARY"]
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.Rows, ds.Columns = q.shape
    ds.BitsAllocated = 16
    ds.BitsStored = bit_depth if q.dtype == np.uint16 else 8
    ds.HighBit = ds.BitsStored - 1
    ds.PixelRepresentation = 0
    sx, sy = camera.pixel_size_mm
    ds.ImagerPixelSpacing = [f"{sy:.10g}", f"{sx:.10g}"]
    ds.DistanceSourceToDetector = f"{camera.focal_length_mm:.10g}"
    if rescale is not None:
        ds.RescaleSlope = f"{rescale[0]:.10g}"
        ds.RescaleIntercept = f"{rescale[1]:.10g}"
        ds.RescaleType = "US"
    ds.ImageComments = _NOTE + json.dumps(note)
    ds.PixelData = q.astype(np.uint16).tobytes()
    with atomic_file(path) as tmp:
        ds.save_as(tmp, enforce_file_format=True)
