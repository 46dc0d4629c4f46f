"""OpenIGTLink messages for the live path (pyigtl, the ``live`` extra).

**IMAGE in.** The pixels are taken as stored — row ``j``, column ``i`` — as the detector's own
grid (SPEC §1); one slice, one component (grey). The camera of a frame is, in this order:

1. ``--camera`` (the server's), whole — as for ``track``, it overrides what a frame says;
2. metadata ``camera``: a SPEC §3 camera object as JSON;
3. metadata ``focal_length_mm`` (the source-to-detector distance), with the pixel pitch from
   the message's IJK-to-world matrix (the lengths of its ``i`` and ``j`` columns: s_x, s_y) and
   the principal point from metadata ``principal_point_px`` (``"u v"`` or a JSON pair), else
   the image centre ((W − 1)/2, (H − 1)/2).

A frame with none of these, or with values out of range, is answered by a STATUS error.

**TRANSFORM out** (header version 2), named ``FiducialToCArm`` by default, timestamped with
the IMAGE's timestamp. Its matrix is float32 (the protocol's) and by default RAS (see
:mod:`ftrac_design.igt`); the metadata (:data:`METADATA_KEYS`) carry the pose at full
precision in SPEC §4's own terms, its status, covariance and timings.

**STATUS** (the protocol's status message, which pyigtl does not provide; :func:`status_message_class`): code, sub-code,
error name (≤ 20 bytes) and text. Codes used: 0 invalid packet (a malformed message), 9
checksum error, 12 unknown message type, 10 configuration error (no camera for a frame).
"""

from __future__ import annotations

import functools
import json
import math
import struct
from types import ModuleType
from typing import Any

import numpy as np

from ..errors import InputError, require
from ..pose import Camera
from ..pose.observation import camera_from_dict
from .frames import Space, in_space, pose_matrix

#: STATUS codes (OpenIGTLink protocol)
STATUS_INVALID_PACKET = 0
STATUS_OK = 1
STATUS_CONFIGURATION_ERROR = 10
STATUS_CHECKSUM_ERROR = 9
STATUS_UNKNOWN_INSTRUCTION = 12

#: the most pixels one frame may hold (a 4096 × 4096 detector)
MAX_FRAME_PIXELS = 4096 * 4096
#: the fewest pixels along a side a frame must have to be tracked
MIN_FRAME_SIDE = 32

#: the TRANSFORM's metadata keys and what they hold (all strings, as the protocol's are)
METADATA_KEYS = {
    "TransformStatus": "OK, or INVALID when the frame has no pose (the matrix is then the identity)",
    "status": "the pose's status: tracked, lost, or error (the frame could not be tracked)",
    "converged": "true / false",
    "error": "why there is no pose (only when converged is false)",
    "rotation": "JSON 3x3, SPEC §4 rotation F -> X, full precision",
    "translation_mm": "JSON 3-vector, SPEC §4 translation (mm), full precision",
    "covariance": "JSON 6x6 (rotation vector rad on the left, then translation mm; SPEC §4), or null",
    "rms_residual_px": "the solve's RMS residual (px), or null",
    "space": "RAS or LPS: the coordinates of this message's matrix",
    "frame": "0-based index of the answered IMAGE among those received on this connection",
    "image_device": "the answered IMAGE's device name",
    "dropped": "IMAGEs received on this connection and dropped unanswered so far (the queue was full)",
    "queue_ms": "time the IMAGE waited for the tracker (ms)",
    "track_ms": "time tracking it took (ms)",
    "latency_ms": "IMAGE fully received -> TRANSFORM queued for sending (ms, the server's clock)",
}


def pyigtl() -> ModuleType:
    """The pyigtl package (the ``live`` extra); MissingDependencyError (exit 2) naming it when absent."""
    return require("pyigtl", "live", "OpenIGTLink (serve, push)")


