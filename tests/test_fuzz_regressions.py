"""Crashes the fuzz tests found (and one a user reported), each kept as a named
regression test: the boundary refuses the input with exit 2 and one line, and the numerical
core, given the same numbers without the boundary, refuses instead of raising."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from fuzz_support import assert_clean, run_cli, scratch
from test_fuzz_observation import BASE, FEATURE_FILES, FEATURES

from ftrac_design.errors import InputError
from ftrac_design.pose import observation_from_dict, so3, solve_pose


def _solve_cli(doc: dict, preset: str = "ftrac_2005"):
    with scratch() as tmp:
        src, out = tmp / "obs.json", tmp / "pose.json"
        src.write_text(json.dumps(doc), encoding="utf-8")
        run = run_cli(["solve", "--features", FEATURE_FILES[preset], src, "-o", out])
        assert_clean(run, [src], tmp)
        return run, out.exists()


def test_bead_at_1e300_pixels_exits_2_not_linalgerror():
    """A bead at 1e300 px: one line naming the key, not `numpy.linalg.LinAlgError: Eigenvalues did not
    converge`."""
    doc = json.loads(json.dumps(BASE[("ftrac_2005", 0, False)]))
    doc["points"]["B1"] = [1e300, 506.651]
    run, wrote = _solve_cli(doc)
    assert run.code == 2 and not wrote
    assert "points.B1" in run.err and "within" in run.err


@pytest.mark.parametrize("value", [1e300, 1e200, 1e150, 1e20])
def test_solver_refuses_absurd_coordinates_that_bypass_validation(value):
    """The core, given an Observation built in code (no file check): a pose with
    ``converged=False`` and an error, never an exception (1e300/1e200: LinAlgError in the DLT;
    1e150: ValueError: math domain error in so3.exp)."""
    obs = observation_from_dict(BASE[("ftrac_2005", 0, False)], "built in code")
    obs.points["B1"] = np.array([value, 5.0])
    with np.errstate(all="ignore"):
        pose = solve_pose(FEATURES["ftrac_2005"], obs)
    assert not pose.converged and pose.error
    d = pose.to_dict()
    assert d["converged"] is False and d["error"]


def test_so3_exp_of_an_infinite_rotation_vector_is_nan_not_valueerror():
    for v in ([math.inf, 0.0, 0.0], [1e200, 1e200, 0.0]):
        R = so3.exp(np.array([v]))
        assert R.shape == (1, 3, 3) and np.isnan(R).all()
        assert np.isnan(so3.exp(np.array([v, v]))).any()  # the batched path, for comparison


def test_features_point_line_that_is_not_a_string_exits_2():
    """features.json `points[i].line = [..]` raised TypeError: unhashable type: 'list'."""
    from ftrac_design.features import features_to_dict

    doc = json.loads(json.dumps(features_to_dict(FEATURES["ftrac_2005"])))
    doc["points"][0]["line"] = ["L1"]
    with scratch() as tmp:
        feats, obs = tmp / "features.json", tmp / "obs.json"
        feats.write_text(json.dumps(doc))
        obs.write_text(json.dumps(BASE[("ftrac_2005", 0, False)]))
        run = run_cli(["solve", "--features", feats, obs, "-o", tmp / "p.json"])
        assert_clean(run, [feats], tmp)
        assert run.code == 2 and "points[0].line" in run.err


# degenerate curves: refused at the boundary with the key named
CURVES = [
    ("no real points", "ellipses", "E1", {"conic": [1, 0, 1, 0, 0, 1]}, "real points"),
    ("a single point", "ellipses", "E1", {"conic": [1, 0, 1, 0, 0, 0]}, "real points"),
    ("semi-axis 1e15 px", "ellipses", "E1", {"conic": [1, 0, 1e-30, 0, 0, -1]}, "within"),
    ("overflowing coefficients", "ellipses", "E1", {"conic": [1e308, 0, 1e308, 0, 0, 1e308]}, "real points"),
    ("all zero", "ellipses", "E1", {"conic": [0, 0, 0, 0, 0, 0]}, "not all zero"),
    ("line at infinity", "lines", "L1", {"coefficients": [1e-300, 0, 5]}, "passing within"),
    ("line 1e300 px away", "lines", "L1", {"coefficients": [1, 0, -1e300]}, "within"),
    ("contour point at 1e300", "lines", "L1", {"points": [[0, 0], [1, 1e300], [2, 2]]}, "within"),
]


@pytest.mark.parametrize("case,section,key,value,expected", CURVES, ids=[c[0] for c in CURVES])
def test_degenerate_curves_exit_2(case, section, key, value, expected):
    doc = json.loads(json.dumps(BASE[("ftrac_2005", 0, True)]))
    doc[section][key] = value
    run, wrote = _solve_cli(doc)
    assert run.code == 2 and not wrote, run.describe()
    assert f"{section}.{key}" in run.err and expected in run.err, run.err


def test_valid_coefficients_are_scaled_not_changed():
    """Coefficients are stored scaled to max |c| = 1 (lines: |(A, B)| = 1): the same curve."""
    doc = json.loads(json.dumps(BASE[("ftrac_2005", 0, True)]))
    conic = np.array(doc["ellipses"]["E1"]["conic"])
    line = np.array(doc["lines"]["L1"]["coefficients"])
    doc["ellipses"]["E1"]["conic"] = (conic * 1e250).tolist()
    obs = observation_from_dict(doc)
    c = obs.ellipses["E1"].coefficients
    assert np.allclose(c / np.abs(c).max(), conic / np.abs(conic).max(), rtol=1e-12)
    ln = obs.lines["L1"].coefficients
    assert np.allclose(ln, line / np.hypot(*line[:2]), rtol=1e-12)
    assert solve_pose(FEATURES["ftrac_2005"], obs).converged


@pytest.mark.parametrize(
    "camera,key",
    [
        ({"focal_length_mm": 1e300, "pixel_size_mm": [0.44, 0.44], "principal_point_px": [512, 512]}, "camera"),
        ({"focal_length_mm": 1000, "pixel_size_mm": [1e-300, 0.44], "principal_point_px": [512, 512]}, "camera"),
        (
            {"focal_length_mm": 1000, "pixel_size_mm": [0.44, 0.44], "principal_point_px": [1e300, 512]},
            "camera.principal_point_px",
        ),
    ],
)
def test_absurd_camera_exits_2(camera, key):
    doc = json.loads(json.dumps(BASE[("ftrac_2005", 0, False)]))
    doc["camera"] = camera
    with pytest.raises(InputError, match=key.replace(".", r"\.")):
        observation_from_dict(doc, "obs.json")
    run, wrote = _solve_cli(doc)
    assert run.code == 2 and not wrote


def test_features_design_source_that_is_not_a_string_exits_2():
    """features.json `design.source = Infinity` reached analysis.json and raised
    ValueError: Out of range float values are not JSON compliant (found by the long profile)."""
    from ftrac_design.features import features_to_dict

    doc = json.loads(json.dumps(features_to_dict(FEATURES["ftrac_2005"])))
    doc["design"]["source"] = math.inf
    with scratch() as tmp:
        feats = tmp / "features.json"
        feats.write_text(json.dumps(doc))
        run = run_cli(
            [
                "analyze",
                feats,
                "-o",
                tmp / "a",
                "--poses",
                "100",
                "--no-plots",
                "--score-images",
                "0",
                "--image-atlas-step-deg",
                "0",
            ]
        )
        assert_clean(run, [feats], tmp)
        assert run.code == 2 and "design.source" in run.err and not (tmp / "a").exists()


def test_features_line_start_at_1e300_exits_2():
    """features.json `lines[2].start = [1e300, …]` crashed `analyze` with numpy.linalg.LinAlgError:
    Eigenvalues did not converge (found by the long profile)."""
    from ftrac_design.features import features_to_dict

    doc = json.loads(json.dumps(features_to_dict(FEATURES["ftrac_2005"])))
    doc["lines"][2]["start"][0] = 1e300
    with scratch() as tmp:
        feats = tmp / "features.json"
        feats.write_text(json.dumps(doc))
        run = run_cli(
            [
                "analyze",
                feats,
                "-o",
                tmp / "a",
                "--poses",
                "100",
                "--no-plots",
                "--score-images",
                "0",
                "--image-atlas-step-deg",
                "0",
            ]
        )
        assert_clean(run, [feats], tmp)
        assert run.code == 2 and "lines[2].start[0]" in run.err and not (tmp / "a").exists()


def test_swapped_neighbouring_wires_on_ftrac_mini_are_refused():
    """ftrac_mini with the contours of L2 and L3 swapped (their images ~2.4 px apart) came
    back converged, 7 mm off in depth, at noise scale 3.7 < 5 with residual p = 1e-30
    (found by the long profile); now refused by the misfit rule (κ > 3 and p < 1e-12)."""
    from test_fuzz_observation import _scramble, _simulated

    obs0, R, t = _simulated("ftrac_mini", 1, e_mm=0.25)
    scrambled = _scramble(obs0.to_dict(), "swap_curves", np.random.default_rng(1), "ftrac_mini")
    assert scrambled["lines"]["L2"] == obs0.to_dict()["lines"]["L3"]
    pose = solve_pose(FEATURES["ftrac_mini"], observation_from_dict(scrambled, "scrambled"))
    assert not pose.converged and "fit no single pose" in pose.error
    assert solve_pose(FEATURES["ftrac_mini"], obs0).converged  # the unscrambled image is solved


def test_png_header_claiming_50000_squared_pixels_exits_2():
    """A PNG whose header claims 50,000 × 50,000 pixels raised PIL.Image.DecompressionBombError
    out of `track` (found by tests/test_fuzz_image.py)."""
    from test_fuzz_image import _png_huge_header

    with scratch() as tmp:
        img = tmp / "bomb.png"
        img.write_bytes(_png_huge_header(50000, 50000))
        run = run_cli(["track", "--features", FEATURE_FILES["ftrac_2005"], img, "-o", tmp / "out" / "pose.json"])
        assert_clean(run, [img], tmp)
        assert run.code == 2 and "bomb.png" in run.err and not (tmp / "out" / "pose.json").exists()


# Crashes found in the segmentation (ftrac_design/segment) by the image fuzzing.
class SegmentCrash(Exception):
    """An exception escaped `track` (the last line of its traceback)."""


def _track(args: list, inputs: list, tmp) -> None:
    run = run_cli(args)
    if run.crash:
        raise SegmentCrash(run.crash.strip().splitlines()[-1])
    assert_clean(run, inputs, tmp)


def test_track_2x2_png_with_camera_exits_cleanly():
    """segment/beads.py fit_beads placed its ~31 px patch outside images smaller than it
    (IndexError on 2 × 2 and 3 × 256 images, found by tests/test_fuzz_image.py): an image
    narrower than one ball's patch now holds no ball, and track exits 1 (not found)."""
    from test_fuzz_image import _png_bytes
    from test_fuzz_observation import CAMERA

    for pixels in (np.array([[10, 200], [30, 90]], np.uint8), np.random.default_rng(0).integers(0, 255, (3, 256))):
        _track_tiny(_png_bytes(pixels.astype(np.uint8)), CAMERA)


