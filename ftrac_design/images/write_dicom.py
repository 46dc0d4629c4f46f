"""The test-data DICOM writer: every case intake reads can be written, so tests and
benchmarks make their own files (XA, RF, DX, CR, Enhanced XA / XRF; MONOCHROME1/2, RGB;
LIN/LOG/DISP with either sign; field-of-view rotation and flip; runs with Frame Time,
Frame Time Vector or per-frame Frame Content; compressed transfer syntaxes; missing tags).

``frames`` are the *stored* integer values on the detector grid; the writer rotates and
flips them into the stored grid as Field of View Rotation / Horizontal Flip say, so a
correct reader returns ``frames × slope + intercept`` (or the LUT's values) on the detector
grid. MONOCHROME1 does not invert them: by the standard the photometric interpretation only
says how values are displayed (see :mod:`.dicom_pixels`).
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Sequence

import numpy as np

from ..errors import require
from ..fileio import atomic_file
from ..pose.camera import Camera
from .dicom_geometry import FieldOfView, apply_field_of_view

Kind = Literal["xa", "rf", "dx", "cr", "enhanced-xa", "enhanced-xrf"]
Syntax = Literal["explicit", "rle", "jpeg-lossless", "jpeg2000-lossless"]
SOP = {
    "xa": ("1.2.840.10008.5.1.4.1.1.12.1", "XA"),
    "rf": ("1.2.840.10008.5.1.4.1.1.12.2", "RF"),
    "dx": ("1.2.840.10008.5.1.4.1.1.1.1", "DX"),
    "cr": ("1.2.840.10008.5.1.4.1.1.1", "CR"),
    "enhanced-xa": ("1.2.840.10008.5.1.4.1.1.12.1.1", "XA"),
    "enhanced-xrf": ("1.2.840.10008.5.1.4.1.1.12.2.1", "RF"),
}
DX_FOR_PROCESSING = "1.2.840.10008.5.1.4.1.1.1.1.1"
SYNTAX = {
    "explicit": "1.2.840.10008.1.2.1",
    "rle": "1.2.840.10008.1.2.5",
    "jpeg-lossless": "1.2.840.10008.1.2.4.70",
    "jpeg2000-lossless": "1.2.840.10008.1.2.4.90",
}
_T0 = datetime.datetime(2026, 1, 1, 12, 0, 0)


@dataclass(frozen=True)
class DicomTags:
    """What :func:`write_dicom` writes beside the pixels (its keyword arguments).

    Attributes
    ----------
    kind : the IOD. Enhanced kinds keep geometry in functional groups.
    photometric, relationship, relationship_sign : Photometric Interpretation, Pixel
        Intensity Relationship (0028,1040) and its Sign (0028,1041).
    fov_rotation_deg, fov_horizontal_flip : clockwise rotation (0/90/180/270 degrees) and flip of
        the stored grid relative to the detector.
    frame_time_ms, frame_time_vector_ms : Frame Time (0018,1063) or Frame Time Vector (0018,1065)
        (legacy kinds); enhanced kinds get per-frame Frame Acquisition DateTime from them.
    transfer_syntax : explicit VR little endian, RLE Lossless, JPEG Lossless SV1 (needs
        imagecodecs) or JPEG 2000 Lossless (needs pylibjpeg-openjpeg).
    omit : keywords deleted wherever they were written (top level and functional groups).
    pixel_spacing_only : write Pixel Spacing (0028,0030) = pitch / magnification with
        ``calibration`` (omitted when None) and Estimated Radiographic Magnification Factor
        (``magnification``, omitted when None) instead of Imager Pixel Spacing.
    isocenter_projection_px : (u, v) detector-grid pixels of the isocentre's projection:
        Position of Isocenter Projection with one detector element per pixel, origin (0, 0).
    signed, bits_stored : Pixel Representation and Bits Stored (Bits Allocated is 8 for
        uint8 RGB, else 16).
    rescale : (slope, intercept) Rescale Slope/Intercept (Pixel Value Transformation group for
        enhanced kinds); ``modality_lut`` a Modality LUT Sequence instead (first mapped value 0).
    image_comments, presentation_intent : Image Comments and Presentation Intent Type.
    """

    kind: Kind = "xa"
    photometric: Literal["MONOCHROME2", "MONOCHROME1", "RGB"] = "MONOCHROME2"
    relationship: Literal["LIN", "LOG", "DISP"] | None = None
    relationship_sign: int | None = None
    fov_rotation_deg: int = 0
    fov_horizontal_flip: bool = False
    frame_time_ms: float | None = None
    frame_time_vector_ms: Sequence[float] | None = None
    transfer_syntax: Syntax = "explicit"
    omit: tuple[str, ...] = ()
    pixel_spacing_only: bool = False
    calibration: Literal["GEOMETRY", "FIDUCIAL"] | None = "GEOMETRY"
    magnification: float | None = None
    isocenter_projection_px: tuple[float, float] | None = None
    signed: bool = False
    bits_stored: int = 16
    rescale: tuple[float, float] | None = None
    modality_lut: np.ndarray | None = None
    image_comments: str | None = None
    presentation_intent: str | None = None


def write_dicom(path: str | Path, frames: np.ndarray, camera: Camera | Sequence[Camera] | None, **tags: Any) -> Path:
    """Write a DICOM image or run atomically (see the module).

    Parameters
    ----------
    path : output file.
    frames : (H, W) or (n, H, W) stored integers on the detector grid; (…, H, W, 3) uint8 with
        ``photometric="RGB"``.
    camera : intrinsics (detector-grid pixels), one per frame for a per-frame geometry
        (enhanced kinds), or None to write no geometry.
    **tags : what is written beside the pixels, by keyword: the fields of :class:`DicomTags`
        (``kind="enhanced-xa"``, ``relationship="LIN"``, ``frame_time_ms=66.7``, …); an unknown
        keyword raises TypeError.

    Returns
    -------
    Path : ``path``.
    """
    t = DicomTags(**tags)
    path = Path(path)
    frames, rgb = _frames(frames, t.photometric)
    n = frames.shape[0]
    cams = _cameras(camera, n, t.kind)
    fov = FieldOfView(int(t.fov_rotation_deg), bool(t.fov_horizontal_flip), (0.0, 0.0))
    stored = np.ascontiguousarray(np.stack([apply_field_of_view(f, fov) for f in frames]))
    ds = _base(path, t.kind, stored, n, t.photometric, rgb, t.signed, t.bits_stored, t.transfer_syntax)
    if t.presentation_intent:
        ds.PresentationIntentType = t.presentation_intent
        if t.kind == "dx" and t.presentation_intent == "FOR PROCESSING":
            ds.SOPClassUID = ds.file_meta.MediaStorageSOPClassUID = DX_FOR_PROCESSING
    if t.image_comments:
        ds.ImageComments = t.image_comments
    _geometry_and_time(ds, t, n, cams, fov)
    if t.modality_lut is not None:
        _modality_lut(ds, np.asarray(t.modality_lut), t.bits_stored)
    _isocenter(ds, t, cams)
    _omit(ds, t.omit)
    _pixel_data(ds, stored, t.transfer_syntax, t.bits_stored, t.signed, rgb)
    with atomic_file(path) as tmp:
        ds.save_as(tmp, enforce_file_format=True)
    return path


def _geometry_and_time(ds, t: DicomTags, n: int, cams: list[Camera], fov: FieldOfView) -> None:
    """The tags of the geometry, the pixel relationship, the frames' times and the rescale:
    in functional groups for the enhanced kinds, at the top level for the others."""
    timing = (t.frame_time_ms, t.frame_time_vector_ms)
    spacing = (t.pixel_spacing_only, t.calibration, t.magnification, t.rescale)
    if t.kind.startswith("enhanced"):
        from .write_dicom_groups import enhanced_groups

        enhanced_groups(ds, n, cams, fov, t.relationship, t.relationship_sign, *timing, *spacing, _T0)
    else:
        cam = cams[0] if cams else None
        _legacy_tags(ds, n, cam, fov, t.relationship, t.relationship_sign, *timing, *spacing)


def _isocenter(ds, t: DicomTags, cams: list[Camera]) -> None:
    """The isocentre's projection, one detector element per pixel (with a camera)."""
    if t.isocenter_projection_px is not None and cams:
        u, v = t.isocenter_projection_px
        ds.PositionOfIsocenterProjection = [float(v), float(u)]
        sx, sy = cams[0].pixel_size_mm
        ds.DetectorElementSpacing = [f"{sy:.10g}", f"{sx:.10g}"]
        if not t.kind.startswith("enhanced"):
            ds.FieldOfViewOrigin = ["0", "0"]


