"""``ftrac-design track`` on images as C-arms hand them over: every DICOM case of the intake
room gives the pose of the same pixels in a plain NumPy file; runs (multi-frame DICOM,
multi-page TIFF, a directory of PNGs) give one pose per frame in order; bad input anywhere
exits 2 before anything is tracked; a frame whose tracking raises never loses the batch;
``--distortion`` undoes an intensifier's distortion.

One 384 × 384 radiograph of ftrac_2005 (principal point at the centre) is rendered once;
each tracked frame costs ~0.1 s.
"""

from __future__ import annotations

import gc
import io
import json
import sys
import weakref
from pathlib import Path

import numpy as np
import pytest
from test_fuzz_observation import FEATURE_FILES, FEATURES

from ftrac_design.cli.main import main
from ftrac_design.images import distort_image, write_dicom, write_distortion, write_image
from ftrac_design.images.distortion import radial
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.tracking import run_tracker
from ftrac_design.workflows import track_run
from ftrac_design.xray import ImagingModel, render

SHAPE = (384, 384)
#: the principal point where DICOM intake puts it without a tag: the image centre
CAM = Camera(1000.0, (0.44, 0.44), ((SHAPE[1] - 1) / 2, (SHAPE[0] - 1) / 2))
FEATS = str(FEATURE_FILES["ftrac_2005"])


@pytest.fixture(scope="module")
def scene():
    """The true pose, the raw counts (uint16, dense = dark) and the log image quantised to
    uint16 (dense = bright) of one rendered radiograph."""
    features = FEATURES["ftrac_2005"]
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(0))
    rad = render(
        features,
        R[0],
        t[0],
        CAM,
        ImagingModel(image_shape=SHAPE),
        rng=np.random.default_rng(0),
    )
    counts = np.asarray(rad.raw, np.uint16)
    log = np.rint((rad.log_image + 0.1) * 20000.0).astype(np.uint16)
    assert log.min() > 0 and log.max() < 65535  # the quantisation kept every value
    return {"R": R[0], "t": t[0], "counts": counts, "log": log}


@pytest.fixture(scope="module")
def camera_json(tmp_path_factory):
    p = tmp_path_factory.mktemp("cam") / "camera.json"
    p.write_text(json.dumps(CAM.to_dict()))
    return p


def _run(args, capsys):
    rc = main([str(a) for a in args])
    out = capsys.readouterr()
    return rc, out.out, out.err


def _poses(path: Path) -> list[dict]:
    text = path.read_text()
    return [json.loads(x) for x in text.splitlines()] if path.suffix == ".jsonl" else [json.loads(text)]


_REFERENCE: dict = {}


@pytest.fixture(scope="module")
def reference(scene, camera_json, tmp_path_factory):
    """The pose tracked from a plain .npy of the same pixels with --camera (and the
    polarity the DICOM file states, as --polarity), per (pixels, polarity)."""

    def get(pixels: str, polarity: str) -> dict:
        if (pixels, polarity) not in _REFERENCE:
            d = tmp_path_factory.mktemp("ref")
            np.save(d / f"{pixels}.npy", scene[pixels])
            rc = main(
                [
                    "track",
                    "--features",
                    FEATS,
                    str(d / f"{pixels}.npy"),
                    "--camera",
                    str(camera_json),
                    "--polarity",
                    polarity,
                    "-o",
                    str(d / "pose.json"),
                ]
            )
            assert rc == 0
            (_REFERENCE[(pixels, polarity)],) = _poses(d / "pose.json")
        return _REFERENCE[(pixels, polarity)]

    return get


def _codec(*modules: str) -> list:
    missing = []
    for m in modules:
        try:
            __import__(m)
        except ImportError:
            missing.append(m)
    return [pytest.mark.skip(reason=f"codec not installed: {', '.join(missing)}")] if missing else []


