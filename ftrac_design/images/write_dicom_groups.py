"""Functional groups for the test-data writer's Enhanced XA / XRF objects: the Shared and
Per-frame Functional Groups Sequences (5200,9229)/(5200,9230) with Frame Pixel Data
Properties (relationship, sign, Imager Pixel Spacing), X-Ray Geometry (SID), Field of View
(rotation, flip, origin), Pixel Measures (Pixel Spacing), Pixel Value Transformation
(rescale) and Frame Content (frame times). Geometry that differs between frames goes
per-frame, the rest is shared."""

from __future__ import annotations

import datetime
from typing import Sequence

from ..pose.camera import Camera
from .dicom_geometry import FieldOfView


def _item(**kw):
    from pydicom.dataset import Dataset

    d = Dataset()
    for k, v in kw.items():
        setattr(d, k, v)
    return d


def _seq(*items):
    from pydicom.sequence import Sequence as Seq

    return Seq(list(items))


def _geometry(
    group, cam: Camera, fov: FieldOfView, relationship, sign, spacing_only, calibration, magnification
) -> None:
    sx, sy = cam.pixel_size_mm
    row, col = (sx, sy) if fov.rotation_deg in (90, 270) else (sy, sx)
    props = _item(FrameType=["ORIGINAL", "PRIMARY", "SINGLE PLANE"])
    if relationship:
        props.PixelIntensityRelationship = relationship
    if sign is not None:
        props.PixelIntensityRelationshipSign = int(sign)
    if spacing_only:
        m = magnification or 1.0
        measures = _item(PixelSpacing=[f"{row / m:.10g}", f"{col / m:.10g}"])
        if calibration:
            measures.PixelSpacingCalibrationType = calibration
        group.PixelMeasuresSequence = _seq(measures)
    else:
        props.ImagerPixelSpacing = [f"{row:.10g}", f"{col:.10g}"]
    group.FramePixelDataPropertiesSequence = _seq(props)
    group.XRayGeometrySequence = _seq(
        _item(
            DistanceSourceToIsocenter=float(cam.focal_length_mm) * 2.0 / 3.0,
            DistanceSourceToDetector=f"{cam.focal_length_mm:.10g}",
        )
    )


def enhanced_groups(
    ds,
    n: int,
    cams: Sequence[Camera],
    fov: FieldOfView,
    relationship,
    sign,
    frame_time_ms: float | None,
    vector_ms: Sequence[float] | None,
    spacing_only: bool,
    calibration,
    magnification,
    rescale,
    t0: datetime.datetime,
) -> None:
    """Fill ``ds`` (an Enhanced XA/XRF dataset) with its functional groups (see the module)."""
    from pydicom.dataset import Dataset

    shared = Dataset()
    per_frame_geometry = len(set(cams)) > 1
    if cams and not per_frame_geometry:
        _geometry(shared, cams[0], fov, relationship, sign, spacing_only, calibration, magnification)
    elif not cams:
        props = _item(FrameType=["ORIGINAL", "PRIMARY", "SINGLE PLANE"])
        if relationship:
            props.PixelIntensityRelationship = relationship
        if sign is not None:
            props.PixelIntensityRelationshipSign = int(sign)
        shared.FramePixelDataPropertiesSequence = _seq(props)
    shared.FieldOfViewSequence = _seq(
        _item(
            FieldOfViewOrigin=["0", "0"],
            FieldOfViewRotation=str(fov.rotation_deg),
            FieldOfViewHorizontalFlip="YES" if fov.flip else "NO",
        )
    )
    if rescale is not None:
        shared.PixelValueTransformationSequence = _seq(
            _item(RescaleSlope=f"{rescale[0]:.10g}", RescaleIntercept=f"{rescale[1]:.10g}", RescaleType="US")
        )
    if magnification is not None and spacing_only:
        ds.EstimatedRadiographicMagnificationFactor = f"{magnification:.10g}"
    if vector_ms is not None:
        offsets = [sum(vector_ms[1 : k + 1]) for k in range(n)]
    elif frame_time_ms is not None:
        offsets = [k * frame_time_ms for k in range(n)]
    else:
        offsets = None
    frames = []
    for k in range(n):
        group = Dataset()
        content = _item(FrameAcquisitionNumber=k + 1)
        if offsets is not None:
            stamp = t0 + datetime.timedelta(milliseconds=offsets[k])
            content.FrameAcquisitionDateTime = stamp.strftime("%Y%m%d%H%M%S.%f")
        group.FrameContentSequence = _seq(content)
        if per_frame_geometry:
            _geometry(group, cams[k], fov, relationship, sign, spacing_only, calibration, magnification)
        frames.append(group)
    ds.SharedFunctionalGroupsSequence = _seq(shared)
    ds.PerFrameFunctionalGroupsSequence = _seq(*frames)
