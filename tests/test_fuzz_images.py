"""Fuzzing the image readers themselves (ftrac_design.images): PNG, TIFF, JPEG, NumPy and
DICOM files — valid ones written by the standard libraries and our writer, then truncated,
bit-flipped, or given headers that lie (sizes, frame counts, bits, spacings, SID,
photometric, VR strings) — and the named regressions: pure noise, an ``.npz`` named
``.npy``, a two-page TIFF whose pages differ in size, an int32 TIFF, DICOM files whose
headers lie.

Property: :func:`read_frames` and :func:`frame_count` give Frames (finite float32, on
at least 2 × 2 pixels) or an InputError naming the file — never another exception.
Counts: ``fuzz_support.CASES["image_read"]``.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest
from fuzz_support import cases, damage, scratch
from hypothesis import given
from hypothesis import strategies as st
from images_support import CAM
from test_fuzz_image import _dicom_bytes, _npy_bytes, _png_bytes, _tiff_bytes

from ftrac_design.errors import InputError
from ftrac_design.images import frame_count, read_frames, write_dicom

LIES = [
    ("Rows", 65535),
    ("Columns", 3),
    ("NumberOfFrames", 1000000),
    ("NumberOfFrames", 7),
    ("BitsStored", 40),
    ("BitsAllocated", 12),
    ("HighBit", 3),
    ("PixelRepresentation", 5),
    ("SamplesPerPixel", 3),
    ("PhotometricInterpretation", "XYZ"),
    ("ImagerPixelSpacing", [-1, 0.2]),
    ("ImagerPixelSpacing", ["nan", 1]),
    ("DistanceSourceToDetector", 0),
    ("DistanceSourceToDetector", -1e9),
    ("FieldOfViewRotation", 33),
    ("FrameTime", -4),
    ("FrameTimeVector", [1, 2]),
    ("RescaleSlope", 0),
    ("RescaleSlope", "1e400"),
    ("PixelIntensityRelationshipSign", 0),
    ("PositionOfIsocenterProjection", [1e308, -1e308]),
]


def _dicom_file(rng: np.random.Generator, kind: str, syntax: str, lie: tuple | None) -> bytes:
    import pydicom

    with scratch() as tmp:
        n = int(rng.integers(1, 4))
        a = rng.integers(0, 4096, (n, 32, 40)).astype(np.uint16)
        p = write_dicom(
            tmp / "a.dcm",
            a,
            CAM,
            kind=kind,
            transfer_syntax=syntax,
            frame_time_ms=30.0,
            relationship="LIN",
            relationship_sign=1,
            fov_rotation_deg=int(rng.choice([0, 90])),
            bits_stored=12,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = pydicom.dcmread(p)
            # fixed UIDs: the file's length must not vary between runs (Hypothesis draws a cut within it)
            for i, kw in enumerate(("SOPInstanceUID", "StudyInstanceUID", "SeriesInstanceUID")):
                setattr(ds, kw, f"1.2.826.0.1.3680043.8.498.{i + 1}")
            ds.file_meta.MediaStorageSOPInstanceUID = ds.SOPInstanceUID
            ds.save_as(p)
            if lie is not None:
                try:
                    setattr(ds, lie[0], lie[1])
                    ds.save_as(p)
                except Exception:  # pydicom refuses to write this lie: keep the valid file
                    pass
        return p.read_bytes()


def _two_page_tiff(rng: np.random.Generator) -> bytes:
    import tifffile

    buf = io.BytesIO()
    with tifffile.TiffWriter(buf) as tw:
        tw.write(rng.integers(0, 255, (20, 24)).astype(np.uint8))
        tw.write(rng.integers(0, 255, (12, 30)).astype(np.uint8))
    return buf.getvalue()


def _npz(rng: np.random.Generator) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, a=rng.normal(size=(8, 8)))
    return buf.getvalue()


def _jpeg(rng: np.random.Generator) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rng.integers(0, 255, (24, 32, 3)).astype(np.uint8)).save(buf, format="JPEG")
    return buf.getvalue()


NAMED = {
    "noise": lambda rng: rng.integers(0, 256, int(rng.integers(0, 4000))).astype(np.uint8).tobytes(),
    "npz_as_npy": _npz,
    "two_page_tiff": _two_page_tiff,
    "int32_tiff": lambda rng: _tiff_bytes(rng.integers(-(2**31), 2**31 - 1, (16, 20)).astype(np.int32)),
    "jpeg": _jpeg,
    "rgb_png": lambda rng: _png_bytes(rng.integers(0, 255, (16, 16, 3)).astype(np.uint8)),
    "npy_run": lambda rng: _npy_bytes(rng.normal(size=(3, 10, 12))),
    "npy_4d": lambda rng: _npy_bytes(rng.normal(size=(2, 2, 8, 8))),
    "fuzz_dicom": lambda rng: _dicom_bytes(rng.uniform(0, 999, (20, 20))),
}
SUFFIX = {
    "noise": ".dcm",
    "npz_as_npy": ".npy",
    "two_page_tiff": ".tif",
    "int32_tiff": ".tif",
    "jpeg": ".jpg",
    "rgb_png": ".png",
    "npy_run": ".npy",
    "npy_4d": ".npy",
    "fuzz_dicom": ".dcm",
}


@st.composite
def files(draw) -> tuple[str, bytes]:
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    source = draw(st.sampled_from(["dicom"] * 4 + list(NAMED)))
    if source == "dicom":
        kind = draw(st.sampled_from(["xa", "dx", "enhanced-xa", "enhanced-xrf"]))
        syntax = draw(st.sampled_from(["explicit", "explicit", "rle"]))
        lie = draw(st.sampled_from([None] + LIES))
        data, suffix = _dicom_file(rng, kind, syntax, lie), draw(st.sampled_from([".dcm", ".png", ""]))
    else:
        data, suffix = NAMED[source](rng), SUFFIX[source]
    _, data = damage(draw, data)
    return suffix, data


def _read_all(path, need_camera: bool) -> list:
    try:
        frame_count(path)
        frames = list(read_frames(path, need_camera=need_camera))
    except InputError as err:
        assert path.name in str(err), str(err)
        return []
    for f in frames:
        assert f.pixels.dtype == np.float32 and f.pixels.ndim == 2 and min(f.pixels.shape) >= 2
        assert np.isfinite(f.pixels).all()
        assert f.camera is not None or not need_camera
    return frames


@cases("image_read")
@given(case=files(), need_camera=st.booleans())
def test_fuzz_reading_gives_frames_or_an_input_error(case, need_camera):
    suffix, data = case
    with scratch() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = tmp / f"image{suffix}"
        path.write_bytes(data)
        _read_all(path, need_camera)


@pytest.mark.parametrize("name", list(NAMED))
def test_named_regressions_are_frames_or_input_errors(name):
    rng = np.random.default_rng(0)
    with scratch() as tmp:
        path = tmp / f"image{SUFFIX[name]}"
        path.write_bytes(NAMED[name](rng))
        frames = _read_all(path, need_camera=False)
    expect_refused = {"noise", "npz_as_npy", "two_page_tiff", "npy_4d"}
    assert (frames == []) == (name in expect_refused), name


@pytest.mark.parametrize("lie", LIES, ids=[f"{k}={v}" for k, v in LIES])
def test_every_dicom_lie_is_refused_or_harmless(lie):
    with scratch() as tmp:
        path = tmp / "lie.dcm"
        path.write_bytes(
            _dicom_file(np.random.default_rng(1), "enhanced-xa" if "Isocenter" in lie[0] else "xa", "explicit", lie)
        )
        _read_all(path, need_camera=True)