# (pixels, polarity the file states, write_dicom arguments)
DICOM_CASES = {
    "legacy-xa": ("counts", "auto", {"kind": "xa"}),
    "xa-lin": ("counts", "dense-dark", {"kind": "xa", "relationship": "LIN"}),
    "rf": ("counts", "auto", {"kind": "rf", "frame_time_ms": 100.0}),
    "dx-monochrome1": (
        "counts",
        "dense-dark",
        {"kind": "dx", "photometric": "MONOCHROME1", "relationship": "LIN", "relationship_sign": 1},
    ),
    "cr": ("counts", "auto", {"kind": "cr"}),
    "enhanced-xa": ("counts", "dense-dark", {"kind": "enhanced-xa", "relationship": "LIN", "relationship_sign": 1}),
    "enhanced-xrf": ("counts", "dense-dark", {"kind": "enhanced-xrf", "relationship": "LIN"}),
    "xa-log": ("log", "dense-bright", {"kind": "xa", "relationship": "LOG", "relationship_sign": -1}),
    "enhanced-xa-log": ("log", "dense-bright", {"kind": "enhanced-xa", "relationship": "LOG", "relationship_sign": -1}),
    "rotated-90-flipped": ("counts", "auto", {"kind": "xa", "fov_rotation_deg": 90, "fov_horizontal_flip": True}),
    "enhanced-rotated-flipped": (
        "counts",
        "dense-dark",
        {"kind": "enhanced-xa", "relationship": "LIN", "fov_rotation_deg": 90, "fov_horizontal_flip": True},
    ),
    "rle": ("counts", "auto", {"kind": "xa", "transfer_syntax": "rle"}),
    "jpeg-lossless": ("counts", "auto", {"kind": "xa", "transfer_syntax": "jpeg-lossless"}),
    "jpeg2000-lossless": ("counts", "auto", {"kind": "xa", "transfer_syntax": "jpeg2000-lossless"}),
}
_MARKS = {"jpeg-lossless": _codec("imagecodecs", "libjpeg"), "jpeg2000-lossless": _codec("openjpeg")}


@pytest.mark.parametrize("case", [pytest.param(k, marks=_MARKS.get(k, [])) for k in DICOM_CASES])
def test_each_dicom_case_gives_the_pose_of_the_same_pixels_in_numpy(case, scene, reference, tmp_path, capsys):
    pixels, polarity, kwargs = DICOM_CASES[case]
    dcm = write_dicom(tmp_path / f"{case}.dcm", scene[pixels], CAM, **kwargs)
    out = tmp_path / "out" / "pose.json"
    rc, so, se = _run(["track", "--features", FEATS, dcm, "-o", out], capsys)
    assert rc == 0, se
    (d,) = _poses(out)
    ref = reference(pixels, polarity)
    assert d["converged"] and d["segmentation"]["polarity"] == ref["segmentation"]["polarity"]
    assert np.allclose(d["translation_mm"], ref["translation_mm"], rtol=0, atol=1e-6)
    assert np.allclose(d["rotation"], ref["rotation"], rtol=0, atol=1e-9)
    dr, dt = pose_errors(np.array(d["rotation"]), np.array(d["translation_mm"]), scene["R"], scene["t"])
    assert np.degrees(np.linalg.norm(dr)) < 0.2 and np.all(np.abs(dt[:2]) < 0.1) and abs(dt[2]) < 1.0
    # SPEC §4 optional keys and our extensions: the camera came from the header's tags
    assert d["image"] == str(dcm) and "frame" not in d
    assert d["camera"] == ref["camera"] == CAM.to_dict()
    assert "(0018,1110)" in d["camera_source"]["focal_length"] and "(0018,1164)" in d["camera_source"]["pixel_size"]
    assert d["camera_source"]["principal_point"] == "image centre"
    assert ref["camera_source"] == dict.fromkeys(("focal_length", "pixel_size", "principal_point"), "--camera")
    assert isinstance(d["intake_notes"], list)
    if kwargs.get("fov_rotation_deg"):
        assert any("undone" in n for n in d["intake_notes"])
    if case == "rf":  # a one-frame file with a Frame Time: its time
        assert d["time_s"] == 0.0
    obs = json.loads((tmp_path / "out" / "pose.observation.json").read_text())
    assert obs["format"] == "ftrac-observation" and obs["image"] == str(dcm)


# ------------------------------------------------------------------------------- runs
def _shifted(counts: np.ndarray) -> np.ndarray:
    """Four frames: the image shifted 0, 12, 24, 36 px along the rows (the fiducial moves +u)."""
    return np.stack([np.roll(counts, 12 * k, axis=1) for k in range(4)])


