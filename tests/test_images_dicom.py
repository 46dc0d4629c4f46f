"""DICOM intake by the standard (ftrac_design.images): each case is written with the
test-data writer and read back — pixels equal to the detector-grid array written (exactly:
every syntax here is lossless), camera, formation and polarity as written."""

from __future__ import annotations

import numpy as np
import pydicom
import pytest
from images_support import CAM, stored

from ftrac_design.errors import InputError
from ftrac_design.images import frame_count, read_frame, read_frames, write_dicom
from ftrac_design.pose import Camera


def _one(path, **kw):
    frames = list(read_frames(path, **kw))
    assert len(frames) == 1
    return frames[0]


@pytest.mark.parametrize("kind", ["xa", "rf", "dx", "cr", "enhanced-xa", "enhanced-xrf"])
def test_every_kind_round_trips_pixels_and_camera(tmp_path, kind):
    a = stored()
    p = write_dicom(
        tmp_path / "a.dcm",
        a,
        CAM,
        kind=kind,
        relationship="LIN",
        relationship_sign=1,
        isocenter_projection_px=CAM.principal_point_px,
        bits_stored=12,
    )
    f = _one(p)
    assert f.pixels.dtype == np.float32 and np.array_equal(f.pixels, a[0])
    assert f.camera == CAM
    assert f.camera_source == {
        "focal_length": "DistanceSourceToDetector (0018,1110)",
        "pixel_size": "ImagerPixelSpacing (0018,1164)",
        "principal_point": "PositionOfIsocenterProjection (0018,9430)",
    }
    assert (f.formation, f.polarity) == ("linear", "dense-dark")
    assert f.meta["enhanced"] == kind.startswith("enhanced") and f.meta["bits"] == 12


def test_enhanced_geometry_lives_in_functional_groups_not_at_the_top(tmp_path):
    p = write_dicom(tmp_path / "a.dcm", stored(2), CAM, kind="enhanced-xa", relationship="LOG", relationship_sign=-1)
    ds = pydicom.dcmread(p)
    assert "DistanceSourceToDetector" not in ds and "ImagerPixelSpacing" not in ds
    f = list(read_frames(p))
    assert [x.camera.pixel_size_mm for x in f] == [CAM.pixel_size_mm] * 2
    assert (f[1].formation, f[1].polarity) == ("log", "dense-bright")


def test_enhanced_per_frame_geometry_gives_each_frame_its_camera(tmp_path):
    cams = [Camera(1000.0 + 50 * k, (round(0.2 + 0.01 * k, 6), 0.25), (31.5, 23.5)) for k in range(3)]
    p = write_dicom(tmp_path / "a.dcm", stored(3), cams, kind="enhanced-xrf")
    got = [f.camera for f in read_frames(p)]
    assert got == cams and len(set(got)) == 3
    assert read_frame(p, 2).camera == cams[2]


@pytest.mark.parametrize("relationship", ["LIN", "LOG", "DISP", None])
@pytest.mark.parametrize("sign", [1, -1, None])
def test_relationship_and_sign_give_formation_and_polarity(tmp_path, relationship, sign):
    p = write_dicom(tmp_path / "a.dcm", stored(), CAM, kind="xa", relationship=relationship, relationship_sign=sign)
    f = _one(p)
    assert f.formation == {"LIN": "linear", "LOG": "log", "DISP": "display", None: None}[relationship]
    # the sign speaks for the stored values (PS3.3 C.8.11.3.1.2); LIN alone means ∝ intensity
    expect = {1: "dense-dark", -1: "dense-bright"}.get(sign, "dense-dark" if relationship == "LIN" else None)
    assert f.polarity == expect


def test_monochrome1_keeps_values_and_the_sign_decides(tmp_path):
    a = stored()
    p = write_dicom(
        tmp_path / "a.dcm", a, CAM, kind="dx", photometric="MONOCHROME1", relationship="LOG", relationship_sign=-1
    )
    f = _one(p)
    assert np.array_equal(f.pixels, a[0]) and f.polarity == "dense-bright"
    assert any("MONOCHROME1" in n for n in f.notes)


@pytest.mark.parametrize("rotation", [0, 90, 180, 270])
@pytest.mark.parametrize("flip", [False, True])
@pytest.mark.parametrize("kind", ["dx", "enhanced-xa"])
def test_field_of_view_rotation_and_flip_are_undone(tmp_path, rotation, flip, kind):
    a = stored(shape=(40, 56))
    p = write_dicom(
        tmp_path / "a.dcm",
        a,
        CAM,
        kind=kind,
        fov_rotation_deg=rotation,
        fov_horizontal_flip=flip,
        isocenter_projection_px=CAM.principal_point_px,
    )
    ds = pydicom.dcmread(p)
    assert (ds.Rows, ds.Columns) == ((56, 40) if rotation in (90, 270) else (40, 56))
    if rotation or flip:
        assert not np.array_equal(ds.pixel_array, a[0])  # stored differently …
    f = _one(p)
    assert np.array_equal(f.pixels, a[0])  # … read back on the detector grid
    assert f.camera == CAM  # same pitch axes, same principal point


