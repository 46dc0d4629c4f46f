"""PNG, JPEG, BMP, GIF, WebP and TIFF intake: 8/16-bit PNG (grey, grey+alpha, RGB, RGBA,
palette), 8-bit JPEG (lossy: a note says so), BMP (1/4/8-bit palette, 16/24/32-bit colour, as
a C-arm workstation's screen capture is), GIF and WebP (a frame per image of an animated one;
lossy WebP noted), TIFF of 8/16/32-bit integers or floats with one frame per page (a
multi-page TIFF is a run; palette, bilevel, CMYK and YCbCr pages, and compressions tifffile
cannot decode, through Pillow). Colour becomes Rec. 709 grey and alpha is dropped, each with a
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


# ----------------------------------------------------------------------------- Pillow's formats
#: the Pillow formats that may hold several frames, each a frame of a run (an animated GIF or
#: WebP a grabber wrote); a PNG or JPEG is one frame whatever extra images it carries
_MULTI_FRAME = ("gif", "webp")
#: Pillow's errors for a damaged or lying file
_PIL_ERRORS: tuple[type[BaseException], ...] = (
    OSError,
    EOFError,
    SyntaxError,
    ValueError,
    TypeError,
    MemoryError,
    AttributeError,
    IndexError,
)


def _pil_array(im: Any) -> tuple[np.ndarray, str]:
    """The samples of the current frame of an open Pillow image and its mode (palettes looked up)."""
    mode = im.mode
    if mode in ("P", "PA"):
        im = im.convert("RGBA" if "transparency" in im.info or mode == "PA" else "RGB")
    elif mode in ("CMYK", "YCbCr", "LAB", "HSV", "1", "La"):
        im = im.convert({"1": "L", "La": "LA"}.get(mode, "RGB"))
    return np.array(im), mode


def _open_pil(path: Path, index: int | None) -> tuple[np.ndarray | None, dict[str, str], str, str, int]:
    """Open a Pillow-read file: (frame ``index``'s samples or None, text chunks, mode, format,
    frame count). The header's size is checked before anything is decoded."""
    from PIL import Image, UnidentifiedImageError

    fmt = ""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(path) as im:
                fmt = (im.format or "").lower()
                w, h = im.size
                check_frame_size(path, (h, w), "image size (header)", 2 * len(im.getbands()))
                n = int(getattr(im, "n_frames", 1)) if fmt in _MULTI_FRAME else 1
                if index is None:
                    return None, {}, im.mode, fmt, n
                if index:
                    im.seek(index)
                im.load()
                text = {k: v for k, v in (getattr(im, "text", {}) or {}).items() if isinstance(v, str)}
                arr, mode = _pil_array(im)
    except InputError:
        raise
    except (UnidentifiedImageError, Image.DecompressionBombError, *_PIL_ERRORS) as exc:
        what = {"webp": "WebP", "": "PNG, JPEG, BMP, GIF or WebP"}.get(fmt, fmt.upper())
        raise InputError(path, None, f"a readable {what} image ({type(exc).__name__}: {exc})") from None
    return arr, text, mode, fmt, n


def pil_frame_count(path: Path) -> int:
    """Frames of a file Pillow reads: one for PNG, JPEG and BMP; one per frame of a GIF or WebP
    (header checked, nothing decoded)."""
    return _open_pil(path, None)[4]


