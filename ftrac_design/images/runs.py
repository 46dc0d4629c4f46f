"""Reading frames from any image file or a directory of them: the public entry points
(:func:`read_frames`, :func:`read_frame`, :func:`frame_count`) and the old
:func:`read_image` tuple for existing call sites.

A directory is a run: its image files in natural order of their names (``img_2`` before
``img_10``), hidden and non-image files skipped, each file's frames in turn, indices
counted across the run. A video file (MP4, AVI, MKV, MOV, WebM; :mod:`.video`) is a run of
its frames.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from ..errors import InputError
from ..pose.camera import Camera
from .dicom import dicom_frame_count, read_dicom_frames
from .frame import Frame, legacy_hint
from .numpy_io import npy_frame_count, read_npy_frames
from .raster import pil_frame_count, read_pil_frames, read_tiff_frames, tiff_frame_count
from .sniff import image_format, looks_like_image
from .video import read_video_frames, video_frame_count

_COUNT: dict[str, Callable[[Path], int]] = {
    "png": pil_frame_count,
    "jpeg": pil_frame_count,
    "bmp": pil_frame_count,
    "gif": pil_frame_count,
    "webp": pil_frame_count,
    "tiff": tiff_frame_count,
    "npy": npy_frame_count,
    "dicom": dicom_frame_count,
    "video": video_frame_count,
}


def natural_key(name: str) -> list:
    """Sort key that orders embedded numbers by value (``a2`` < ``a10``)."""
    return [(0, int(t), "") if t.isdigit() else (1, 0, t.lower()) for t in re.split(r"(\d+)", name) if t]


def run_files(path: str | Path) -> list[Path]:
    """The image files of a run: ``[path]`` for a file, the directory's image files in
    natural order for a directory (InputError when it holds none)."""
    path = Path(path)
    if path.is_dir():
        files = sorted((p for p in path.iterdir() if looks_like_image(p)), key=lambda p: natural_key(p.name))
        if not files:
            raise InputError(
                path, None, "a directory holding image files (PNG, TIFF, JPEG, BMP, GIF, WebP, NumPy .npy, DICOM)"
            )
        return files
    if not path.is_file():
        raise InputError(path, None, "an existing image file or directory of frames")
    return [path]


def frame_count(path: str | Path) -> int:
    """Number of frames in an image file (pages, DICOM frames, ``(n, H, W)`` arrays) or a
    directory of them, from the headers only.

    Raises
    ------
    InputError : missing, unreadable, or a header that lies (see :func:`read_frames`).
    """
    total = 0
    for f in run_files(path):
        fmt, _ = image_format(f)
        total += _COUNT[fmt](f)
    return total


def _file_frames(f: Path, camera: Camera | None, need_camera: bool, first: int) -> Iterator[Frame]:
    fmt, notes = image_format(f)
    if fmt == "dicom":
        frames = read_dicom_frames(f, camera, need_camera=need_camera, first_index=first)
    elif fmt == "tiff":
        frames = read_tiff_frames(f, camera, need_camera, first)
    elif fmt == "npy":
        frames = read_npy_frames(f, camera, need_camera, first)
    elif fmt == "video":
        frames = read_video_frames(f, camera, need_camera, first)
    else:
        frames = read_pil_frames(f, camera, need_camera, first)
    for fr in frames:
        if notes:
            fr = replace(fr, notes=notes + fr.notes)
        yield fr


def read_frames(path: str | Path, camera: Camera | None = None, *, need_camera: bool = True) -> Iterator[Frame]:
    """Frames of an image file (single, multi-frame DICOM, multi-page TIFF, ``(n, H, W)``
    ``.npy``, a video), or of a directory of image files, yielded one at a time.

    Parameters
    ----------
    path : a file (format found by content, suffix as fallback) or a directory (a run).
    camera : intrinsics (SPEC §3, detector-grid pixels) overriding what the files say (``--camera``).
    need_camera : without ``camera``, a frame with no camera in its file raises InputError
        naming what is missing (True), or gets ``camera=None`` (False).

    Yields
    ------
    Frame : see :class:`~ftrac_design.images.frame.Frame`; ``index`` counts across the run.

    Raises
    ------
    InputError : (file, key, expected) for anything unreadable, malformed or refused.
    """
    index = 0
    for f in run_files(path):
        following = index
        for fr in _file_frames(f, camera, need_camera, index):
            yield fr
            following = fr.index + 1
        index = following


def read_frame(path: str | Path, index: int = 0, camera: Camera | None = None, need_camera: bool = True) -> Frame:
    """Frame ``index`` (0-based, across a run) of a file or directory; only that frame is decoded.

    Raises
    ------
    InputError : as :func:`read_frames`, or ``index`` beyond the last frame.
    """
    if index < 0:
        raise InputError(path, "frame", f"a frame index ≥ 0, got {index}")
    first = 0
    for f in run_files(path):
        fmt, _ = image_format(f)
        n = _COUNT[fmt](f)
        if index < first + n:
            if fmt == "dicom":
                fr = next(
                    read_dicom_frames(
                        f,
                        camera,
                        need_camera=need_camera,
                        indices=range(index - first, index - first + 1),
                        first_index=first,
                    )
                )
                return fr
            for fr in _file_frames(f, camera, need_camera, first):
                if fr.index == index:
                    return fr
        first += n
    raise InputError(path, "frame", f"a frame index in 0 … {first - 1}, got {index}")


def read_image(path: str | Path, camera: Camera | None = None) -> tuple[np.ndarray, Camera | None, dict]:
    """The first frame as the old tuple ``(pixels (H, W) float64, camera or None, meta)``.

    ``camera`` overrides the file's; a DICOM file must otherwise carry its geometry tags
    (InputError naming the missing ones); other formats give camera None, their noted camera
    in ``meta["camera"]``. ``pixels`` are :attr:`Frame.pixels` (detector grid, modality
    values). ``meta`` holds ``format``, ``bits``, ``polarity_hint`` (``"dense_dark"``,
    ``"dense_bright"`` or None), ``camera`` (our note's camera dict, when present) and the
    frame's ``meta``.
    """
    f = run_files(path)[0]
    fmt, _ = image_format(f)
    fr = read_frame(f, 0, camera, need_camera=fmt == "dicom")
    meta = {k: v for k, v in fr.meta.items() if k != "note"}
    note = fr.meta.get("note") or {}
    if isinstance(note.get("camera"), dict):
        meta["camera"] = note["camera"]
    if isinstance(note.get("quantity"), str):
        meta["quantity"] = note["quantity"]
    meta["polarity_hint"] = legacy_hint(fr.polarity)
    meta["formation"] = fr.formation
    meta["notes"] = list(fr.notes)
    cam = fr.camera if (camera is not None or fmt == "dicom") else None
    return fr.pixels.astype(np.float64), cam, meta