def _track_tiny(png: bytes, camera) -> None:
    with scratch() as tmp:
        img, cam = tmp / "tiny.png", tmp / "camera.json"
        img.write_bytes(png)
        cam.write_text(json.dumps(camera.to_dict()))
        _track(
            ["track", "--features", FEATURE_FILES["ftrac_2005"], img, "--camera", cam, "-o", tmp / "out" / "pose.json"],
            [img],
            tmp,
        )


@pytest.mark.parametrize("suffix", [".npy", ".png", ".dcm", ".tif"])
def test_track_empty_image_file_exits_2_not_aborted(suffix):
    """An empty .npy made np.load raise EOFError, which click turns into "aborted", exit 130
    (found by the long profile of tests/test_fuzz_image.py)."""
    with scratch() as tmp:
        img = tmp / f"empty{suffix}"
        img.write_bytes(b"")
        run = run_cli(["track", "--features", FEATURE_FILES["ftrac_2005"], img, "-o", tmp / "out" / "pose.json"])
        assert_clean(run, [img], tmp)
        assert run.code == 2 and img.name in run.err


@pytest.mark.parametrize("value,codes", [(1e300, (2,)), (1e38, (0, 1))])
def test_track_radiograph_with_one_absurd_pixel(value, codes):
    """A simulated radiograph with one pixel of 1e300 crashed the bead fit (float32 inf →
    np.linalg.pinv: SVD did not converge; found by the ci profile of tests/test_fuzz_image.py
    as the segmentation changed). Values beyond float32 are refused when the image is read;
    a 1e38 pixel is read, and the image is either not solved or solved as without it (one
    pixel far from the fiducial changes nothing the tracker measures)."""
    from test_fuzz_image import _RG, _radiograph

    a = _radiograph().copy()
    rng = np.random.default_rng(0)
    a[rng.integers(0, a.shape[0]), rng.integers(0, a.shape[1])] = value
    with scratch() as tmp:
        img, plain = tmp / "image.npy", tmp / "plain.npy"
        np.save(img, a)
        np.save(plain, _radiograph())
        run = run_cli(
            [
                "track",
                "--features",
                FEATURE_FILES["ftrac_2005"],
                img,
                "--camera",
                _RG["cam"],
                "-o",
                tmp / "out" / "pose.json",
            ]
        )
        assert_clean(run, [img, plain], tmp)
        assert run.code in codes, run.describe()
        if run.code == 2:
            assert "pixels" in run.err and "float32" in run.err
        if run.code == 0:
            ref = run_cli(
                [
                    "track",
                    "--features",
                    FEATURE_FILES["ftrac_2005"],
                    plain,
                    "--camera",
                    _RG["cam"],
                    "-o",
                    tmp / "ref" / "pose.json",
                ]
            )
            assert ref.code == 0, ref.describe()
            got = json.loads((tmp / "out" / "pose.json").read_text())
            want = json.loads((tmp / "ref" / "pose.json").read_text())
            np.testing.assert_allclose(got["translation_mm"], want["translation_mm"], atol=0.05)
            np.testing.assert_allclose(got["rotation"], want["rotation"], atol=1e-3)