def _webp_is_lossy(path: Path) -> bool:
    """Whether a WebP file holds lossy (VP8) rather than lossless (VP8L) image data."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    k = 12
    while k + 8 <= len(head):
        tag, size = head[k : k + 4], int.from_bytes(head[k + 4 : k + 8], "little")
        if tag == b"VP8 ":
            return True
        if tag == b"VP8L":
            return False
        # an animation frame holds its image chunks after a 16-byte frame header
        k += 8 + 16 if tag == b"ANMF" else 8 + size + (size & 1)
    return False


def _pil_notes(path: Path, fmt: str, n: int, k: int) -> tuple[str, ...]:
    notes: tuple[str, ...] = ()
    if n > 1 and k == 0:
        notes += (f"animated {fmt.upper() if fmt != 'webp' else 'WebP'}: one frame per image",)
    if fmt == "jpeg" or (fmt == "webp" and _webp_is_lossy(path)):
        notes += (f"{'JPEG' if fmt == 'jpeg' else 'WebP'}: lossy compression has altered the pixel values",)
    if fmt == "gif":
        notes += ("GIF: at most 256 levels (a palette)",)
    return notes


def read_pil_frames(path: Path, camera: Camera | None, need_camera: bool, first_index: int = 0) -> Iterator[Frame]:
    """The frames of a file Pillow reads (PNG, JPEG, BMP, GIF, WebP), one decoded at a time."""
    n = pil_frame_count(path)
    for k in range(n):
        arr, text, mode, fmt, _ = _open_pil(path, k)
        fmt = "jpeg" if fmt in ("jpeg", "mpo") else fmt or "png"
        if arr.dtype in (np.uint16, np.int32, np.int16) and mode.startswith("I"):
            bits = 16
        else:
            bits = 8 * arr.dtype.itemsize
        meta = {"format": fmt, "bits": int(bits), "mode": mode}
        if n > 1:
            meta["page"] = k
        note = parse_note(text.get("ftrac"))
        yield make_frame(path, arr, note, meta, first_index + k, camera, need_camera, _pil_notes(path, fmt, n, k))


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


#: TIFF photometric interpretations (TIFF 6.0): tifffile returns their samples as stored, which for
#: these is not what the picture shows
_MINISWHITE, _PALETTE, _SEPARATED, _CIELAB = 0, 3, 5, 8


def _pillow_page(path: Path, k: int, why: str) -> np.ndarray:
    """Page ``k`` of a TIFF decoded by Pillow (libtiff), for what tifffile cannot decode or
    returns as stored samples (CMYK, CIE L*a*b*)."""
    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(path) as im:
                im.seek(k)
                im.load()
                return _pil_array(im)[0]
    except Exception as exc:  # noqa: BLE001 — Pillow raises many types for damaged pages
        expected = f"a decodable TIFF page ({why}; Pillow: {type(exc).__name__}: {exc})"
        raise InputError(path, f"page {k}", expected) from None


def _tiff_page(path: Path, page: Any, k: int) -> tuple[np.ndarray, int, tuple[str, ...]]:
    """(samples, bits per sample, notes) of one TIFF page: a palette looked up, CMYK and L*a*b*
    converted, a compression tifffile cannot decode read through Pillow."""
    try:
        bits = int(page.bitspersample)
        photometric = int(page.photometric)
    except Exception as exc:  # tifffile raises many types for damaged pages
        raise InputError(path, f"page {k}", f"a readable TIFF page ({type(exc).__name__}: {exc})") from None
    if photometric in (_SEPARATED, _CIELAB):
        return _pillow_page(path, k, "CMYK or L*a*b*"), bits, ("TIFF colour page converted by Pillow",)
    try:
        arr = page.asarray()
    except Exception as exc:  # a codec tifffile lacks (e.g. old-style JPEG) or a damaged page
        arr = _pillow_page(path, k, f"tifffile: {type(exc).__name__}: {exc}")
        return arr, bits, ("TIFF page decoded by Pillow",)
    notes: tuple[str, ...] = ()
    if photometric == _PALETTE and page.colormap is not None and arr.dtype.kind == "u":
        cmap = np.asarray(page.colormap)
        # TIFF stores palettes as 16-bit: an 8-bit picture's colours are their top bytes (as Pillow reads them)
        cmap = cmap >> 8 if bits <= 8 else cmap
        arr = np.moveaxis(cmap[:, arr], 0, -1)
        notes += ("palette TIFF: colours looked up",)
    elif photometric == _MINISWHITE:
        notes += ("TIFF MinIsWhite: values kept as stored (low values show white)",)
    if arr.ndim == 3 and arr.shape[0] in (3, 4) and arr.shape[-1] not in (3, 4):
        arr = np.moveaxis(arr, 0, -1)
    return arr, bits, notes


def read_tiff_frames(path: Path, camera: Camera | None, need_camera: bool, first_index: int = 0) -> Iterator[Frame]:
    """One frame per TIFF page, decoded page by page; pages must share one shape."""
    n = tiff_frame_count(path)
    with _tiff(path) as tf:
        pages = _pages(tf, path)
        note = parse_note(pages[0].description or "")
        for k in range(n):
            arr, bits, notes = _tiff_page(path, pages[k], k)
            if n > 1 and k == 0:
                notes = ("multi-page TIFF: one frame per page",) + notes
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