def test_rotated_file_without_isocenter_uses_the_detector_grid_centre(tmp_path):
    p = write_dicom(tmp_path / "a.dcm", stored(shape=(40, 56)), CAM, kind="dx", fov_rotation_deg=90)
    f = _one(p)
    assert f.camera.principal_point_px == (27.5, 19.5) and f.camera_source["principal_point"] == "image centre"


def test_frame_time_and_frame_time_vector_give_times(tmp_path):
    a = stored(4)
    f = list(read_frames(write_dicom(tmp_path / "t.dcm", a, CAM, frame_time_ms=40.0)))
    assert [x.time_s for x in f] == pytest.approx([0.0, 0.04, 0.08, 0.12])
    assert [x.index for x in f] == [0, 1, 2, 3] and all(np.array_equal(x.pixels, a[i]) for i, x in enumerate(f))
    f = list(read_frames(write_dicom(tmp_path / "v.dcm", a, CAM, frame_time_vector_ms=[0, 30, 50, 20])))
    assert [x.time_s for x in f] == pytest.approx([0.0, 0.03, 0.08, 0.10])
    f = list(
        read_frames(write_dicom(tmp_path / "e.dcm", a, CAM, kind="enhanced-xa", frame_time_vector_ms=[0, 30, 50, 20]))
    )
    assert [x.time_s for x in f] == pytest.approx([0.0, 0.03, 0.08, 0.10])  # Frame Content DateTimes
    assert [x.time_s for x in read_frames(write_dicom(tmp_path / "n.dcm", a, CAM))] == [None] * 4
    assert frame_count(tmp_path / "t.dcm") == 4


@pytest.mark.parametrize("syntax", ["rle", "jpeg-lossless", "jpeg2000-lossless"])
@pytest.mark.parametrize("kind", ["xa", "enhanced-xa"])
def test_compressed_syntaxes_decode_exactly(tmp_path, syntax, kind):
    if syntax == "jpeg-lossless":
        pytest.importorskip("imagecodecs", reason="the writer encodes JPEG Lossless with imagecodecs")
        pytest.importorskip("libjpeg", reason="pylibjpeg-libjpeg decodes JPEG Lossless")
    if syntax == "jpeg2000-lossless":
        pytest.importorskip("openjpeg", reason="pylibjpeg-openjpeg encodes and decodes JPEG 2000")
    a = stored(3, shape=(64, 80))
    p = write_dicom(
        tmp_path / "a.dcm", a, CAM, kind=kind, transfer_syntax=syntax, fov_rotation_deg=90, fov_horizontal_flip=True
    )
    f = list(read_frames(p))
    assert pydicom.dcmread(p, stop_before_pixels=True).file_meta.TransferSyntaxUID.is_compressed
    assert all(np.array_equal(x.pixels, a[i]) for i, x in enumerate(f))
    assert np.array_equal(read_frame(p, 1).pixels, a[1])


def test_a_missing_codec_names_the_transfer_syntax_and_the_package(tmp_path, monkeypatch):
    p = write_dicom(tmp_path / "a.dcm", stored(), CAM, transfer_syntax="rle")
    import pydicom.pixels

    monkeypatch.setattr(pydicom.pixels, "get_decoder", lambda uid: (_ for _ in ()).throw(NotImplementedError()))
    with pytest.raises(InputError, match=r"1\.2\.840\.10008\.1\.2\.5 \(RLE Lossless\)"):
        list(read_frames(p))


def test_missing_geometry_names_the_tags_and_the_ways_out(tmp_path):
    p = write_dicom(
        tmp_path / "a.dcm", stored(), CAM, kind="xa", omit=("DistanceSourceToDetector", "ImagerPixelSpacing")
    )
    with pytest.raises(
        InputError,
        match=r"DistanceSourceToDetector \(0018,1110\), ImagerPixelSpacing \(0018,1164\).*"
        r"--camera C\.json.*fiducial",
    ):
        list(read_frames(p))
    assert _one(p, need_camera=False).camera is None
    f = _one(p, camera=Camera(900.0))
    assert f.camera == Camera(900.0) and set(f.camera_source.values()) == {"--camera"}
    p = write_dicom(tmp_path / "b.dcm", stored(), CAM, kind="enhanced-xa", omit=("DistanceSourceToDetector",))
    with pytest.raises(InputError, match=r"b\.dcm: DistanceSourceToDetector \(0018,1110\):"):
        list(read_frames(p))


