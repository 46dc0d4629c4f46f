"""Video files (MP4, AVI, MKV, MOV, WebM) as runs of frames, read through PyAV (FFmpeg's
libraries; the ``video`` extra).

A frame grabber's recording of a C-arm's monitor, or a cine exported as video, is a run: one
grey frame per video frame, in order, with its presentation time as ``time_s``. Colour frames
are read as luminance (FFmpeg's own conversion to grey); frames with more than 8 bits per
sample are read at 16 bits. A video carries no camera: ``--camera`` gives it. Lossy codecs
(H.264, MPEG-4, VP9, …) alter the pixel values, which the frame's notes say.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..errors import InputError, require
from ..pose.camera import Camera
from .frame import Frame, check_frame_size
from .raster import make_frame

#: codecs that keep every pixel value
LOSSLESS_CODECS = ("ffv1", "rawvideo", "huffyuv", "ffvhuff", "png", "utvideo", "magicyuv", "qtrle", "zlib")


def _av() -> Any:
    return require("av", "video", "reading video files (PyAV)")


def _open(path: Path) -> tuple[Any, Any]:
    """The opened container and its first video stream, or InputError."""
    av = _av()
    try:
        container = av.open(str(path))
    except Exception as exc:  # FFmpeg raises many types for files it cannot demux
        raise InputError(path, None, f"a readable video file ({type(exc).__name__}: {exc})") from None
    if not container.streams.video:
        container.close()
        raise InputError(path, None, "a video file with a video stream")
    return container, container.streams.video[0]


def video_frame_count(path: Path) -> int:
    """Frames of the first video stream: the header's count, else the packets counted
    (demuxed, not decoded); the frame size checked."""
    container, stream = _open(path)
    try:
        check_frame_size(path, (stream.codec_context.height or 2, stream.codec_context.width or 2), "video size")
        n = int(stream.frames or 0)
        if n <= 0:
            n = sum(1 for p in container.demux(stream) if p.size)
        return n
    except InputError:
        raise
    except Exception as exc:
        raise InputError(path, None, f"a readable video file ({type(exc).__name__}: {exc})") from None
    finally:
        container.close()


def _grey(vf: Any) -> np.ndarray:
    """A decoded video frame's samples as grey: 8-bit, or 16-bit for deeper formats."""
    deep = any(c.bits > 8 for c in vf.format.components)
    return vf.to_ndarray(format="gray16le" if deep else "gray")


def read_video_frames(path: Path, camera: Camera | None, need_camera: bool, first_index: int = 0) -> Iterator[Frame]:
    """The frames of a video file's first video stream, in order, one decoded at a time.

    Parameters
    ----------
    path : the video file.
    camera : ``--camera`` intrinsics (a video carries none).
    need_camera : without ``camera``, raise InputError (True) or give frames with camera None.
    first_index : the index of the first frame within the run.

    Yields
    ------
    Frame : grey pixels (float32), ``time_s`` the presentation time (s) where the file gives one.
    """
    container, stream = _open(path)
    codec = str(stream.codec_context.name)
    lossy = codec not in LOSSLESS_CODECS
    meta = {"format": "video", "codec": codec}
    try:
        for k, vf in enumerate(container.decode(stream)):
            arr = _grey(vf)
            notes = (f"video ({codec}): lossy compression has altered the pixel values",) if lossy and k == 0 else ()
            fr = make_frame(
                path, arr, {}, {**meta, "bits": 8 * arr.dtype.itemsize}, first_index + k, camera, need_camera, notes
            )
            t = vf.time
            yield replace(fr, time_s=float(t) if t is not None else None)
    except InputError:
        raise
    except Exception as exc:  # a damaged stream: FFmpeg's decoders raise many types
        raise InputError(path, None, f"a decodable video stream ({type(exc).__name__}: {exc})") from None
    finally:
        container.close()
