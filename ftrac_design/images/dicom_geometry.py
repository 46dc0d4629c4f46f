"""A DICOM frame's geometry: the field-of-view rotation/flip to undo, the camera in the
detector grid's pixels (and where each intrinsic came from), and the frame's time.

Pixel grid (PS3.3 C.8.11.4.1.1, C.8.19.6.2; PS3.17 Annex FFF): Field of View Rotation
(0018,7032) is the clockwise rotation of the stored image relative to the physical
detector and Field of View Horizontal Flip (0018,7034) a left–right flip applied after it,
so ``stored = fliplr(rot_cw(detector))`` and intake undoes the flip, then the rotation.

Camera (SPEC §1): f = Distance Source to Detector (0018,1110); the pitch from Imager Pixel
Spacing (0018,1164) (detector plane), else Pixel Spacing (0028,0030) when it is not
calibrated to another plane (Pixel Spacing Calibration Type (0028,0A02) absent) or can be
brought back to the detector with Estimated Radiographic Magnification Factor (0018,1114)
(SID/SOD: detector pitch = Pixel Spacing × factor); both are (row, column) spacings of the
stored grid. The principal point from Position of Isocenter Projection (0018,9430)
(fractional physical detector elements, (column-direction, row-direction) distances from the
centre of the top-left element) mapped through Field of View Origin (0018,7030) and Detector
Element Spacing (0018,7022); else the centre of the physical detector (Physical Detector
Size (0018,9429)) where the field-of-view origin places it; else our note's principal point;
else the image centre ((W − 1)/2, (H − 1)/2).
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..pose.camera import Camera
from .dicom_header import DicomHeader
from .dicom_tags import as_floats, as_text, lookup, raw_value, tag_name

FOV = "FieldOfViewSequence"
PIXEL_PROPS = "FramePixelDataPropertiesSequence"
GEOMETRY = "XRayGeometrySequence"
MEASURES = "PixelMeasuresSequence"
CONTENT = "FrameContentSequence"


@dataclass(frozen=True)
class FieldOfView:
    """How the stored grid sits on the detector: clockwise rotation (0/90/180/270 °, the
    standard's unit), horizontal flip after it, and the origin (row, column) in detector elements."""

    rotation_deg: int = 0
    flip: bool = False
    origin: tuple[float, float] | None = None


def field_of_view(hdr: DicomHeader, frame: int) -> FieldOfView:
    """The field of view of ``frame`` (functional group, then top level)."""
    path, ds = hdr.path, hdr.ds
    rot, _ = lookup(ds, frame, FOV, "FieldOfViewRotation", path)
    flip, _ = lookup(ds, frame, FOV, "FieldOfViewHorizontalFlip", path)
    origin, _ = lookup(ds, frame, FOV, "FieldOfViewOrigin", path)
    r = 0
    if rot is not None:
        r = int(as_floats(rot, "FieldOfViewRotation", path, 1)[0])
        if r not in (0, 90, 180, 270):
            raise InputError(path, tag_name("FieldOfViewRotation"), f"0, 90, 180 or 270, got {rot!r}")
    f = as_text(flip)
    if f not in ("", "NO", "YES"):
        raise InputError(path, tag_name("FieldOfViewHorizontalFlip"), f"YES or NO, got {flip!r}")
    o = as_floats(origin, "FieldOfViewOrigin", path, 2) if origin is not None else None
    return FieldOfView(r, f == "YES", o)


def undo_field_of_view(stored: np.ndarray, fov: FieldOfView) -> np.ndarray:
    """The detector-grid image from the stored one: undo the flip, then the clockwise rotation."""
    img = np.fliplr(stored) if fov.flip else stored
    return np.rot90(img, fov.rotation_deg // 90)


def apply_field_of_view(detector: np.ndarray, fov: FieldOfView) -> np.ndarray:
    """The stored image from the detector-grid one (the writer's side of :func:`undo_field_of_view`)."""
    img = np.rot90(detector, -(fov.rotation_deg // 90))
    return np.fliplr(img) if fov.flip else img


def frame_camera(
    hdr: DicomHeader, frame: int, fov: FieldOfView, detector_shape: tuple[int, int], note_camera: Camera | None
) -> tuple[Camera | None, dict[str, str], tuple[str, ...], list[str]]:
    """The camera of ``frame`` from its tags (see the module).

    Returns
    -------
    (camera or None, camera_source, notes, missing tag names). The camera is None when a tag
    is missing (named in ``missing``); present but invalid tags raise InputError naming them.
    """
    path, ds = hdr.path, hdr.ds
    notes: list[str] = []
    missing: list[str] = []
    sid_value, _ = lookup(ds, frame, GEOMETRY, "DistanceSourceToDetector", path)
    f = as_floats(sid_value, "DistanceSourceToDetector", path, 1, positive=True)[0] if sid_value is not None else None
    if f is None:
        missing.append(tag_name("DistanceSourceToDetector"))
    spacing, spacing_source = _pitch(hdr, frame, notes)
    if spacing is None:
        missing.append(tag_name("ImagerPixelSpacing"))
    if missing:
        return None, {}, tuple(notes), missing
    row_sp, col_sp = spacing
    # stored (row, column) spacing → detector (s_x, s_y): a quarter turn swaps the axes
    sx, sy = (row_sp, col_sp) if fov.rotation_deg in (90, 270) else (col_sp, row_sp)
    pp, pp_source = _principal_point(hdr, frame, fov, (sx, sy), detector_shape, note_camera, notes)
    cam = Camera(float(f), (float(sx), float(sy)), pp)
    try:
        cam.validate()
    except ValueError as exc:
        raise InputError(path, "camera", f"a valid camera from the header ({exc})") from None
    source = {
        "focal_length": tag_name("DistanceSourceToDetector"),
        "pixel_size": spacing_source,
        "principal_point": pp_source,
    }
    return cam, source, tuple(notes), []


def _pitch(hdr: DicomHeader, frame: int, notes: list[str]) -> tuple[tuple[float, float] | None, str]:
    path, ds = hdr.path, hdr.ds
    ips, _ = lookup(ds, frame, PIXEL_PROPS, "ImagerPixelSpacing", path)
    if ips is not None:
        return as_floats(ips, "ImagerPixelSpacing", path, 2, positive=True), tag_name("ImagerPixelSpacing")
    ps, _ = lookup(ds, frame, MEASURES, "PixelSpacing", path)
    if ps is None:
        return None, ""
    ps = as_floats(ps, "PixelSpacing", path, 2, positive=True)
    calib, _ = lookup(ds, frame, MEASURES, "PixelSpacingCalibrationType", path)
    calib = as_text(calib)
    if not calib:
        notes.append("PixelSpacing without a calibration type taken as the detector pitch")
        return ps, f"{tag_name('PixelSpacing')}, no calibration type: taken as the detector pitch"
    mag_value, _ = lookup(ds, frame, None, "EstimatedRadiographicMagnificationFactor", path)
    if mag_value is None:
        notes.append(
            f"PixelSpacing is calibrated to another plane ({calib}) and no "
            f"EstimatedRadiographicMagnificationFactor brings it back to the detector: not used as the pitch"
        )
        return None, ""
    mag = as_floats(mag_value, "EstimatedRadiographicMagnificationFactor", path, 1, positive=True)[0]
    return (
        (ps[0] * mag, ps[1] * mag),
        f"{tag_name('PixelSpacing')}, calibration {calib}, × "
        f"{tag_name('EstimatedRadiographicMagnificationFactor')} {mag:g}",
    )


def _principal_point(
    hdr: DicomHeader,
    frame: int,
    fov: FieldOfView,
    pitch: tuple[float, float],
    shape: tuple[int, int],
    note_camera: Camera | None,
    notes: list[str],
) -> tuple[tuple[float, float], str]:
    path, ds = hdr.path, hdr.ds
    iso = raw_value(ds, "PositionOfIsocenterProjection", path)
    element = raw_value(ds, "DetectorElementSpacing", path)
    element = as_floats(element, "DetectorElementSpacing", path, 2, positive=True) if element is not None else None
    origin = fov.origin or (0.0, 0.0)
    # detector-element (row, column) spacing → pixels per element along x (columns) and y (rows)
    bin_x = pitch[0] / element[1] if element else 1.0
    bin_y = pitch[1] / element[0] if element else 1.0
    if iso is not None:
        r, c = as_floats(iso, "PositionOfIsocenterProjection", path, 2)
        if element is None:
            notes.append("no DetectorElementSpacing: one detector element per image pixel assumed")
        u = (c + 0.5 - origin[1]) / bin_x - 0.5
        v = (r + 0.5 - origin[0]) / bin_y - 0.5
        return (u, v), tag_name("PositionOfIsocenterProjection")
    size = raw_value(ds, "PhysicalDetectorSize", path)
    if size is not None and element is not None and fov.origin is not None:
        h_mm, w_mm = as_floats(size, "PhysicalDetectorSize", path, 2, positive=True)
        cr, cc = h_mm / element[0] / 2.0, w_mm / element[1] / 2.0  # centre, in element-corner units
        return (
            ((cc - origin[1]) / bin_x - 0.5, (cr - origin[0]) / bin_y - 0.5),
            f"centre of the physical detector ({tag_name('PhysicalDetectorSize')}, {tag_name('FieldOfViewOrigin')})",
        )
    if note_camera is not None:
        return note_camera.principal_point_px, "ftrac note"
    h, w = shape
    return ((w - 1) / 2.0, (h - 1) / 2.0), "image centre"


def frame_times(hdr: DicomHeader) -> list[float | None]:
    """Each frame's time (s) from the start of the run: Frame Time (0018,1063), Frame Time
    Vector (0018,1065), or the Frame Content's Frame Acquisition / Reference DateTime of an
    enhanced object; None for all when the file gives none."""
    path, ds, n = hdr.path, hdr.ds, hdr.frames
    if hdr.enhanced:
        stamps = [_content_time(hdr, i) for i in range(n)]
        if stamps and all(s is not None for s in stamps):
            return [(s - stamps[0]).total_seconds() for s in stamps]
    vector = raw_value(ds, "FrameTimeVector", path)
    if vector is not None:
        ms = as_floats(vector, "FrameTimeVector", path, n)
        if min(ms) < 0:
            raise InputError(path, tag_name("FrameTimeVector"), f"{n} non-negative increments (ms)")
        # the first value is the first frame's offset (0); each next one the increment to it
        return [float(t) / 1000.0 for t in np.cumsum(ms) - ms[0]]
    ft = raw_value(ds, "FrameTime", path)
    if ft is not None:
        dt = as_floats(ft, "FrameTime", path, 1, positive=True)[0]
        return [i * dt / 1000.0 for i in range(n)]
    return [None] * n


def _content_time(hdr: DicomHeader, frame: int) -> datetime.datetime | None:
    from pydicom.valuerep import DT

    for kw in ("FrameAcquisitionDateTime", "FrameReferenceDateTime"):
        value, _ = lookup(hdr.ds, frame, CONTENT, kw, hdr.path)
        if value is None:
            continue
        try:
            dt = value if isinstance(value, datetime.datetime) else DT(str(value))
        except (TypeError, ValueError):
            raise InputError(
                hdr.path, tag_name(kw), f"a DICOM DT value (YYYYMMDDhhmmss.ffffff), got {value!r}"
            ) from None
        return dt.replace(tzinfo=None)
    return None


def positioner(hdr: DicomHeader, frame: int) -> dict[str, Any]:
    """Positioner angles of ``frame`` (degrees, as in the file) where given, for ``meta``."""
    out = {}
    for kw in ("PositionerPrimaryAngle", "PositionerSecondaryAngle"):
        value, _ = lookup(hdr.ds, frame, "PositionerPositionSequence", kw, hdr.path)
        if value is not None:
            try:
                out[kw] = float(value)
            except (TypeError, ValueError):
                continue
    return out
