"""NumPy ``.npy`` intake, always with ``allow_pickle=False``: a 2-D array is one frame, a
3-D (n, H, W) array a run of n frames (read through a memory map, one frame at a time);
(H, W, 3|4) is RGB(A) and (H, W, 2) grey + alpha. Only real numeric dtypes are accepted.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import InputError
from ..pose.camera import Camera
from .frame import Frame, check_frame_size
from .raster import make_frame


def _header(path: Path) -> tuple[tuple[int, ...], np.dtype]:
    try:
        with open(path, "rb") as fh:
            version = np.lib.format.read_magic(fh)
            read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, _fortran, dtype = read(fh)
    except Exception as exc:  # numpy raises ValueError, EOFError, SyntaxError, … for a bad header
        raise InputError(path, None, f"a NumPy .npy array ({type(exc).__name__}: {exc})") from None
    if dtype.hasobject or dtype.kind not in "iuf" or dtype.fields is not None:
        raise InputError(path, "dtype", f"a real numeric array (integers or floats), got {dtype}")
    return tuple(int(x) for x in shape), dtype


def _layout(path: Path, shape: tuple[int, ...], dtype: np.dtype) -> int:
    """Frames in an array of ``shape``: 1 for (H, W) and (H, W, 2|3|4), n for (n, H, W)."""
    if len(shape) == 2:
        check_frame_size(path, shape, "shape", dtype.itemsize)
        return 1
    if len(shape) == 3 and shape[-1] in (2, 3, 4):
        check_frame_size(path, shape, "shape", dtype.itemsize * shape[-1])
        return 1
    if len(shape) == 3:
        check_frame_size(path, shape[1:], "shape", dtype.itemsize)
        if shape[0] < 1:
            raise InputError(path, "shape", "at least one frame")
        return shape[0]
    raise InputError(path, "shape", f"(H, W), (H, W, 3|4) RGB(A) or (n, H, W) frames, got {shape}")


def npy_frame_count(path: Path) -> int:
    """Frames of an ``.npy`` file (header only)."""
    shape, dtype = _header(path)
    return _layout(path, shape, dtype)


def read_npy_frames(path: Path, camera: Camera | None, need_camera: bool, first_index: int = 0) -> Iterator[Frame]:
    """Frames of an ``.npy`` file, memory-mapped so a run is read one frame at a time."""
    shape, dtype = _header(path)
    n = _layout(path, shape, dtype)
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception as exc:  # a truncated file, or one that is not what its header says
        raise InputError(path, None, f"a complete NumPy .npy array ({type(exc).__name__}: {exc})") from None
    meta = {"format": "npy", "bits": 8 * dtype.itemsize, "dtype": str(dtype)}
    single = len(shape) == 2 or n == 1 and len(shape) == 3 and shape[-1] in (2, 3, 4)
    for k in range(n):
        data = np.array(arr if single else arr[k])
        notes = ("3-D array: one frame per first index",) if not single and k == 0 else ()
        yield make_frame(path, data, {}, meta, first_index + k, camera, need_camera, notes)
