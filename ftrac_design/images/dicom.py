"""DICOM intake: XA, RF, DX, CR, Enhanced XA / Enhanced XRF (and any grey or colour image
object with pixel data), one :class:`~ftrac_design.images.frame.Frame` per frame, decoded
lazily so a long run never sits in memory. See :mod:`.dicom_header` (checks),
:mod:`.dicom_pixels` (values, polarity) and :mod:`.dicom_geometry` (grid, camera, time).
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from ..errors import InputError
from ..pose.camera import Camera
from .dicom_geometry import field_of_view, frame_camera, frame_times, positioner, undo_field_of_view
from .dicom_header import DicomHeader, read_header
from .dicom_pixels import decode_frame, formation_polarity, grey_values, header_meta
from .dicom_tags import raw_value
from .frame import Frame, finish_pixels
from .notes import camera_from_note, note_polarity, parse_note

CAMERA_WAYS_OUT = (
    "supply the intrinsics with --camera C.json (SPEC §3 camera object), or estimate them from "
    "the fiducial over several frames (intrinsics from the fiducial, as `ftrac-design reconstruct` "
    "does)"
)


def dicom_frame_count(path: str | Path) -> int:
    """Number of frames in a DICOM file (header only)."""
    return read_header(path).frames


def read_dicom_frames(
    path: str | Path,
    camera: Camera | None = None,
    *,
    need_camera: bool = True,
    indices: range | None = None,
    first_index: int = 0,
) -> Iterator[Frame]:
    """Frames of a DICOM file, decoded one at a time.

    Parameters
    ----------
    path : the file.
    camera : intrinsics that override the header (``--camera``); None reads them from the tags.
    need_camera : without ``camera``, a frame whose tags lack the geometry raises InputError
        naming the missing tags (True) or gets camera None (False).
    indices : which frames (default all).
    first_index : added to each frame's index (its place in a run of several files).

    Raises
    ------
    InputError : see :func:`.dicom_header.read_header`, and a frame that cannot be decoded
        or whose geometry tags are missing or invalid.
    """
    hdr = read_header(path)
    indices = range(hdr.frames) if indices is None else indices
    if indices and (indices[0] < 0 or indices[-1] >= hdr.frames):
        raise InputError(path, "frame", f"a frame index in 0 … {hdr.frames - 1}")
    times = frame_times(hdr)
    note = parse_note(str(raw_value(hdr.ds, "ImageComments", hdr.path) or ""))
    base = header_meta(hdr)
    if note:
        base["note"] = note
    for i in indices:
        yield _frame(hdr, i, camera, need_camera, times[i], note, base, first_index)


def _frame(
    hdr: DicomHeader,
    i: int,
    camera: Camera | None,
    need_camera: bool,
    time_s: float | None,
    note: dict,
    base: dict,
    first_index: int,
) -> Frame:
    fov = field_of_view(hdr, i)
    values, direction, notes = grey_values(hdr, i, decode_frame(hdr, i))
    if fov.rotation_deg or fov.flip:
        notes += (
            f"FieldOfViewRotation {fov.rotation_deg}°" + (" and horizontal flip" if fov.flip else "") + " undone",
        )
    pixels = finish_pixels(undo_field_of_view(values, fov), hdr.path)
    formation, polarity, more = formation_polarity(hdr, i, direction, note_polarity(note))
    notes += more
    if camera is not None:
        cam, source = camera, dict.fromkeys(("focal_length", "pixel_size", "principal_point"), "--camera")
    else:
        cam, source, cam_notes, missing = frame_camera(hdr, i, fov, pixels.shape, camera_from_note(note.get("camera")))
        notes += cam_notes
        if missing and need_camera:
            raise InputError(
                hdr.path,
                ", ".join(missing),
                "the DICOM tags giving the camera geometry (a "
                f"{hdr.modality or 'DICOM'} image may omit them); {CAMERA_WAYS_OUT}",
            )
    meta = dict(base)
    meta.update(positioner(hdr, i))
    return Frame(pixels, cam, source, formation, polarity, str(hdr.path), first_index + i, time_s, notes, meta)
