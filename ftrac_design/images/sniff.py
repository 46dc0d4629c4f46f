"""Which image format a file holds, found by its first bytes (magic numbers), with its
suffix as a fallback for formats without one (a DICOM stream with no preamble).

Besides the detector's own formats (DICOM, TIFF, PNG, NumPy), what a C-arm workstation's
screen capture or a frame grabber writes: BMP (Windows bitmaps, 1/4/8-bit palette, 16/24/32-bit),
GIF and WebP (still or animated), JPEG.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from ..errors import InputError

ImageFormat = Literal["png", "tiff", "jpeg", "bmp", "gif", "webp", "npy", "dicom", "video"]

SUFFIXES: dict[str, ImageFormat] = {
    ".png": "png",
    ".tif": "tiff",
    ".tiff": "tiff",
    ".jpg": "jpeg",
    ".jpeg": "jpeg",
    ".bmp": "bmp",
    ".dib": "bmp",
    ".gif": "gif",
    ".webp": "webp",
    ".npy": "npy",
    ".dcm": "dicom",
    ".dicom": "dicom",
    ".mp4": "video",
    ".m4v": "video",
    ".mov": "video",
    ".avi": "video",
    ".mkv": "video",
    ".webm": "video",
}
_MAGIC: tuple[tuple[bytes, ImageFormat], ...] = (
    (b"\x89PNG\r\n\x1a\n", "png"),
    (b"II*\x00", "tiff"),
    (b"MM\x00*", "tiff"),
    (b"II+\x00", "tiff"),
    (b"MM\x00+", "tiff"),
    (b"\xff\xd8\xff", "jpeg"),
    (b"\x93NUMPY", "npy"),
    (b"GIF87a", "gif"),
    (b"GIF89a", "gif"),
)
#: the sizes of the BMP info headers Windows and OS/2 define (BITMAPCOREHEADER … BITMAPV5HEADER):
#: "BM" alone is too weak a magic number
_BMP_INFO_SIZES = (12, 16, 40, 52, 56, 64, 108, 124)
#: every format the intake reads, as the refusal names them
FORMATS_READ = (
    "an image file (PNG, TIFF, JPEG, BMP, GIF, WebP, NumPy .npy, DICOM) or a video (MP4, AVI, MKV, MOV, WebM)"
)


def content_format(head: bytes) -> ImageFormat | Literal["zip"] | None:
    """The format the first 132 bytes of a file announce, ``"zip"`` for a zip archive (an
    ``.npz``), or None."""
    if len(head) >= 132 and head[128:132] == b"DICM":
        return "dicom"
    for magic, fmt in _MAGIC:
        if head.startswith(magic):
            return fmt
    if head.startswith(b"BM") and len(head) >= 18 and int.from_bytes(head[14:18], "little") in _BMP_INFO_SIZES:
        return "bmp"
    if head.startswith(b"RIFF") and head[8:12] == b"WEBP":
        return "webp"
    if head.startswith(b"PK\x03\x04") or head.startswith(b"PK\x05\x06"):
        return "zip"
    # ISO base media (MP4, MOV: an "ftyp" box first), AVI (RIFF … "AVI "), Matroska / WebM (EBML)
    if (
        head[4:8] == b"ftyp"
        or (head.startswith(b"RIFF") and head[8:12] == b"AVI ")
        or head.startswith(b"\x1a\x45\xdf\xa3")
    ):
        return "video"
    return None


def image_format(path: str | Path) -> tuple[ImageFormat, tuple[str, ...]]:
    """The format of the image file at ``path`` and a note when its suffix says otherwise.

    The content decides; the suffix only where the content has no magic number. A ``.npy``
    file must hold a NumPy array (an ``.npz`` archive or anything else is refused).

    Raises
    ------
    InputError : not a file, unreadable, or no known image format.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(132)
    except OSError as exc:
        raise InputError(path, None, f"a readable image file ({exc.strerror or exc})") from None
    by_content = content_format(head)
    by_suffix = SUFFIXES.get(path.suffix.lower())
    if by_suffix == "npy" and by_content != "npy":
        what = (
            "a zip archive (an .npz?)"
            if by_content == "zip"
            else (f"a {by_content.upper()} file" if by_content else "no NumPy header")
        )
        raise InputError(path, None, f"a NumPy .npy array (allow_pickle=False), got {what}")
    if by_content in (None, "zip"):
        if by_suffix is not None and by_content is None:
            return by_suffix, ()
        raise InputError(path, None, f"{FORMATS_READ}, found by its content or suffix")
    notes = ()
    if by_suffix is not None and by_suffix != by_content:
        notes = (f"suffix {path.suffix} but the content is {by_content.upper()}: read as {by_content.upper()}",)
    return by_content, notes


def looks_like_image(path: Path) -> bool:
    """Whether a directory entry is an image file worth reading as a frame of a run."""
    if path.name.startswith(".") or not path.is_file():
        return False
    if path.suffix.lower() in SUFFIXES:
        return True
    try:
        with open(path, "rb") as fh:
            return content_format(fh.read(132)) not in (None, "zip")
    except OSError:
        return False