@functools.cache
def status_message_class() -> type:
    """OpenIGTLink STATUS as a pyigtl message: ``code`` (uint16), ``subcode`` (int64),
    ``error_name`` (≤ 20 bytes) and ``status_string`` (NUL-terminated)."""
    MessageBase = pyigtl().MessageBase

    class StatusMessage(MessageBase):
        def __init__(
            self,
            code: int = STATUS_OK,
            subcode: int = 0,
            error_name: str = "",
            status_string: str = "",
            timestamp: float | None = None,
            device_name: str | None = None,
        ):
            MessageBase.__init__(self, timestamp=timestamp, device_name=device_name)
            self._message_type = "STATUS"
            self.code, self.subcode = int(code), int(subcode)
            self.error_name, self.status_string = error_name, status_string
            self._valid_message = True

        def _pack_content(self) -> bytes:
            name = self.error_name.encode("ascii", "replace")[:20]
            return (
                struct.pack(">Hq20s", self.code, self.subcode, name)
                + self.status_string.encode("utf-8", "replace")
                + b"\0"
            )

        def _unpack_content(self, content: bytes) -> None:
            self.code, self.subcode, name = struct.unpack(">Hq20s", content[:30])
            self.error_name = name.rstrip(b"\0").decode("ascii", "replace")
            self.status_string = content[30:].split(b"\0", 1)[0].decode("utf-8", "replace")

    return StatusMessage


def crc64(data: bytes | bytearray) -> int:
    """OpenIGTLink's CRC-64 of a message body (pyigtl's, in C through crcmod)."""
    return require("pyigtl.messages", "live", "OpenIGTLink (serve, push)").CRC64(data)


def parse_header(head: bytes) -> dict[str, Any]:
    """pyigtl's parsed fields of a 58-byte OpenIGTLink header (type, device, timestamp, body size)."""
    return pyigtl().MessageBase.parse_header(bytes(head))


def image_message(fields: dict[str, Any], body: bytes | bytearray) -> Any:
    """The IMAGE message of a received header's ``fields`` and ``body`` (pyigtl's ImageMessage);
    raises whatever decoding a malformed body raises."""
    msg = pyigtl().ImageMessage()
    msg.unpack(fields, body)
    return msg


def status_message(code: int, text: str, device_name: str, timestamp: float | None = None) -> Any:
    """A STATUS reply: ``code``, error name ``"OK"`` or ``"Error"``, ``text`` on one line.

    Parameters
    ----------
    code : a STATUS code (``STATUS_*``).
    text : what was wrong (or what happened).
    device_name : the device the reply is about (≤ 20 bytes; cut).
    timestamp : the message's timestamp (s since 1970), default now.
    """
    msg = status_message_class()(
        code,
        0,
        "OK" if code == STATUS_OK else "Error",
        " ".join(str(text).split()),
        timestamp=timestamp,
        device_name=device_name[:20],
    )
    msg.header_version = 2
    return msg


def _metadata_number(meta: dict[str, str], key: str) -> float:
    try:
        v = float(json.loads(meta[key]))
    except (ValueError, TypeError):
        raise InputError("IMAGE metadata", key, f"a number, got {meta[key][:40]!r}") from None
    if not math.isfinite(v):
        raise InputError("IMAGE metadata", key, "a finite number")
    return v


