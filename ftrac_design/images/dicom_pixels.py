"""A DICOM frame's pixel values: decoded one frame at a time (pydicom's pixel handlers,
pylibjpeg and its plug-ins for JPEG / JPEG 2000), the bits above Bits Stored masked off,
two's-complement sign restored (Pixel Representation), then the Modality LUT Sequence
(0028,3000) or Rescale Slope/Intercept (top level, or the Pixel Value Transformation
functional group) applied. VOI LUT and window are for display and never applied.

MONOCHROME1 only says how values are displayed (the minimum white); the values are kept as
stored. Polarity comes from Pixel Intensity Relationship Sign (0028,1041), which PS3.3
C.8.11.3.1.2 ties to the stored values and the beam intensity: +1 = lower values, less
intensity (dense matter dark), −1 = higher values, less intensity (dense matter bright). A
decreasing modality transform flips it. Without a sign, LIN (XA/XRF: values approximately
proportional to the beam intensity) implies dense-dark; LOG and DISP imply nothing.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ..errors import InputError
from .dicom_header import DicomHeader
from .dicom_tags import as_floats, as_int, as_text, lookup, raw_value, tag_name
from .frame import Formation, Polarity, flip_polarity, to_grey

PIXEL_PROPS = "FramePixelDataPropertiesSequence"
TRANSFORM = "PixelValueTransformationSequence"
FORMATION: dict[str, Formation] = {"LIN": "linear", "LOG": "log", "DISP": "display"}


def decode_frame(hdr: DicomHeader, frame: int) -> np.ndarray:
    """The stored samples of ``frame`` as pydicom decodes them ((H, W) or (H, W, 3) RGB)."""
    from pydicom.pixels import pixel_array

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            arr = pixel_array(hdr.path, index=frame)
    except Exception as exc:  # decoders raise many types for damaged or lying data
        raise InputError(
            hdr.path,
            f"frame {frame}",
            f"decodable pixel data ({hdr.transfer_syntax_name}; {type(exc).__name__}: {exc})",
        ) from None
    expected = (hdr.rows, hdr.columns) + ((3,) if hdr.samples == 3 else ())
    if arr.shape != expected:
        raise InputError(
            hdr.path,
            f"{tag_name('Rows')} / {tag_name('Columns')}",
            f"frames of {expected}, decoded {arr.shape} (frame {frame})",
        )
    return arr


def stored_values(hdr: DicomHeader, arr: np.ndarray) -> np.ndarray:
    """Integer stored values: bits above Bits Stored masked, the sign restored when signed."""
    if arr.dtype.kind not in "iu" or hdr.bits_allocated == 1:
        return arr
    bits = hdr.bits_stored
    unsigned = arr.view(arr.dtype.str.replace("i", "u")) if arr.dtype.kind == "i" else arr
    if bits >= 8 * unsigned.dtype.itemsize:
        # every bit allocated is stored: the samples are the values, no copy (a run's frame is
        # read at video rate)
        values = unsigned
    else:
        values = unsigned & unsigned.dtype.type((1 << bits) - 1)
    if hdr.signed:
        wide = values.astype(np.int32 if values.dtype.itemsize < 4 else np.int64)
        values = np.where(wide >= (1 << (bits - 1)), wide - (1 << bits), wide)
    return values


def modality_values(hdr: DicomHeader, frame: int, stored: np.ndarray) -> tuple[np.ndarray, int, str | None]:
    """Modality values of ``stored`` (grey; the stored integers themselves where the transform
    is the identity, float64 otherwise), the transform's direction (+1 increasing, −1
    decreasing) and a note naming the transform applied (None for identity)."""
    path, ds = hdr.path, hdr.ds
    lut = raw_value(ds, "ModalityLUTSequence", path)
    if lut is not None:
        return _apply_lut(hdr, stored)
    slope, where = lookup(ds, frame, TRANSFORM, "RescaleSlope", path)
    intercept, _ = lookup(ds, frame, TRANSFORM, "RescaleIntercept", path)
    if slope is None and intercept is None:
        return stored, 1, None
    m = as_floats(slope, "RescaleSlope", path, 1)[0] if slope is not None else 1.0
    b = as_floats(intercept, "RescaleIntercept", path, 1)[0] if intercept is not None else 0.0
    if m == 0:
        raise InputError(path, tag_name("RescaleSlope"), "a non-zero slope")
    if m == 1 and b == 0:
        return stored, 1, None
    return stored * m + b, (1 if m > 0 else -1), f"rescale applied (value = stored × {m:g} + {b:g}, {where})"


def _apply_lut(hdr: DicomHeader, stored: np.ndarray) -> tuple[np.ndarray, int, str]:
    from pydicom.pixels import apply_modality_lut

    item = raw_value(hdr.ds, "ModalityLUTSequence", hdr.path)[0]
    desc = raw_value(item, "LUTDescriptor", hdr.path)
    data = raw_value(item, "LUTData", hdr.path)
    if desc is None or data is None or len(desc) != 3:
        raise InputError(hdr.path, tag_name("ModalityLUTSequence"), "an item with LUTDescriptor (3 values) and LUTData")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = apply_modality_lut(stored, hdr.ds)
            table = np.asarray(item.LUTData, dtype=np.float64).ravel()
    except Exception as exc:
        raise InputError(
            hdr.path, tag_name("ModalityLUTSequence"), f"a usable LUT ({type(exc).__name__}: {exc})"
        ) from None
    direction = 1 if table.size < 2 or table[-1] >= table[0] else -1
    return np.asarray(out, dtype=np.float64), direction, "Modality LUT Sequence (0028,3000) applied"


def grey_values(hdr: DicomHeader, frame: int, arr: np.ndarray) -> tuple[np.ndarray, int, tuple[str, ...]]:
    """Modality values of a decoded frame as a grey (H, W) image (integers or float64), the value map's
    direction and the notes (colour → Rec. 709 grey; MONOCHROME1 kept as stored)."""
    if hdr.samples == 3:
        grey, notes = to_grey(np.asarray(arr), hdr.path)
        return grey, 1, (f"{hdr.photometric} (a frame grabber's DICOM?) converted to grey (Rec. 709 luminance)",)
    values, direction, note = modality_values(hdr, frame, stored_values(hdr, arr))
    notes = (note,) if note else ()
    if hdr.photometric == "MONOCHROME1":
        notes += ("MONOCHROME1: values kept as stored (it only says the minimum is displayed white)",)
    return values, direction, notes


def formation_polarity(
    hdr: DicomHeader, frame: int, direction: int, note_polarity: Polarity | None
) -> tuple[Formation | None, Polarity | None, tuple[str, ...]]:
    """Formation and polarity of ``frame``'s modality values (see the module)."""
    path, ds = hdr.path, hdr.ds
    rel, _ = lookup(ds, frame, PIXEL_PROPS, "PixelIntensityRelationship", path)
    sign, _ = lookup(ds, frame, PIXEL_PROPS, "PixelIntensityRelationshipSign", path)
    rel = as_text(rel)
    formation = FORMATION.get(rel)
    notes: list[str] = []
    if rel and formation is None:
        notes.append(f"PixelIntensityRelationship {rel!r} is none of LIN/LOG/DISP: formation unknown")
    polarity: Polarity | None = None
    if sign is not None:
        s = as_int(sign, "PixelIntensityRelationshipSign", path)
        if s not in (1, -1):
            raise InputError(path, tag_name("PixelIntensityRelationshipSign"), f"+1 or -1, got {s}")
        polarity = "dense-dark" if s == 1 else "dense-bright"
    elif rel == "LIN":
        polarity = "dense-dark"
        notes.append("LIN without a sign: values proportional to the beam intensity, dense matter dark")
    elif note_polarity is not None:
        return formation, note_polarity, tuple(notes)  # our note describes the modality values
    if polarity is not None and direction < 0:
        polarity = flip_polarity(polarity)
        notes.append("decreasing modality transform: polarity of the stored values reversed")
    return formation, polarity, tuple(notes)


def header_meta(hdr: DicomHeader) -> dict[str, Any]:
    """The ``meta`` entries every frame of ``hdr`` shares."""
    return {
        "format": "dicom",
        "bits": hdr.bits_stored,
        "bits_allocated": hdr.bits_allocated,
        "signed": hdr.signed,
        "photometric": hdr.photometric,
        "modality": hdr.modality,
        "sop_class": hdr.sop_class,
        "transfer_syntax": hdr.transfer_syntax,
        "transfer_syntax_name": hdr.transfer_syntax_name,
        "frames": hdr.frames,
        "enhanced": hdr.enhanced,
    }