def _frames(frames: np.ndarray, photometric: str) -> tuple[np.ndarray, bool]:
    a = np.asarray(frames)
    rgb = photometric == "RGB"
    if rgb:
        a = a[None] if a.ndim == 3 else a
        if a.ndim != 4 or a.shape[-1] != 3 or a.dtype != np.uint8:
            raise ValueError("RGB frames: (H, W, 3) or (n, H, W, 3) uint8")
        return a, True
    a = a[None] if a.ndim == 2 else a
    if a.ndim != 3 or a.dtype.kind not in "iu":
        raise ValueError(f"frames: (H, W) or (n, H, W) integers, got {a.dtype} {a.shape}")
    return a, False


def _cameras(camera, n: int, kind: str) -> list[Camera]:
    if camera is None:
        return []
    if isinstance(camera, Camera):
        return [camera] * n
    cams = list(camera)
    if len(cams) != n:
        raise ValueError(f"one camera per frame ({n}), got {len(cams)}")
    if not kind.startswith("enhanced") and len(set(cams)) > 1:
        raise ValueError("a per-frame geometry needs an enhanced kind (functional groups)")
    return cams


def _base(
    path: Path,
    kind: str,
    stored: np.ndarray,
    n: int,
    photometric: str,
    rgb: bool,
    signed: bool,
    bits_stored: int,
    syntax: str,
):
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import generate_uid

    sop, modality = SOP[kind]
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = SYNTAX[syntax]
    ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID, ds.SOPInstanceUID = sop, meta.MediaStorageSOPInstanceUID
    ds.StudyInstanceUID, ds.SeriesInstanceUID = generate_uid(), generate_uid()
    ds.Modality = modality
    ds.PatientName, ds.PatientID = "FTRAC^PHANTOM", "ftrac-sim"
    ds.Manufacturer = "ftrac_design (simulated)"
    ds.ContentDate, ds.ContentTime = _T0.strftime("%Y%m%d"), _T0.strftime("%H%M%S")
    ds.ImageType = ["ORIGINAL", "PRIMARY", "SINGLE PLANE" if kind in ("xa", "rf") else ""]
    ds.SamplesPerPixel = 3 if rgb else 1
    ds.PhotometricInterpretation = photometric
    if rgb:
        ds.PlanarConfiguration = 0
    ds.Rows, ds.Columns = stored.shape[1], stored.shape[2]
    ds.BitsAllocated = 8 if rgb else 16
    ds.BitsStored = 8 if rgb else int(bits_stored)
    ds.HighBit = ds.BitsStored - 1
    ds.PixelRepresentation = 1 if signed else 0
    if n > 1 or kind.startswith("enhanced"):
        ds.NumberOfFrames = n
    return ds