def test_track_npy_with_a_garbled_header_exits_2():
    """A .npy whose header dict is garbled made np.load raise tokenize.TokenError out of
    `track` (found by an exploratory run of tests/test_fuzz_image.py's generator)."""
    import io as _io

    buf = _io.BytesIO()
    np.save(buf, np.zeros((48, 64), np.uint8))
    data = buf.getvalue().replace(b"'shape': (", b"'shape':((", 1)
    with scratch() as tmp:
        img = tmp / "garbled.npy"
        img.write_bytes(data)
        run = run_cli(["track", "--features", FEATURE_FILES["ftrac_2005"], img, "-o", tmp / "out" / "pose.json"])
        assert_clean(run, [img], tmp)
        assert run.code == 2 and "garbled.npy" in run.err


def test_every_truncation_of_a_dicom_header_is_an_input_error():
    """A DICOM file cut inside its meta header raised pydicom's NotImplementedError (transfer
    syntax '1'), struct.error or BytesLengthException out of `track` (found by an exploratory
    run of tests/test_fuzz_image.py's generator). Every cut of the first 400 bytes is now an
    InputError naming the file, and `track` exits 2."""
    import warnings

    from test_fuzz_image import _dicom_bytes

    from ftrac_design.images import read_image

    data = _dicom_bytes(np.zeros((48, 64)))
    with scratch() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pydicom warns about the cut UIDs
        img = tmp / "cut.dcm"
        for cut in range(400):
            img.write_bytes(data[:cut])
            with pytest.raises(InputError, match="cut.dcm"):
                read_image(img)
        img.write_bytes(data[:276])  # transfer syntax UID "1"
        run = run_cli(["track", "--features", FEATURE_FILES["ftrac_2005"], img, "-o", tmp / "out" / "pose.json"])
        assert_clean(run, [img], tmp)
        assert run.code == 2