def _check_run(poses: list[dict], image_of_frame, times=None) -> np.ndarray:
    assert [d["frame"] for d in poses] == [0, 1, 2, 3]
    assert all(d["converged"] for d in poses)
    assert [d["image"] for d in poses] == [str(image_of_frame(k)) for k in range(4)]
    if times is None:
        assert all("time_s" not in d for d in poses)
    else:
        assert [d["time_s"] for d in poses] == pytest.approx(times, abs=1e-9)
    tx = np.array([d["translation_mm"][0] for d in poses])
    # 12 px at the detector is 12 × 0.44 / M mm at the fiducial (M = f / z ≈ 1.5): frames in order
    step = 12 * 0.44 * np.array([d["translation_mm"][2] for d in poses]) / 1000.0
    assert np.allclose(np.diff(tx), step[1:], atol=0.05)
    return np.array([d["translation_mm"] for d in poses])


def test_multiframe_dicom_tiff_and_directory_give_one_pose_per_frame_in_order(scene, camera_json, tmp_path, capsys):
    import tifffile

    frames = _shifted(scene["counts"])
    dcm = write_dicom(tmp_path / "run.dcm", frames, CAM, kind="xa", frame_time_ms=66.7)
    rc, so, se = _run(["track", "--features", FEATS, dcm, "-o", tmp_path / "d" / "poses.jsonl", "--overlay"], capsys)
    assert rc == 0, se
    t_dcm = _check_run(_poses(tmp_path / "d" / "poses.jsonl"), lambda k: dcm, [0.0, 0.0667, 0.1334, 0.2001])
    assert "4 of 4 tracked" in so
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == [
        "poses.jsonl",
        "poses.observations.jsonl",
        *[f"poses_run_{k}_overlay.png" for k in range(4)],
    ]
    obs = [json.loads(x) for x in (tmp_path / "d" / "poses.observations.jsonl").read_text().splitlines()]
    assert [o["frame"] for o in obs] == [0, 1, 2, 3]

    tif = tmp_path / "run.tif"
    tifffile.imwrite(tif, frames, photometric="minisblack")  # 4 pages, not planar RGBA
    rc, so, se = _run(["track", "--features", FEATS, tif, "--camera", camera_json, "-o", tmp_path / "t.jsonl"], capsys)
    assert rc == 0, se
    t_tif = _check_run(_poses(tmp_path / "t.jsonl"), lambda k: tif)

    # a directory of PNGs in natural order (img_2 before img_10), with a non-image file
    folder = tmp_path / "pngs"
    folder.mkdir()
    names = ["img_1.png", "img_2.png", "img_10.png", "img_11.png"]
    for name, f in zip(names, frames):
        write_image(folder / name, f)
    (folder / "notes.txt").write_text("not a frame")
    rc, so, se = _run(
        ["track", "--features", FEATS, folder, "--camera", camera_json, "-o", tmp_path / "p.jsonl"], capsys
    )
    assert rc == 0, se
    t_png = _check_run(_poses(tmp_path / "p.jsonl"), lambda k: folder / names[k])
    # the same pixels in three containers: the same poses
    assert np.allclose(t_tif, t_dcm, rtol=0, atol=1e-6) and np.allclose(t_png, t_dcm, rtol=0, atol=1e-6)


def test_frames_are_read_lazily_one_at_a_time(scene, tmp_path, monkeypatch, capsys):
    """While a frame is tracked, no earlier frame's pixels are alive."""
    dcm = write_dicom(tmp_path / "run.dcm", _shifted(scene["counts"]), CAM, kind="xa", frame_time_ms=100.0)
    alive_at_call: list[int] = []
    refs: list[weakref.ref] = []

    def spy(image, *args, **kwargs):
        gc.collect()
        alive_at_call.append(sum(r() is not None for r in refs))
        refs.append(weakref.ref(image))
        raise RuntimeError("spy")

    monkeypatch.setattr(track_run, "track_image", spy)
    monkeypatch.setattr(run_tracker, "track_image", spy)  # a run's frames go through its tracker
    rc, so, se = _run(["track", "--features", FEATS, dcm, "-o", tmp_path / "poses.jsonl"], capsys)
    assert rc == 1 and alive_at_call == [0, 0, 0, 0]


