"""Fuzzing image files given to ``ftrac-design track`` (in this process): small PNG, TIFF,
NumPy and DICOM images — noise, constant, NaN/inf, every dtype, 0-D to 4-D shapes — written
by the standard libraries and then truncated, bit-flipped or emptied, and headers that
claim huge dimensions (50,000² pixels) over a few bytes of data.

Property: exit 0, 1 or 2; exit 2 names the file in one to three lines and writes nothing;
no traceback; nothing half-written (the pose, the observation and overlays are written
atomically). Counts: ``fuzz_support.CASES["image_track"]``.
"""

from __future__ import annotations

import io
import json
import struct
import zlib

import numpy as np
from fuzz_support import assert_clean, cases, damage, run_cli, scratch
from hypothesis import given
from hypothesis import strategies as st
from test_fuzz_observation import CAMERA, FEATURE_FILES

DTYPES = ["uint8", "uint16", "int16", "int32", "int64", "float32", "float64", "bool", "complex64", "float16"]


def _array(kind: str, dtype: str, shape: tuple, rng: np.random.Generator) -> np.ndarray:
    if kind == "noise":
        a = rng.uniform(0, 255, shape)
    elif kind == "constant":
        a = np.full(shape, 7.0)
    elif kind == "nan":
        a = rng.uniform(0, 255, shape)
        if a.size:
            a.flat[rng.integers(a.size)] = np.nan
    elif kind == "inf":
        a = rng.uniform(0, 255, shape)
        if a.size:
            a.flat[rng.integers(a.size)] = np.inf
    else:  # "huge"
        a = np.full(shape, 1e300)
    with np.errstate(all="ignore"):
        return a.astype(dtype)


def _png_bytes(a: np.ndarray) -> bytes:
    from PIL import Image

    a = np.nan_to_num(a.real if np.iscomplexobj(a) else a).astype(np.uint8 if a.dtype != np.uint16 else np.uint16)
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG")
    return buf.getvalue()


def _png_huge_header(w: int, h: int) -> bytes:
    def chunk(t: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + t + data + struct.pack(">I", zlib.crc32(t + data) & 0xFFFFFFFF)

    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(b"\x00" * 64))
        + chunk(b"IEND", b"")
    )


def _tiff_bytes(a: np.ndarray) -> bytes:
    import tifffile

    buf = io.BytesIO()
    tifffile.imwrite(buf, a)
    return buf.getvalue()


def _npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def _npy_huge_header() -> bytes:
    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (50000, 50000), }"
    header += " " * (118 - len(header)) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + b"\x00" * 64


def _dicom_bytes(a: np.ndarray, rows: int | None = None, spacing=(0.44, 0.44), sdd=1000.0) -> bytes:
    import pydicom
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian

    a = np.nan_to_num(a.real if np.iscomplexobj(a) else a)
    a = np.atleast_2d(a)
    if a.ndim > 2:
        a = a.reshape(a.shape[0], -1)
    a = np.clip(a, 0, 65535).astype(np.uint16)
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.12.1"
    # a fixed UID: the file's length must not vary between runs (Hypothesis draws a cut within it)
    meta.MediaStorageSOPInstanceUID = "1.2.826.0.1.3680043.8.498.1"
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset(None, {}, file_meta=meta, preamble=b"\0" * 128)
    ds.Rows, ds.Columns = (rows if rows is not None else a.shape[0]), a.shape[1]
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 0
    ds.ImagerPixelSpacing = list(spacing)
    ds.DistanceSourceToDetector = sdd
    ds.PixelData = a.tobytes()
    buf = io.BytesIO()
    pydicom.dcmwrite(buf, ds, enforce_file_format=True)
    return buf.getvalue()


@st.composite
def image_files(draw) -> tuple[str, bytes, list[str]]:
    fmt = draw(st.sampled_from(["png", "tif", "npy", "dcm"]))
    kind = draw(st.sampled_from(["noise", "constant", "nan", "inf", "huge"]))
    dtype = draw(st.sampled_from(DTYPES))
    shape = draw(
        st.sampled_from(
            [
                (48, 64),
                (64, 48),
                (2, 2),
                (1, 40),
                (40, 1),
                (0, 5),
                (),
                (7,),
                (24, 24, 3),
                (24, 24, 4),
                (24, 24, 2),
                (3, 16, 16),
                (2, 2, 8, 8),
            ]
        )
    )
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    a = _array(kind, dtype, shape, rng)
    done = [fmt, kind, dtype, str(shape)]
    special = draw(st.sampled_from(["none"] * 6 + ["huge_header", "empty", "dicom_bad_camera"]))
    if special == "empty":
        return fmt, b"", done + ["empty"]
    if special == "huge_header" and fmt in ("png", "npy", "dcm"):
        data = {
            "png": lambda: _png_huge_header(50000, 50000),
            "npy": _npy_huge_header,
            "dcm": lambda: _dicom_bytes(np.zeros((4, 4)), rows=50000),
        }[fmt]()
        return fmt, data, done + ["huge header"]
    try:
        if fmt == "png":
            data = _png_bytes(a)
        elif fmt == "tif":
            data = _tiff_bytes(a)
        elif fmt == "npy":
            data = _npy_bytes(a)
        else:
            cam = (
                draw(
                    st.sampled_from(
                        [((0.44, 0.44), 1000.0), ((0.0, 0.44), 1000.0), ((0.44, 0.44), -5.0), ((1e300, 1e300), 1e300)]
                    )
                )
                if special == "dicom_bad_camera"
                else ((0.44, 0.44), 1000.0)
            )
            data = _dicom_bytes(a, spacing=cam[0], sdd=cam[1])
    except Exception:  # the writer refuses (e.g. a PNG of 4-D data): write a valid 2-D one instead
        data = {"png": _png_bytes, "tif": _tiff_bytes, "npy": _npy_bytes, "dcm": _dicom_bytes}[fmt](
            np.zeros((32, 32), np.uint8)
        )
        done.append("writer refused; zeros")
    cut, data = damage(draw, data)
    return fmt, data, done + [cut]


