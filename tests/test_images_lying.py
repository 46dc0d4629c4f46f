"""DICOM headers that lie: each is refused with an InputError naming the tag, before any
large allocation — never another exception, never a hang."""

from __future__ import annotations

import pydicom
import pytest
from images_support import CAM, stored

from ftrac_design.errors import InputError
from ftrac_design.images import frame_count, read_frames, write_dicom


def _file(tmp_path, **kw):
    return write_dicom(tmp_path / "a.dcm", stored(kw.pop("n", 2)), CAM, **kw)


def _edit(path, **values):
    ds = pydicom.dcmread(path)
    for k, v in values.items():
        setattr(ds, k, v)
    ds.save_as(path)
    return path


@pytest.mark.parametrize(
    "values,tag",
    [
        ({"Rows": 47}, r"NumberOfFrames \(0028,0008\) / Rows \(0028,0010\) / Columns \(0028,0011\)"),
        ({"Columns": 65}, r"Rows \(0028,0010\) / Columns"),
        ({"NumberOfFrames": 3}, r"NumberOfFrames \(0028,0008\)"),
        ({"NumberOfFrames": 0}, r"NumberOfFrames \(0028,0008\)"),
        ({"BitsStored": 17}, r"BitsStored \(0028,0101\)"),
        ({"HighBit": 10}, r"HighBit \(0028,0102\)"),
        ({"PhotometricInterpretation": "PALETTE COLOR"}, r"PhotometricInterpretation \(0028,0004\)"),
        ({"PhotometricInterpretation": "NONSENSE"}, r"PhotometricInterpretation \(0028,0004\)"),
        ({"ImagerPixelSpacing": [-0.3, 0.4]}, r"ImagerPixelSpacing \(0018,1164\)"),
        ({"ImagerPixelSpacing": [0, 0.4]}, r"ImagerPixelSpacing \(0018,1164\)"),
        ({"ImagerPixelSpacing": ["NaN", 0.4]}, r"ImagerPixelSpacing \(0018,1164\)"),
        ({"ImagerPixelSpacing": [0.3]}, r"ImagerPixelSpacing \(0018,1164\)"),
        ({"DistanceSourceToDetector": -5}, r"DistanceSourceToDetector \(0018,1110\)"),
        ({"DistanceSourceToDetector": 0}, r"DistanceSourceToDetector \(0018,1110\)"),
        ({"FieldOfViewRotation": 45, "FieldOfViewHorizontalFlip": "NO"}, r"FieldOfViewRotation \(0018,7032\)"),
        ({"FrameTimeVector": [0, 10, 20]}, r"FrameTimeVector \(0018,1065\)"),
        ({"PixelIntensityRelationshipSign": 2}, r"PixelIntensityRelationshipSign \(0028,1041\)"),
    ],
)
def test_a_lying_header_names_the_tag(tmp_path, values, tag):
    p = _edit(_file(tmp_path), **values)
    with pytest.raises(InputError, match=tag):
        list(read_frames(p))


def test_absurd_sizes_are_refused_before_allocating(tmp_path):
    p = _edit(_file(tmp_path), Rows=65535, Columns=65535, NumberOfFrames=1000000)
    with pytest.raises(InputError, match=r"Rows \(0028,0010\) × Columns \(0028,0011\).*at most 16777216 pixels"):
        frame_count(p)
    # a real-sized run is fine: 1024² × 500 frames passes the header checks (frames are decoded lazily)
    ds = pydicom.dcmread(_file(tmp_path))
    ds.Rows = ds.Columns = 1024
    ds.NumberOfFrames = 500
    ds.PixelData = b""
    ds.save_as(tmp_path / "big.dcm")
    with pytest.raises(InputError, match="pixel data holds 0 bytes"):  # only the data's length lies
        frame_count(tmp_path / "big.dcm")


def test_a_wrong_vr_string_names_the_tag(tmp_path):
    p = write_dicom(tmp_path / "a.dcm", stored(), CAM.__class__(1234.5, CAM.pixel_size_mm, CAM.principal_point_px))
    data = p.read_bytes()
    assert data.count(b"1234.5") == 1
    p.write_bytes(data.replace(b"1234.5", b"abc   "))
    with pytest.raises(InputError, match=r"DistanceSourceToDetector \(0018,1110\)"):
        list(read_frames(p))


def test_unknown_transfer_syntax_and_a_missing_pixel_data_element(tmp_path):
    p = _file(tmp_path)
    ds = pydicom.dcmread(p)
    del ds.PixelData
    ds.save_as(tmp_path / "b.dcm")
    with pytest.raises(InputError, match=r"PixelData \(7FE0,0010\)"):
        list(read_frames(tmp_path / "b.dcm"))
    ds = pydicom.dcmread(p)
    ds.file_meta.TransferSyntaxUID = "1.2.3.4"
    ds.save_as(tmp_path / "c.dcm", enforce_file_format=False)
    with pytest.raises(InputError):
        list(read_frames(tmp_path / "c.dcm"))


def test_cut_pixel_data_of_a_compressed_file_is_an_input_error(tmp_path):
    p = write_dicom(tmp_path / "a.dcm", stored(2), CAM, transfer_syntax="rle")
    data = p.read_bytes()
    p.write_bytes(data[: len(data) - 300])
    with pytest.raises(InputError):
        list(read_frames(p))
