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

**Header versions.** Each connection is answered in the header version its client speaks,
as PLUS answers (``PlusIgtlClientInfo::ClientHeaderVersion``): version 1 until the client has
sent a message of a higher one, then the highest it has sent, at most :data:`MAX_HEADER_VERSION`
(2, OpenIGTLink 3's; :class:`PeerVersion`). :func:`answer_messages` composes a frame's answer:

- **version 2** — a TRANSFORM, named ``FiducialToCArm`` by default, timestamped with the IMAGE's
  timestamp, with an extended header and metadata (:data:`METADATA_KEYS`: the pose at full
  precision in SPEC §4's own terms, its status, covariance and timings); a frame without a pose
  gets the identity with ``TransformStatus`` INVALID and the reason.
- **version 1** — the protocol as the reference library 1.x and older PLUS builds speak it: no
  extended header, no metadata. A frame with a pose gets a plain TRANSFORM (the matrix, float32);
  a frame without one gets **no TRANSFORM** (an identity would put the fiducial at the X-ray
  source) but a STATUS of the same device name and the IMAGE's timestamp, code
  :data:`STATUS_NOT_FOUND` (lost) or :data:`STATUS_UNKNOWN_ERROR` (the tracker failed), error
  name ``NoPose``, text ``frame K: <reason>``: that is how a version-1 client learns a frame was
  refused.

The matrix is float32 (the protocol's) and by default RAS (see :mod:`ftrac_design.igt`).

**STATUS** (the protocol's status message, which pyigtl does not provide; :func:`status_message_class`): code, sub-code,
error name (≤ 20 bytes) and text. Codes used: 0 invalid packet (a malformed message), 9
checksum error, 12 unknown message type, 10 configuration error (no camera for a frame), 4 not
found and 2 unknown error (a version-1 client's frame without a pose).

**Framing** (:func:`read_message`): the fixed 58-byte header (:data:`HEADER`: version, type,
device, timestamp, body size, CRC-64 of the body), then the body. A header of an unknown
version, with non-ASCII names or an absurd body size, and a message that stalls, cannot be
trusted: :class:`FramingError`.
"""

from __future__ import annotations

import functools
import json
import math
import socket
import struct
import threading
import time
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Literal

import numpy as np

from ..errors import InputError, require
from ..pose import Camera
from ..pose.observation import camera_from_dict
from .frames import Space, in_space, pose_matrix

#: STATUS codes (OpenIGTLink protocol)
STATUS_INVALID_PACKET = 0
STATUS_OK = 1
STATUS_UNKNOWN_ERROR = 2
STATUS_NOT_FOUND = 4
STATUS_CONFIGURATION_ERROR = 10
STATUS_CHECKSUM_ERROR = 9
STATUS_UNKNOWN_INSTRUCTION = 12

#: an OpenIGTLink header version: 1 (the protocol 1 and 2, no extended header) or 2 (OpenIGTLink 3:
#: extended header and metadata)
HeaderVersion = Literal[1, 2]
#: the highest header version spoken here
MAX_HEADER_VERSION: HeaderVersion = 2
#: the fixed header of every OpenIGTLink message: version, type, device, timestamp, body size, CRC
HEADER = struct.Struct(">H12s20sIIQQ")
#: the largest body accepted: a 4096² frame of 8-byte pixels plus room for headers and metadata
MAX_BODY_BYTES = 4096 * 4096 * 8 + (1 << 20)
#: seconds a started message may stall before the connection is given up
STALL_S = 5.0
#: the STATUS error name a version-1 client gets for a frame without a pose
NO_POSE = "NoPose"

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


def status_message(
    code: int,
    text: str,
    device_name: str,
    timestamp: float | None = None,
    version: HeaderVersion = MAX_HEADER_VERSION,
    error_name: str | None = None,
) -> Any:
    """A STATUS reply: ``code``, an error name, ``text`` on one line.

    Parameters
    ----------
    code : a STATUS code (``STATUS_*``).
    text : what was wrong (or what happened).
    device_name : the device the reply is about (≤ 20 bytes; cut).
    timestamp : the message's timestamp (s since 1970), default now.
    version : the header version to send it in.
    error_name : the error name (≤ 20 bytes), default ``"OK"`` or ``"Error"`` by the code.
    """
    if error_name is None:
        error_name = "OK" if code == STATUS_OK else "Error"
    msg = status_message_class()(
        code, 0, error_name, " ".join(str(text).split()), timestamp=timestamp, device_name=device_name[:20]
    )
    msg.header_version = int(version)
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


def has_pose(pose: dict[str, Any]) -> bool:
    """Whether a SPEC §4 pose object holds a solved pose (``converged``, rotation and translation)."""
    return bool(pose.get("converged")) and pose.get("rotation") is not None and pose.get("translation_mm") is not None


def transform_message(
    pose: dict[str, Any],
    name: str,
    space: Space,
    timestamp: float,
    extra: dict[str, str],
    version: HeaderVersion = MAX_HEADER_VERSION,
) -> Any:
    """The TRANSFORM answering one frame.

    Parameters
    ----------
    pose : the frame's SPEC §4 pose object (``converged`` false: identity, INVALID).
    name : the device name (a PLUS transform name, ≤ 20 bytes).
    space : the matrix's coordinates: ``"ras"`` (``S M S``, for Slicer) or ``"lps"`` (M).
    timestamp : the answered IMAGE's timestamp (s since 1970).
    extra : further metadata (frame, timings, …; strings).
    version : the header version: 2 carries the metadata, 1 the matrix alone.

    Returns
    -------
    pyigtl TransformMessage; in version 2 with :data:`METADATA_KEYS` filled, in version 1 with
    no metadata.
    """
    ok = has_pose(pose)
    M = in_space(pose_matrix(pose["rotation"], pose["translation_mm"]), space) if ok else np.eye(4)
    msg = pyigtl().TransformMessage(M, timestamp=timestamp, device_name=name)
    msg.header_version = int(version)
    if version < 2:
        return msg
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


def refusal_message(pose: dict[str, Any], name: str, timestamp: float, frame: int | None = None) -> Any:
    """The version-1 answer to a frame without a pose: a STATUS named ``name``, stamped with the
    IMAGE's ``timestamp``, code :data:`STATUS_NOT_FOUND` (the fiducial was lost) or
    :data:`STATUS_UNKNOWN_ERROR` (the tracker failed, status ``error``), error name
    :data:`NO_POSE`, text ``frame K: <reason>``."""
    code = STATUS_UNKNOWN_ERROR if pose.get("status") == "error" else STATUS_NOT_FOUND
    why = " ".join(str(pose.get("error") or "no pose").split())
    text = f"frame {frame}: {why}" if frame is not None else why
    return status_message(code, text, name, timestamp, version=1, error_name=NO_POSE)


def answer_messages(
    pose: dict[str, Any],
    name: str,
    space: Space,
    timestamp: float,
    extra: dict[str, str],
    version: HeaderVersion,
    valid_only: bool = False,
) -> list[Any]:
    """What answers one frame in header ``version`` (see the module): version 2, its TRANSFORM
    (none for a frame without a pose when ``valid_only``); version 1, a plain TRANSFORM, or a
    STATUS :data:`NO_POSE` for a frame without a pose.

    Parameters
    ----------
    pose : the frame's SPEC §4 pose object.
    name, space, timestamp, extra : as :func:`transform_message` (``extra["frame"]``, when
        given, is named in a version-1 refusal).
    version : the client's header version.
    valid_only : send no TRANSFORM for a frame without a pose.

    Returns
    -------
    list of pyigtl messages (zero or one).
    """
    ok = has_pose(pose)
    if version < 2 and not ok:
        frame = extra.get("frame")
        return [refusal_message(pose, name, timestamp, int(frame) if frame is not None else None)]
    if valid_only and not ok:
        return []
    return [transform_message(pose, name, space, timestamp, extra, version)]


def pose_from_metadata(meta: dict[str, str]) -> tuple[np.ndarray, np.ndarray] | None:
    """(R, t) at full precision from a TRANSFORM's metadata, or None when it has no pose."""
    if meta.get("TransformStatus") != "OK":
        return None
    return np.array(json.loads(meta["rotation"]), float), np.array(json.loads(meta["translation_mm"]), float)


# ----------------------------------------------------------------------------- header versions
class PeerVersion:
    """The header version to answer a peer in: 1 until it has sent a message of a higher one,
    then the highest it has sent, at most :data:`MAX_HEADER_VERSION` (PLUS's rule). Safe to
    share between threads.

    Parameters
    ----------
    start : the version before the peer has said anything (1 for a client of ``serve``).
    """

    def __init__(self, start: HeaderVersion = 1):
        self._version: int = int(start)
        self._lock = threading.Lock()

    @property
    def version(self) -> HeaderVersion:
        """The version to send in now."""
        return self._version  # type: ignore[return-value]

    def heard(self, version: int) -> HeaderVersion:
        """The peer sent a message of header ``version``: raise ours to it (bounded); the version now."""
        with self._lock:
            if version > self._version:
                self._version = min(int(version), MAX_HEADER_VERSION)
            return self._version  # type: ignore[return-value]


def packed(msg: Any, version: HeaderVersion) -> bytes:
    """``msg`` (a pyigtl message) as bytes in header ``version``: version 1 drops the metadata
    (which only the extended header can carry)."""
    msg.header_version = int(version)
    if version < 2:
        msg.metadata = {}
    return msg.pack()


# ----------------------------------------------------------------------------- framing
class FramingError(Exception):
    """The byte stream cannot be trusted any more (a bad header, a stalled message): answer, then close."""


class ConnectionClosed(Exception):
    """The peer closed the connection."""


@dataclass
class RawMessage:
    """One message as read off the socket: its header fields and its body, not yet checked.

    Attributes
    ----------
    version : the header version.
    type, device : the message type and device name (ASCII).
    fields : pyigtl's parsed header (``timestamp``, ``device_name``, …) for unpacking the body.
    body : the body bytes.
    crc : the CRC-64 the header states for the body.
    """

    version: int
    type: str
    device: str
    fields: dict[str, Any]
    body: bytearray
    crc: int

    @property
    def timestamp(self) -> float:
        """The message's timestamp (s since 1970)."""
        return float(self.fields["timestamp"])

    def crc_ok(self) -> bool:
        """Whether the body's CRC-64 is the header's."""
        return crc64(self.body) == self.crc


def recv_exact(sock: socket.socket, buf: memoryview, started: bool) -> bool:
    """Fill ``buf`` from ``sock`` (whose timeout is short).

    Returns False when nothing arrived within the socket's timeout and ``started`` is False (no
    message yet); raises ConnectionClosed at the end of the stream and FramingError when a started
    message stalls for :data:`STALL_S`.
    """
    got, last = 0, time.monotonic()
    while got < len(buf):
        try:
            n = sock.recv_into(buf[got:])
        except socket.timeout:
            if got == 0 and not started:
                return False
            if time.monotonic() - last > STALL_S:
                raise FramingError(f"message stalled for {STALL_S:.0f} s") from None
            continue
        if n == 0:
            raise ConnectionClosed()
        got += n
        last = time.monotonic()
    return True


def read_message(sock: socket.socket) -> RawMessage | None:
    """The next message on ``sock``, or None when none started within the socket's timeout.

    Raises FramingError for a header that cannot be trusted (a version other than 1 or 2,
    non-ASCII names, a body over :data:`MAX_BODY_BYTES`) or a stalled message, ConnectionClosed
    at the end of the stream. The CRC is not checked here (:meth:`RawMessage.crc_ok`).
    """
    head = bytearray(HEADER.size)
    if not recv_exact(sock, memoryview(head), started=False):
        return None
    version, mtype, device, _, _, size, crc = HEADER.unpack(head)
    try:
        mtype_s = mtype.rstrip(b"\0 ").decode("ascii")
        device_s = device.rstrip(b"\0 ").decode("ascii")
    except UnicodeDecodeError:
        raise FramingError("a message header whose type and device name are ASCII") from None
    if version not in (1, 2) or size > MAX_BODY_BYTES:
        raise FramingError(
            f"a message header of version 1 or 2 with a body of at most {MAX_BODY_BYTES} bytes "
            f"(got version {version}, {size} bytes)"
        )
    body = bytearray(size)
    recv_exact(sock, memoryview(body), started=True)
    return RawMessage(version, mtype_s, device_s, parse_header(head), body, crc)