@cases("image_track")
@given(case=image_files(), with_camera=st.booleans())
def test_fuzz_track_image_files(case, with_camera):
    fmt, data, done = case
    with scratch() as tmp:
        img = tmp / f"image.{fmt}"
        img.write_bytes(data)
        out = tmp / "out" / "pose.json"
        args = ["track", "--features", FEATURE_FILES["ftrac_2005"], img, "-o", out]
        if with_camera:
            cam = tmp / "camera.json"
            cam.write_text(json.dumps(CAMERA.to_dict()))
            args += ["--camera", cam]
        run = run_cli(args)
        assert_clean(run, [img, tmp / "camera.json"], tmp)
        if run.code == 2:
            assert not out.exists(), run.describe()
        elif out.exists():
            # a multi-page TIFF or an (n, H, W) array is a run: one pose per frame, JSON Lines
            text = out.read_text()
            poses = [json.loads(text)] if text.startswith("{\n") else [json.loads(x) for x in text.splitlines()]
            assert all(p["converged"] for p in poses) == (run.code == 0), run.describe()
            assert all(p["converged"] or p.get("error") for p in poses), run.describe()


# ------------------------------------------------------- a real radiograph, damaged
_RG: dict = {}


def _radiograph() -> np.ndarray:
    """One simulated 384 × 384 radiograph of ftrac_2005 (log image, dense = bright)."""
    if "img" not in _RG:
        import tempfile
        from pathlib import Path

        d = Path(tempfile.mkdtemp(prefix="ftrac-fuzz-rg-"))
        (d / "cam.json").write_text(
            json.dumps({"focal_length_mm": 1000.0, "pixel_size_mm": [0.44, 0.44], "principal_point_px": [192.0, 192.0]})
        )
        run = run_cli(
            [
                "radiograph",
                "--features",
                FEATURE_FILES["ftrac_2005"],
                "--workspace-sample",
                "1",
                "--seed",
                "3",
                "-o",
                d / "rg",
                "--format",
                "npy",
                "--image-size",
                "384",
                "384",
                "--camera",
                d / "cam.json",
            ]
        )
        assert run.code == 0, run.describe()
        _RG["img"] = np.load(d / "rg" / "img_0000.npy")
        _RG["cam"] = d / "cam.json"
    return _RG["img"]


DAMAGE = [
    "none",
    "nan_pixel",
    "inf_pixel",
    "huge_pixel",
    "to_uint8",
    "to_int64",
    "to_float16",
    "to_bool",
    "crop",
    "transpose",
    "rgb",
    "scale_huge",
    "scale_tiny",
    "negate",
    "constant",
    "stripe",
]


@cases("radiograph_track")
@given(damage=st.sampled_from(DAMAGE), fmt=st.sampled_from(["npy", "tif", "png"]), seed=st.integers(0, 2**16))
def test_fuzz_track_damaged_radiograph(damage, fmt, seed):
    a = _radiograph().copy()
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, a.shape[0]), rng.integers(0, a.shape[1])
    with np.errstate(all="ignore"):
        if damage == "nan_pixel":
            a[i, j] = np.nan
        elif damage == "inf_pixel":
            a[i, j] = np.inf
        elif damage == "huge_pixel":
            a[i, j] = 1e300
        elif damage == "to_uint8":
            a = (255 * (a - a.min()) / np.ptp(a)).astype(np.uint8)
        elif damage == "to_int64":
            a = (a * 1e6).astype(np.int64)
        elif damage == "to_float16":
            a = a.astype(np.float16)
        elif damage == "to_bool":
            a = a > np.median(a)
        elif damage == "crop":
            a = a[: a.shape[0] // 2, :]
        elif damage == "transpose":
            a = a.T.copy()
        elif damage == "rgb":
            a = np.repeat(a[..., None], 3, axis=2)
        elif damage == "scale_huge":
            a = a * 1e300
        elif damage == "scale_tiny":
            a = a * 1e-300
        elif damage == "negate":
            a = -a
        elif damage == "constant":
            a[:] = 1.0
        elif damage == "stripe":
            a[:, j : j + 20] = a.max()
    with scratch() as tmp:
        img = tmp / f"image.{fmt}"
        try:
            data = {"npy": _npy_bytes, "tif": _tiff_bytes, "png": _png_bytes}[fmt](a)
        except Exception:  # e.g. PNG of float16: fall back to .npy
            img, data = tmp / "image.npy", _npy_bytes(a)
        img.write_bytes(data)
        out = tmp / "out" / "pose.json"
        run = run_cli(["track", "--features", FEATURE_FILES["ftrac_2005"], img, "--camera", _RG["cam"], "-o", out])
        assert_clean(run, [img], tmp)
        if run.code == 2:
            assert not out.exists(), run.describe()
        else:
            pose = json.loads(out.read_text())
            assert pose["converged"] == (run.code == 0), run.describe()