def _metadata_pair(meta: dict[str, str], key: str) -> list[float]:
    text = meta[key].strip()
    try:
        vals = json.loads(text) if text.startswith("[") else [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        vals = None
    if not isinstance(vals, list) or len(vals) != 2:
        raise InputError("IMAGE metadata", key, f'two numbers ("u v" or [u, v]), got {text[:40]!r}')
    return vals


def image_pixels(msg: Any) -> np.ndarray:
    """The (H, W) pixels of an IMAGE message as float32 (row ``j``, column ``i``).

    Raises InputError (named ``IMAGE``) unless the image is one grey slice of a trackable size.
    """
    img = np.asarray(msg.image)
    if img.ndim == 4:
        if img.shape[3] != 1:
            raise InputError("IMAGE", "components", f"one (grey) component per pixel, got {img.shape[3]}")
        img = img[..., 0]
    if img.ndim == 3:
        if img.shape[0] != 1:
            raise InputError("IMAGE", "size", f"one slice (a 2-D frame), got {img.shape[0]}")
        img = img[0]
    if img.ndim != 2:
        raise InputError("IMAGE", "size", "a 2-D frame")
    h, w = img.shape
    if min(h, w) < MIN_FRAME_SIDE or h * w > MAX_FRAME_PIXELS:
        raise InputError("IMAGE", "size", f"between {MIN_FRAME_SIDE} and 4096 pixels a side, got {h} × {w}")
    return img.astype(np.float32)


def image_camera(msg: Any, shape: tuple[int, int], override: Camera | None) -> tuple[Camera, str]:
    """The camera of one IMAGE (see the module for the order) and where it came from.

    Parameters
    ----------
    msg : the IMAGE message (its matrix and metadata are read).
    shape : (H, W) of its pixels.
    override : the server's ``--camera``, or None.

    Returns
    -------
    (Camera, source) : source is ``"--camera"``, ``"metadata camera"`` or ``"metadata
    focal_length_mm + IMAGE spacing"``. InputError when the frame gives no usable camera.
    """
    if override is not None:
        return override, "--camera"
    meta = dict(msg.metadata or {})
    if "camera" in meta:
        try:
            d = json.loads(meta["camera"])
        except ValueError:
            raise InputError("IMAGE metadata", "camera", "a SPEC §3 camera object as JSON") from None
        return camera_from_dict(d, "IMAGE metadata"), "metadata camera"
    if "focal_length_mm" not in meta:
        raise InputError(
            "IMAGE metadata",
            "focal_length_mm",
            "the source-to-detector distance (or a camera object, or the server's --camera)",
        )
    f = _metadata_number(meta, "focal_length_mm")
    M = np.asarray(msg.ijk_to_world_matrix, float)
    sx, sy = float(np.linalg.norm(M[:3, 0])), float(np.linalg.norm(M[:3, 1]))
    h, w = shape
    pp = _metadata_pair(meta, "principal_point_px") if "principal_point_px" in meta else [(w - 1) / 2, (h - 1) / 2]
    cam = {"focal_length_mm": f, "pixel_size_mm": [sx, sy], "principal_point_px": pp}
    return camera_from_dict(cam, "IMAGE metadata"), "metadata focal_length_mm + IMAGE spacing"


def _json_or_null(a: Any) -> str:
    if a is None:
        return "null"
    arr = np.asarray(a, float)
    return json.dumps(arr.tolist()) if np.isfinite(arr).all() else "null"


def transform_message(pose: dict[str, Any], name: str, space: Space, timestamp: float, extra: dict[str, str]) -> Any:
    """The TRANSFORM answering one frame (header version 2).

    Parameters
    ----------
    pose : the frame's SPEC §4 pose object (``converged`` false: identity, INVALID).
    name : the device name (a PLUS transform name, ≤ 20 bytes).
    space : the matrix's coordinates: ``"ras"`` (``S M S``, for Slicer) or ``"lps"`` (M).
    timestamp : the answered IMAGE's timestamp (s since 1970).
    extra : further metadata (frame, timings, …; strings).

    Returns
    -------
    pyigtl TransformMessage with :data:`METADATA_KEYS` filled.
    """
    ok = bool(pose.get("converged")) and pose.get("rotation") is not None and pose.get("translation_mm") is not None
    M = in_space(pose_matrix(pose["rotation"], pose["translation_mm"]), space) if ok else np.eye(4)
    msg = pyigtl().TransformMessage(M, timestamp=timestamp, device_name=name)
    msg.header_version = 2
    rms = pose.get("rms_residual_px")
    meta = {
        "TransformStatus": "OK" if ok else "INVALID",
        "status": str(pose.get("status") or ("tracked" if ok else "lost")),
        "converged": "true" if ok else "false",
        "rotation": _json_or_null(pose.get("rotation")) if ok else "null",
        "translation_mm": _json_or_null(pose.get("translation_mm")) if ok else "null",
        "covariance": _json_or_null(pose.get("covariance")) if ok else "null",
        "rms_residual_px": repr(float(rms)) if isinstance(rms, (int, float)) and math.isfinite(rms) else "null",
        "space": space.upper(),
    }
    if not ok:
        meta["error"] = " ".join(str(pose.get("error") or "no pose").split())
    meta.update(extra)
    msg.metadata = meta
    return msg


def pose_from_metadata(meta: dict[str, str]) -> tuple[np.ndarray, np.ndarray] | None:
    """(R, t) at full precision from a TRANSFORM's metadata, or None when it has no pose."""
    if meta.get("TransformStatus") != "OK":
        return None
    return np.array(json.loads(meta["rotation"]), float), np.array(json.loads(meta["translation_mm"]), float)