def _legacy_tags(
    ds, n, cam, fov, relationship, sign, frame_time_ms, vector_ms, spacing_only, calibration, magnification, rescale
) -> None:
    if cam is not None:
        sx, sy = cam.pixel_size_mm
        row, col = (sx, sy) if fov.rotation_deg in (90, 270) else (sy, sx)  # stored grid's (row, column)
        if spacing_only:
            m = magnification or 1.0
            ds.PixelSpacing = [f"{row / m:.10g}", f"{col / m:.10g}"]
            if calibration:
                ds.PixelSpacingCalibrationType = calibration
            if magnification is not None:
                ds.EstimatedRadiographicMagnificationFactor = f"{magnification:.10g}"
        else:
            ds.ImagerPixelSpacing = [f"{row:.10g}", f"{col:.10g}"]
        ds.DistanceSourceToDetector = f"{cam.focal_length_mm:.10g}"
    if relationship:
        ds.PixelIntensityRelationship = relationship
    if sign is not None:
        ds.PixelIntensityRelationshipSign = int(sign)
    if fov.rotation_deg or fov.flip:
        ds.FieldOfViewOrigin = ["0", "0"]
        ds.FieldOfViewRotation = str(fov.rotation_deg)
        ds.FieldOfViewHorizontalFlip = "YES" if fov.flip else "NO"
    if vector_ms is not None:
        ds.FrameTimeVector = [f"{t:.10g}" for t in vector_ms]
        ds.FrameIncrementPointer = 0x00181065
    elif frame_time_ms is not None:
        ds.FrameTime = f"{frame_time_ms:.10g}"
        ds.FrameIncrementPointer = 0x00181063
    if rescale is not None:
        ds.RescaleSlope, ds.RescaleIntercept = f"{rescale[0]:.10g}", f"{rescale[1]:.10g}"
        ds.RescaleType = "US"


def _modality_lut(ds, table: np.ndarray, bits_stored: int) -> None:
    from pydicom.dataset import Dataset
    from pydicom.sequence import Sequence as Seq

    item = Dataset()
    item.LUTDescriptor = [int(table.size), 0, 16]
    item.ModalityLUTType = "US"
    item.add_new(0x00283006, "US", [int(x) for x in table.astype(np.uint16)])  # LUT Data, US or OW
    ds.ModalityLUTSequence = Seq([item])


def _omit(ds, keywords: tuple[str, ...]) -> None:
    for kw in keywords:
        if kw in ds:
            delattr(ds, kw)
    for seq_kw in ("SharedFunctionalGroupsSequence", "PerFrameFunctionalGroupsSequence"):
        for group in getattr(ds, seq_kw, []) or []:
            for elem in list(group):
                if elem.VR == "SQ":
                    for item in elem.value:
                        for kw in keywords:
                            if kw in item:
                                delattr(item, kw)


def _pixel_data(ds, stored: np.ndarray, syntax: str, bits_stored: int, signed: bool, rgb: bool) -> None:
    if rgb:
        arr = np.ascontiguousarray(stored, dtype=np.uint8)
    else:
        arr = np.ascontiguousarray(stored, dtype=np.int16 if signed else np.uint16)
    if syntax == "explicit":
        data = arr.tobytes()
        ds.PixelData = data + (b"\0" if len(data) % 2 else b"")
        return
    if syntax == "jpeg-lossless":
        from pydicom.encaps import encapsulate

        imagecodecs = require("imagecodecs", "dicom", "writing JPEG Lossless DICOM")

        enc = [imagecodecs.jpeg8_encode(f, lossless=True, predictor=1, bitspersample=int(ds.BitsStored)) for f in arr]
        ds.PixelData = encapsulate(enc)
        ds["PixelData"].VR = "OB"
        return
    from pydicom.uid import UID

    src = arr if arr.shape[0] > 1 else arr[0]
    ds.PixelData = src.tobytes()
    ds.compress(UID(SYNTAX[syntax]), src, generate_instance_uid=False)
