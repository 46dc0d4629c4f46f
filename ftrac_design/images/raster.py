"""PNG, JPEG and TIFF intake: 8/16-bit PNG (grey, grey+alpha, RGB, RGBA, palette), 8-bit
JPEG (lossy: a note says so), TIFF of 8/16/32-bit integers or floats with one frame per page
(a multi-page TIFF is a run). Colour becomes Rec. 709 grey and alpha is dropped, each with a
note; our own note (PNG ``tEXt`` ``ftrac``, TIFF ImageDescription) gives the camera, the
polarity, the formation and the linear map of quantised values, which is applied.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..errors import InputError
from ..pose.camera import Camera
from .frame import Frame, check_frame_size, finish_pixels, to_grey
from .notes import camera_from_note, note_formation, note_polarity, note_rescale, parse_note


def make_frame(
    path: Path,
    arr: np.ndarray,
    note: dict[str, Any],
    meta: dict[str, Any],
    index: int,
    camera: Camera | None,
    need_camera: bool,
    notes: tuple[str, ...] = (),
) -> Frame:
    """A :class:`Frame` from a non-DICOM image array and our note (shared by PNG, JPEG, TIFF, NumPy).

    Parameters
    ----------
    path, arr : the file and its (H, W[, C]) samples.
    note : our header note ({} when none).
    meta : format, bits, … (copied into the frame).
    index : the frame's 0-based index in the file or run.
    camera : ``--camera`` intrinsics, overriding the note's.
    need_camera : without a camera from either, raise InputError (True) or give None (False).
    notes : notes the caller already has.
    """
    grey, more = to_grey(arr, path)
    notes = tuple(notes) + more
    rescale = note_rescale(note)
    if rescale is not None:
        grey = grey * rescale[0] + rescale[1]
        notes += (f"our note's linear map applied (value = stored × {rescale[0]:g} + {rescale[1]:g})",)
    pixels = finish_pixels(grey, path)
    if camera is not None:
        cam, source = camera, dict.fromkeys(("focal_length", "pixel_size", "principal_point"), "--camera")
    else:
        cam = camera_from_note(note.get("camera")) if note.get("camera") is not None else None
        source = dict.fromkeys(("focal_length", "pixel_size", "principal_point"), "ftrac note") if cam else {}
        if cam is None and need_camera:
            raise InputError(
                path,
                "camera",
                f"camera intrinsics: a {meta.get('format', 'image').upper()} file "
                f"carries none; supply --camera C.json (SPEC §3 camera object), or "
                f"estimate them from the fiducial over several frames (intrinsics from "
                f"the fiducial, as `ftrac-design reconstruct` does)",
            )
    meta = dict(meta)
    if note:
        meta["note"] = note
    return Frame(pixels, cam, source, note_formation(note), note_polarity(note), str(path), index, None, notes, meta)


# ----------------------------------------------------------------------------- PNG / JPEG
def pil_frame_count(path: Path) -> int:
    """One frame per PNG or JPEG file (header checked)."""
    _open_pil(path, load=False)
    return 1


def _open_pil(path: Path, load: bool) -> tuple[np.ndarray | None, dict[str, str], str, str]:
    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(path) as im:
                fmt = (im.format or "").lower()
                w, h = im.size
                bands = len(im.getbands())
                check_frame_size(path, (h, w), "image size (header)", 2 * bands)
                if not load:
                    return None, {}, im.mode, fmt
                im.load()
                text = {k: v for k, v in (getattr(im, "text", {}) or {}).items() if isinstance(v, str)}
                mode = im.mode
                if mode in ("P", "PA"):
                    im = im.convert("RGBA" if "transparency" in im.info or mode == "PA" else "RGB")
                elif mode in ("CMYK", "YCbCr", "LAB", "HSV", "1"):
                    im = im.convert("L" if mode == "1" else "RGB")
                arr = np.array(im)
    except InputError:
        raise
    except (
        UnidentifiedImageError,
        Image.DecompressionBombError,
        OSError,
        EOFError,
        SyntaxError,
        ValueError,
        TypeError,
        MemoryError,
        AttributeError,
    ) as exc:
        raise InputError(path, None, f"a readable PNG/JPEG image ({type(exc).__name__}: {exc})") from None
    return arr, text, mode, fmt


def read_pil_frames(path: Path, camera: Camera | None, need_camera: bool, first_index: int = 0) -> Iterator[Frame]:
    """The one frame of a PNG or JPEG file."""
    arr, text, mode, fmt = _open_pil(path, load=True)
    fmt = "jpeg" if fmt in ("jpeg", "mpo") else fmt or "png"
    bits = 16 if arr.dtype in (np.uint16, np.int32, np.int16) and mode.startswith("I") else 8 * arr.dtype.itemsize
    notes: tuple[str, ...] = ()
    if fmt == "jpeg":
        notes = ("JPEG: lossy compression has altered the pixel values",)
    note = parse_note(text.get("ftrac"))
    yield make_frame(
        path, arr, note, {"format": fmt, "bits": int(bits), "mode": mode}, first_index, camera, need_camera, notes
    )


# ----------------------------------------------------------------------------- TIFF
def _pages(tf: Any, path: Path) -> list[Any]:
    pages = list(tf.pages)
    if not pages:
        raise InputError(path, None, "a TIFF with at least one page")
    return pages


def _tiff(path: Path) -> Any:
    import tifffile

    try:
        return tifffile.TiffFile(path)
    except Exception as exc:  # tifffile raises many types for malformed files
        raise InputError(path, None, f"a readable TIFF image ({type(exc).__name__}: {exc})") from None


def _page_shape(page: Any, path: Path, k: int) -> tuple[int, ...]:
    try:
        shape = tuple(int(x) for x in page.shape)
        itemsize = int(np.dtype(page.dtype).itemsize) if page.dtype is not None else 1
    except Exception as exc:
        raise InputError(path, f"page {k}", f"a readable TIFF page ({type(exc).__name__}: {exc})") from None
    if len(shape) == 3 and shape[0] in (3, 4) and shape[-1] not in (3, 4):  # planar RGB
        shape = shape[1:] + shape[:1]
    if len(shape) not in (2, 3):
        raise InputError(path, f"page {k}", f"a 2-D grey or RGB(A) page, got shape {shape}")
    check_frame_size(path, shape, f"page {k}", itemsize * (shape[2] if len(shape) == 3 else 1))
    return shape


def tiff_frame_count(path: Path) -> int:
    """Pages of a TIFF file (one frame each; headers checked, no pixel decoded)."""
    with _tiff(path) as tf:
        try:
            pages = _pages(tf, path)
        except InputError:
            raise
        except Exception as exc:
            raise InputError(path, None, f"a readable TIFF image ({type(exc).__name__}: {exc})") from None
        shapes = [_page_shape(p, path, k) for k, p in enumerate(pages)]
    for k, s in enumerate(shapes):
        if s[:2] != shapes[0][:2]:
            raise InputError(
                path, f"page {k}", f"pages of one shape (a run): page 0 is {shapes[0][:2]}, page {k} is {s[:2]}"
            )
    return len(shapes)


def read_tiff_frames(path: Path, camera: Camera | None, need_camera: bool, first_index: int = 0) -> Iterator[Frame]:
    """One frame per TIFF page, decoded page by page; pages must share one shape."""
    n = tiff_frame_count(path)
    with _tiff(path) as tf:
        pages = _pages(tf, path)
        note = parse_note(pages[0].description or "")
        for k in range(n):
            try:
                arr = pages[k].asarray()
                bits = int(pages[k].bitspersample)
            except Exception as exc:  # tifffile raises many types for damaged pages
                raise InputError(path, f"page {k}", f"a decodable TIFF page ({type(exc).__name__}: {exc})") from None
            if arr.ndim == 3 and arr.shape[0] in (3, 4) and arr.shape[-1] not in (3, 4):
                arr = np.moveaxis(arr, 0, -1)
            notes = ("multi-page TIFF: one frame per page",) if n > 1 and k == 0 else ()
            if arr.dtype.kind in "iu" and arr.dtype.itemsize >= 4 and arr.size and np.abs(arr).max() > 2**24:
                notes += ("integers beyond 2^24 rounded to float32",)
            if arr.dtype.kind == "c":
                raise InputError(path, f"page {k}", f"real pixel values, got {arr.dtype}")
            yield make_frame(
                path,
                arr,
                note,
                {"format": "tiff", "bits": bits, "dtype": str(arr.dtype), "page": k},
                first_index + k,
                camera,
                need_camera,
                notes,
            )