# ------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "omit,named",
    [
        (("DistanceSourceToDetector",), ["DistanceSourceToDetector (0018,1110)"]),
        (("ImagerPixelSpacing",), ["ImagerPixelSpacing (0018,1164)"]),
        (("DistanceSourceToDetector", "ImagerPixelSpacing"), ["(0018,1110)", "(0018,1164)"]),
    ],
)
def test_missing_geometry_tags_exit_2_naming_them_and_nothing_is_tracked_or_written(
    omit, named, scene, tmp_path, monkeypatch, capsys
):
    calls = []
    monkeypatch.setattr(track_run, "track_image", lambda *a, **k: calls.append(1))
    monkeypatch.setattr(run_tracker, "track_image", lambda *a, **k: calls.append(1))  # a run's frames
    good = write_dicom(tmp_path / "good.dcm", scene["counts"], CAM, kind="xa")
    bad = write_dicom(tmp_path / "bad.dcm", scene["counts"], CAM, kind="xa", omit=omit)
    out = tmp_path / "out" / "poses.jsonl"
    rc, so, se = _run(["track", "--features", FEATS, good, bad, "-o", out, "--overlay"], capsys)
    assert rc == 2 and len(se.strip().splitlines()) == 1 and "Traceback" not in se
    assert str(bad) in se and all(n in se for n in named) and "--camera" in se
    assert not calls and not out.parent.exists()