@pytest.mark.parametrize("kind", ["cr", "enhanced-xa"])
def test_pixel_spacing_and_its_calibration_type(tmp_path, kind):
    a = stored()
    # no calibration type: taken as the detector pitch
    f = _one(write_dicom(tmp_path / "a.dcm", a, CAM, kind=kind, pixel_spacing_only=True, calibration=None))
    assert (
        f.camera.pixel_size_mm == pytest.approx(CAM.pixel_size_mm) and "PixelSpacing" in f.camera_source["pixel_size"]
    )
    # calibrated to the object plane: × the magnification factor back to the detector
    f = _one(
        write_dicom(
            tmp_path / "b.dcm", a, CAM, kind=kind, pixel_spacing_only=True, calibration="GEOMETRY", magnification=1.5
        )
    )
    assert f.camera.pixel_size_mm == pytest.approx(CAM.pixel_size_mm)
    assert "EstimatedRadiographicMagnificationFactor" in f.camera_source["pixel_size"]
    # calibrated (FIDUCIAL) with no factor: not a pitch → the spacing is missing
    p = write_dicom(tmp_path / "c.dcm", a, CAM, kind=kind, pixel_spacing_only=True, calibration="FIDUCIAL")
    with pytest.raises(InputError, match=r"ImagerPixelSpacing \(0018,1164\)"):
        list(read_frames(p))
    f = _one(p, need_camera=False)
    assert f.camera is None and any("calibrated to another plane" in n for n in f.notes)


def test_isocenter_projection_maps_through_binning_and_field_of_view_origin(tmp_path):
    p = write_dicom(tmp_path / "a.dcm", stored(shape=(40, 50)), CAM, kind="enhanced-xa")
    ds = pydicom.dcmread(p)
    ds.PositionOfIsocenterProjection = [101.0, 61.0]  # (row, column) in detector elements
    ds.DetectorElementSpacing = [0.2, 0.15]  # 2 × 2 binning of CAM's pitch
    ds.SharedFunctionalGroupsSequence[0].FieldOfViewSequence[0].FieldOfViewOrigin = [20, 10]
    ds.save_as(p)
    f = _one(p)
    # column: (61 + 0.5 − 10) / 2 − 0.5 = 25.25; row: (101 + 0.5 − 20) / 2 − 0.5 = 40.25
    assert f.camera.principal_point_px == pytest.approx((25.25, 40.25))


def test_signed_12_bit_pixels_with_garbage_above_bits_stored(tmp_path):
    a = stored(signed=True, bits=12)
    p = write_dicom(tmp_path / "a.dcm", a, CAM, signed=True, bits_stored=12)
    ds = pydicom.dcmread(p)
    raw = np.frombuffer(ds.PixelData, np.uint16).copy()
    raw = (raw & 0x0FFF) | 0xA000  # overlay-like junk in bits 12–15
    ds.PixelData = raw.tobytes()
    ds.save_as(p)
    assert np.array_equal(_one(p).pixels, a[0])


def test_modality_lut_and_rescale_give_modality_values(tmp_path):
    a = stored(bits=8)
    lut = (4000 - 7 * np.arange(256)).astype(np.uint16)  # a decreasing LUT
    f = _one(
        write_dicom(
            tmp_path / "l.dcm", a, CAM, bits_stored=8, modality_lut=lut, relationship="LIN", relationship_sign=1
        )
    )
    assert np.array_equal(f.pixels, lut[a[0]]) and f.polarity == "dense-bright"
    f = _one(
        write_dicom(
            tmp_path / "r.dcm",
            a,
            CAM,
            kind="enhanced-xa",
            rescale=(-0.5, 100.0),
            relationship="LIN",
            relationship_sign=-1,
        )
    )
    assert np.array_equal(f.pixels, a[0] * -0.5 + 100.0) and f.polarity == "dense-dark"


def test_a_grabbers_rgb_dicom_becomes_grey(tmp_path):
    rgb = np.random.default_rng(3).integers(0, 256, (30, 40, 3)).astype(np.uint8)
    f = _one(write_dicom(tmp_path / "a.dcm", rgb, CAM, photometric="RGB"))
    np.testing.assert_allclose(f.pixels, rgb @ np.array([0.2126, 0.7152, 0.0722]), rtol=1e-6)
    assert any("grey" in n for n in f.notes)


def test_read_frame_decodes_only_what_it_is_asked(tmp_path):
    a = stored(5)
    p = write_dicom(tmp_path / "a.dcm", a, CAM, frame_time_ms=10.0)
    f = read_frame(p, 3)
    assert f.index == 3 and f.time_s == pytest.approx(0.03) and np.array_equal(f.pixels, a[3])
    with pytest.raises(InputError, match="frame"):
        read_frame(p, 5)
