"""A DICOM file's header, read without its pixel data and checked before any frame is
decoded: image size and sample layout, bits, frame count, transfer syntax and whether its
codec is installed. A header that lies is refused here, naming the tag."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError
from .dicom_tags import as_int, as_text, raw_value, tag_name
from .frame import check_frame_size

#: photometric interpretations intake reads: grey, and colour from a frame grabber
PHOTOMETRIC = ("MONOCHROME1", "MONOCHROME2", "RGB", "YBR_FULL", "YBR_FULL_422", "YBR_RCT", "YBR_ICT", "YBR_PARTIAL_420")
#: the Python package that decodes each compressed transfer syntax, for the error when it is missing
CODEC_PACKAGES = {
    **dict.fromkeys(
        (
            "1.2.840.10008.1.2.4.57",
            "1.2.840.10008.1.2.4.70",
            "1.2.840.10008.1.2.4.50",
            "1.2.840.10008.1.2.4.51",
            "1.2.840.10008.1.2.4.80",
            "1.2.840.10008.1.2.4.81",
        ),
        "pylibjpeg and pylibjpeg-libjpeg",
    ),
    **dict.fromkeys(("1.2.840.10008.1.2.4.90", "1.2.840.10008.1.2.4.91"), "pylibjpeg and pylibjpeg-openjpeg"),
    "1.2.840.10008.1.2.5": "pydicom (RLE Lossless is built in)",
}
ENHANCED_SOP = {"1.2.840.10008.5.1.4.1.1.12.1.1": "Enhanced XA", "1.2.840.10008.5.1.4.1.1.12.2.1": "Enhanced XRF"}


@dataclass(frozen=True)
class DicomHeader:
    """What intake needs from a DICOM header, checked (see the module)."""

    path: Path
    ds: Any  # the pydicom Dataset, pixel data deferred
    rows: int
    columns: int
    frames: int
    samples: int
    bits_allocated: int
    bits_stored: int
    signed: bool
    photometric: str
    transfer_syntax: str
    transfer_syntax_name: str
    sop_class: str
    modality: str
    enhanced: bool


def read_header(path: str | Path) -> DicomHeader:
    """Read and check the header of the DICOM file at ``path`` (pixel data not loaded).

    Raises
    ------
    InputError : unreadable, no pixel data, or a header value that is missing, malformed,
        inconsistent with the pixel data, or too large (see :func:`check_frame_size`).
    """
    import pydicom

    path = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = pydicom.dcmread(path, defer_size="64 KB")
            "PixelData" in ds  # noqa: B015 - parses up to the pixel data, so a cut header fails here
    except Exception as exc:  # pydicom raises many types for malformed files (InvalidDicomError, EOFError, …)
        raise InputError(path, None, f"a readable DICOM file ({type(exc).__name__}: {exc})") from None
    meta = getattr(ds, "file_meta", None)
    ts = str(raw_value(meta, "TransferSyntaxUID", path) or "1.2.840.10008.1.2")
    if "PixelData" not in ds:
        raise InputError(
            path,
            "PixelData (7FE0,0010)",
            "a DICOM image with pixel data (FloatPixelData and non-image objects are not read)",
        )
    rows = as_int(_required(ds, "Rows", path), "Rows", path, 1, 65535)
    columns = as_int(_required(ds, "Columns", path), "Columns", path, 1, 65535)
    samples = as_int(raw_value(ds, "SamplesPerPixel", path) or 1, "SamplesPerPixel", path, 1, 3)
    if samples == 2:
        raise InputError(path, tag_name("SamplesPerPixel"), "1 (grey) or 3 (colour), got 2")
    bits_allocated = as_int(_required(ds, "BitsAllocated", path), "BitsAllocated", path, 1, 64)
    if bits_allocated not in (1, 8, 16, 32):
        raise InputError(path, tag_name("BitsAllocated"), f"1, 8, 16 or 32, got {bits_allocated}")
    bits_stored = as_int(raw_value(ds, "BitsStored", path) or bits_allocated, "BitsStored", path, 1, 64)
    if bits_stored > bits_allocated:
        raise InputError(path, tag_name("BitsStored"), f"at most BitsAllocated ({bits_allocated}), got {bits_stored}")
    high_bit = raw_value(ds, "HighBit", path)
    if high_bit is not None and as_int(high_bit, "HighBit", path) != bits_stored - 1:
        raise InputError(path, tag_name("HighBit"), f"BitsStored − 1 = {bits_stored - 1}, got {high_bit}")
    signed = as_int(raw_value(ds, "PixelRepresentation", path) or 0, "PixelRepresentation", path, 0, 1) == 1
    frames = as_int(raw_value(ds, "NumberOfFrames", path) or 1, "NumberOfFrames", path, 1, 10**7)
    photometric = as_text(raw_value(ds, "PhotometricInterpretation", path)) or (
        "MONOCHROME2" if samples == 1 else "RGB"
    )
    if photometric not in PHOTOMETRIC:
        raise InputError(
            path, tag_name("PhotometricInterpretation"), f"one of {', '.join(PHOTOMETRIC)}, got {photometric!r}"
        )
    if (samples == 1) != photometric.startswith("MONOCHROME"):
        raise InputError(
            path,
            tag_name("PhotometricInterpretation"),
            f"a photometric interpretation matching SamplesPerPixel {samples}, got {photometric}",
        )
    check_frame_size(
        path, (rows, columns), f"{tag_name('Rows')} × {tag_name('Columns')}", max(1, bits_allocated // 8) * samples
    )
    name = _check_codec(path, ts)
    hdr = DicomHeader(
        path,
        ds,
        rows,
        columns,
        frames,
        samples,
        bits_allocated,
        bits_stored,
        signed,
        photometric,
        ts,
        name,
        str(raw_value(ds, "SOPClassUID", path) or ""),
        as_text(raw_value(ds, "Modality", path)),
        str(raw_value(ds, "SOPClassUID", path) or "") in ENHANCED_SOP
        or raw_value(ds, "PerFrameFunctionalGroupsSequence", path) is not None,
    )
    _check_length(hdr)
    return hdr


def _required(ds: Any, keyword: str, path: Path) -> Any:
    value = raw_value(ds, keyword, path)
    if value is None:
        raise InputError(path, tag_name(keyword), "present in a DICOM image")
    return value


def _check_codec(path: Path, ts: str) -> str:
    from pydicom.pixels import get_decoder
    from pydicom.uid import UID

    uid = UID(ts)
    name = uid.name if uid.is_transfer_syntax else ts
    if not uid.is_transfer_syntax:
        raise InputError(path, "TransferSyntaxUID (0002,0010)", f"a known transfer syntax, got {ts!r}")
    if not uid.is_compressed:
        return name
    try:
        decoder = get_decoder(uid)
        available = decoder.is_available
    except Exception:  # pydicom has no decoder at all for this syntax
        available = False
    if not available:
        pkg = CODEC_PACKAGES.get(ts, "a pydicom pixel-data plug-in for it (pylibjpeg and its plug-ins, or GDCM)")
        raise InputError(
            path,
            "TransferSyntaxUID (0002,0010)",
            f"a transfer syntax this installation decodes: "
            f"{ts} ({name}) needs {pkg} (pip install 'ftrac_design[dicom]')",
        )
    return name


def _check_length(hdr: DicomHeader) -> None:
    """For native (uncompressed) pixel data, the bytes must match Rows × Columns × frames."""
    from pydicom.uid import UID

    if UID(hdr.transfer_syntax).is_compressed:
        return
    try:
        elem = hdr.ds.get_item("PixelData", keep_deferred=True)
        length = getattr(elem, "length", None)  # a raw (deferred) element knows its length
        if length is None:
            length = len(elem.value or b"")
    except Exception as exc:  # pydicom raises many types for a damaged element
        raise InputError(hdr.path, "PixelData (7FE0,0010)", f"a readable pixel data element ({exc})") from None
    if length is None or length == 0xFFFFFFFF:
        raise InputError(
            hdr.path,
            "PixelData (7FE0,0010)",
            "native pixel data of defined length (the transfer syntax is uncompressed)",
        )
    bits = hdr.rows * hdr.columns * hdr.samples * hdr.bits_allocated
    frame_bytes = bits // 8 if hdr.bits_allocated > 1 else None
    expected = (hdr.frames * bits + 7) // 8
    if length not in (expected, expected + 1):
        claimed = f"{hdr.frames} frame(s) of {hdr.rows} × {hdr.columns} × {hdr.samples} × {hdr.bits_allocated} bits"
        have = f"{length // frame_bytes} whole frame(s)" if frame_bytes else f"{length} bytes"
        raise InputError(
            hdr.path,
            f"{tag_name('NumberOfFrames')} / {tag_name('Rows')} / {tag_name('Columns')}",
            f"a header matching the pixel data: it claims {claimed} = {expected} bytes, the pixel "
            f"data holds {length} bytes ({have})",
        )