def test_an_unreadable_frame_anywhere_is_bad_input_for_the_whole_command(
    scene, camera_json, tmp_path, monkeypatch, capsys
):
    calls = []
    monkeypatch.setattr(track_run, "track_image", lambda *a, **k: calls.append(1))
    monkeypatch.setattr(run_tracker, "track_image", lambda *a, **k: calls.append(1))  # a run's frames
    good = tmp_path / "good.npy"
    np.save(good, scene["counts"])
    broken = tmp_path / "broken.npy"
    broken.write_bytes(good.read_bytes()[:4000])
    folder = tmp_path / "run"  # a run whose third frame is not an image
    folder.mkdir()
    for k in range(3):
        write_image(folder / f"f{k}.png", scene["counts"])
    (folder / "f2.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    out = tmp_path / "out" / "poses.jsonl"
    for bad in (broken, folder / "f2.png"):
        rc, so, se = _run(
            [
                "track",
                "--features",
                FEATS,
                good,
                broken if bad == broken else folder,
                "--camera",
                camera_json,
                "-o",
                out,
            ],
            capsys,
        )
        assert rc == 2 and len(se.strip().splitlines()) == 1 and str(bad) in se
        assert not calls and not out.parent.exists()


def test_one_poisoned_frame_never_loses_the_batch(scene, camera_json, tmp_path, monkeypatch, capsys):
    """The second of three images raises inside tracking: its object says why, the others
    are tracked and written, exit 1."""
    real = track_run.track_image
    calls = []

    def poisoned(image, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("poisoned\nframe")
        return real(image, *args, **kwargs)

    monkeypatch.setattr(track_run, "track_image", poisoned)
    paths = []
    for name, shift in (("a", 0), ("b", 12), ("c", 24)):
        paths.append(tmp_path / f"{name}.npy")
        np.save(paths[-1], np.roll(scene["counts"], shift, axis=1))
    out = tmp_path / "out" / "poses.jsonl"
    rc, so, se = _run(["track", "--features", FEATS, *paths, "--camera", camera_json, "-o", out, "--overlay"], capsys)
    assert rc == 1
    poses = _poses(out)
    assert [d["image"] for d in poses] == [str(p) for p in paths]
    assert [d["converged"] for d in poses] == [True, False, True]
    assert poses[1]["error"] == "internal error: RuntimeError: poisoned frame" and poses[1]["rotation"] is None
    assert poses[1]["camera"] == CAM.to_dict() and poses[1]["format"] == "ftrac-pose"
    assert se.strip().splitlines() == [f"{paths[1]}: internal error: RuntimeError: poisoned frame"]
    assert "2 of 3 tracked" in so
    obs = (tmp_path / "out" / "poses.observations.jsonl").read_text().splitlines()
    assert len(obs) == 3 and json.loads(obs[1])["points"] == {}
    assert sorted(p.name for p in out.parent.glob("*_overlay.png")) == ["poses_a_overlay.png", "poses_c_overlay.png"]


# ------------------------------------------------------------------------------- distortion
def test_distortion_model_undoes_an_intensifier_distortion(scene, camera_json, reference, tmp_path, capsys):
    """A radial (pincushion) distortion, 4 mm at 60 mm from the centre: tracked as imaged
    the pose is refused or off; with --distortion it is the undistorted image's within
    0.05° and 0.1 mm across, and in depth within 3 of its own σ (resampling the image moves
    the depth by 0.0–0.25 mm over seeds 0–6, σ_z ≈ 0.1 mm)."""
    model = radial(SHAPE, (4.0, 60.0), 0.44)
    mpath = write_distortion(tmp_path / "model.json", model)
    img = tmp_path / "distorted.npy"
    np.save(img, distort_image(scene["counts"], model))
    ref = reference("counts", "auto")
    Rr, tr = np.array(ref["rotation"]), np.array(ref["translation_mm"])

    rc, so, se = _run(["track", "--features", FEATS, img, "--camera", camera_json, "-o", tmp_path / "u.json"], capsys)
    (d,) = _poses(tmp_path / "u.json")
    if d["converged"]:
        dr, dt = pose_errors(np.array(d["rotation"]), np.array(d["translation_mm"]), Rr, tr)
        assert np.degrees(np.linalg.norm(dr)) > 0.05 or np.linalg.norm(dt) > 0.1
    else:
        assert rc == 1

    rc, so, se = _run(
        ["track", "--features", FEATS, img, "--camera", camera_json, "--distortion", mpath, "-o", tmp_path / "c.json"],
        capsys,
    )
    assert rc == 0, se
    (d,) = _poses(tmp_path / "c.json")
    assert d["distortion"] == str(mpath)
    dr, dt = pose_errors(np.array(d["rotation"]), np.array(d["translation_mm"]), Rr, tr)
    sz = float(np.sqrt(np.asarray(d["covariance"])[5, 5]))
    assert np.degrees(np.linalg.norm(dr)) < 0.05 and np.linalg.norm(dt[:2]) < 0.1 and abs(dt[2]) < 3 * sz
    dr, dt = pose_errors(np.array(d["rotation"]), np.array(d["translation_mm"]), scene["R"], scene["t"])
    assert np.degrees(np.linalg.norm(dr)) < 0.2 and np.all(np.abs(dt[:2]) < 0.1) and abs(dt[2]) < 1.0


def test_a_distortion_model_of_another_shape_is_bad_input(scene, camera_json, tmp_path, monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(track_run, "track_image", lambda *a, **k: calls.append(1))
    monkeypatch.setattr(run_tracker, "track_image", lambda *a, **k: calls.append(1))  # a run's frames
    mpath = write_distortion(tmp_path / "model.json", radial((512, 512), (4.0, 60.0), 0.44))
    img = tmp_path / "img.npy"
    np.save(img, scene["counts"])
    out = tmp_path / "out" / "pose.json"
    rc, so, se = _run(
        ["track", "--features", FEATS, img, "--camera", camera_json, "--distortion", mpath, "-o", out], capsys
    )
    assert rc == 2 and len(se.strip().splitlines()) == 1
    assert str(img) in se and "512 × 512" in se and "384 × 384" in se and str(mpath) in se
    assert not calls and not out.parent.exists()


@pytest.mark.parametrize(
    "kwargs,option,want",
    [
        ({"kind": "enhanced-xa", "relationship": "LOG", "relationship_sign": -1}, [], ("dense-bright", "log", "auto")),
        ({"kind": "xa", "relationship": "LIN"}, [], ("dense-dark", "linear", "auto")),
        ({"kind": "xa"}, [], (None, None, "auto")),
        (
            {"kind": "xa", "relationship": "LOG", "relationship_sign": -1},
            ["--polarity", "dense-dark"],
            ("dense-bright", "log", "dense-dark"),
        ),
    ],
)
def test_the_files_polarity_and_formation_are_the_trackers_hints(
    kwargs, option, want, scene, tmp_path, monkeypatch, capsys
):
    """What the header says reaches track_image as hints; --polarity overrides them (the
    tracker's options win over a hint)."""
    seen = []

    def spy(image, features, camera, options=None, polarity_hint=None, formation_hint=None):
        seen.append((polarity_hint, formation_hint, options.polarity))
        raise RuntimeError("spy")

    monkeypatch.setattr(track_run, "track_image", spy)
    dcm = write_dicom(tmp_path / "img.dcm", scene["log"], CAM, **kwargs)
    rc, so, se = _run(["track", "--features", FEATS, dcm, *option, "-o", tmp_path / "pose.json"], capsys)
    assert rc == 1 and seen == [want]


class _Terminal:
    """A stderr that says it is a terminal (tqdm draws only there)."""

    def __init__(self):
        self.buffer = io.StringIO()

    def isatty(self) -> bool:
        return True

    def write(self, s: str) -> int:
        return self.buffer.write(s)

    def flush(self) -> None:
        pass


@pytest.mark.parametrize("frames,tty,bar", [(4, True, True), (3, True, False), (4, False, False)])
def test_a_progress_bar_on_a_terminal_for_more_than_three_frames(
    frames, tty, bar, scene, camera_json, tmp_path, monkeypatch, capsys
):
    def spy(*args, **kwargs):
        raise RuntimeError("spy")

    monkeypatch.setattr(track_run, "track_image", spy)
    monkeypatch.setattr(run_tracker, "track_image", spy)  # a run's frames
    np.save(tmp_path / "run.npy", np.stack([scene["counts"][:64, :64]] * frames))
    err = _Terminal() if tty else io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    rc = main(
        [
            "track",
            "--features",
            FEATS,
            str(tmp_path / "run.npy"),
            "--camera",
            str(camera_json),
            "-o",
            str(tmp_path / "poses.jsonl"),
        ]
    )
    text = err.buffer.getvalue() if tty else err.getvalue()
    assert rc == 1 and text.count("internal error: RuntimeError: spy") == frames
    assert (f"| {frames}/{frames} " in text) == bar  # tqdm's "track: 100%|████| 4/4 [..."


def test_an_undistorting_detector_narrows_the_covariance(scene, camera_json, tmp_path, capsys):
    """Without a word on the detector, each pose's covariance carries an intensifier's
    possible distortion (mostly in depth); `--distortion none` (a flat panel) and a DX file
    (digital radiography) carry none: the same pose, a depth σ several times smaller."""
    img = tmp_path / "img.npy"
    np.save(img, scene["counts"])
    out = {}
    for name, extra in (("unknown", []), ("flat", ["--distortion", "none"])):
        rc, _, err = _run(
            ["track", "--features", FEATS, img, "--camera", camera_json, "-o", tmp_path / f"{name}.json", *extra],
            capsys,
        )
        assert rc == 0, err
        out[name] = _poses(tmp_path / f"{name}.json")[0]
    dx = tmp_path / "dx.dcm"
    write_dicom(dx, scene["counts"], CAM, kind="dx")
    rc, _, err = _run(["track", "--features", FEATS, dx, "-o", tmp_path / "dx.json"], capsys)
    assert rc == 0, err
    out["dx"] = _poses(tmp_path / "dx.json")[0]
    np.testing.assert_allclose(out["flat"]["translation_mm"], out["unknown"]["translation_mm"], atol=1e-9)
    sz = {k: np.sqrt(np.asarray(v["covariance"])[5, 5]) for k, v in out.items()}
    assert sz["unknown"] > 3 * sz["flat"]
    np.testing.assert_allclose(sz["dx"], sz["flat"], rtol=1e-6)


@pytest.mark.parametrize("detector", ["classical", "learned"])
def test_detector_option_chooses_what_finds_the_features(detector, scene, camera_json, tmp_path, capsys):
    """``--detector`` reaches the tracker and the pose file says which path found the fiducial;
    either finds the same fiducial (its pose within its covariance of the truth)."""
    np.save(tmp_path / "counts.npy", scene["counts"])
    out = tmp_path / "pose.json"
    args = ["track", "--features", FEATS, tmp_path / "counts.npy", "--camera", camera_json, "-o", out]
    rc, _, err = _run([*args, "--detector", detector], capsys)
    assert rc == 0, err
    (pose,) = _poses(out)
    assert pose["segmentation"]["detector"] == detector
    dr, dt = pose_errors(np.array(pose["rotation"]), np.array(pose["translation_mm"]), scene["R"], scene["t"])
    e = np.concatenate([np.ravel(dr), np.ravel(dt)])
    assert float(e @ np.linalg.solve(np.array(pose["covariance"]), e)) < 25.7


def test_an_unknown_detector_is_bad_input(scene, camera_json, tmp_path, capsys):
    np.save(tmp_path / "counts.npy", scene["counts"])
    rc, _, err = _run(["track", "--features", FEATS, tmp_path / "counts.npy", "--detector", "hough"], capsys)
    assert rc == 2 and "--detector" in err and "Traceback" not in err
