"""The demo's C-arm step (:mod:`ftrac_design.demo.carm`): what it prints is what it wrote.

The step runs once (≈ 6 s) into a temporary directory, which is the working directory while
it runs so that printed paths are relative; every printed number is recomputed from the
files it wrote (poses, truth, model) and the DICOM run is checked against a fresh render of
the same seed.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from ftrac_design.demo.carm import (
    CAMERA,
    SHAPE,
    CarmDemoSettings,
    c_arm_orbit,
    demo_step,
    format_errors,
    pose_report,
    read_jsonl,
)
from ftrac_design.features import compute_features, write_features
from ftrac_design.images import frame_count, read_frames
from ftrac_design.pose import TrackedPose
from ftrac_design.pose.simulate import pose_errors
from ftrac_design.xray.scenario import realistic_image

SETTINGS = CarmDemoSettings()
NUM = r"[-+]?\d+\.\d+"
ERRORS = re.compile(
    rf"converged: error t \(({NUM}), ({NUM}), ({NUM})\) mm, rotation ({NUM})°; "
    rf"1σ t \(({NUM}), ({NUM}), ({NUM})\) mm, rotation \(({NUM}), ({NUM}), ({NUM})\)°"
)


@pytest.fixture(scope="module")
def ran(tmp_path_factory, design_2005):
    """(printed text, the step's directory relative to the working directory, the features file);
    the working directory is the temporary one while the step runs and the test reads."""
    root = tmp_path_factory.mktemp("demo_carm")
    features = write_features(root / "features.json", compute_features(design_2005))
    here = os.getcwd()
    os.chdir(root)
    try:
        text = demo_step(Path("carm"), Path("features.json"))
        yield text, root, features
    finally:
        os.chdir(here)


def _numbers(line: str) -> np.ndarray:
    m = ERRORS.search(line)
    assert m, line
    return np.array([float(v) for v in m.groups()])


def _expected(pose: dict, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The ten printed numbers recomputed: t error (3), rotation error (deg), t 1σ (3), rotation 1σ (3, deg)."""
    dr, dt = pose_errors(np.array(pose["rotation"]), np.array(pose["translation_mm"]), R, t)
    sd = np.sqrt(np.diag(np.array(pose["covariance"])))
    return np.r_[dt, math.degrees(np.linalg.norm(dr)), sd[3:], np.degrees(sd[:3])]


def test_each_frame_of_the_run_is_printed_as_tracked(ran):
    text, root, _ = ran
    carm = root / "carm"
    poses, truth = read_jsonl(carm / "poses.jsonl"), read_jsonl(carm / "run.truth.jsonl")
    frame_lines = [ln for ln in text.splitlines() if re.match(r"\s+frame \d+ \(time", ln)]
    n = frame_count(carm / "run.dcm")
    assert n == SETTINGS.frames == len(poses) == len(truth) == len(frame_lines)
    for k, (line, pose, true) in enumerate(zip(frame_lines, poses, truth)):
        assert pose["frame"] == true["frame"] == k
        assert line.strip().startswith(f"frame {k} (time {pose['time_s']:.3f} s):")
        assert line.endswith(f" [{pose['status']}]"), line
        assert pose["time_s"] == pytest.approx(true["time_s"], abs=1e-6)
        assert true["time_s"] == pytest.approx(k * SETTINGS.frame_time_ms / 1e3)
        if pose["converged"]:
            got = _numbers(line)
            want = _expected(pose, np.array(true["rotation"]), np.array(true["translation_mm"]))
            assert np.allclose(got, want, rtol=0, atol=0.0005 + 1e-9), (got, want)
            assert (carm / f"poses_run_{k}_overlay.png").is_file()
        else:
            assert "NOT converged: " + " ".join(pose["error"].split()) in line
    tracked = sum(p["converged"] for p in poses)
    near = sum(p["status"] == "tracked" for p in poses)
    assert f"{tracked} of {n} frames tracked ({near} from the frame before, {tracked - near} identified" in text
    # what intake read from the Enhanced XA file is what the poses record
    assert "FieldOfViewRotation 90° and horizontal flip undone" in poses[0]["intake_notes"]
    assert poses[0]["camera"] == CAMERA.to_dict()
    assert "tracked as display, dense-dark" in text


def test_printed_paths_are_relative_and_exist(ran):
    text, root, _ = ran
    assert str(root) not in text
    for p in (
        "carm/run.dcm",
        "carm/run.truth.jsonl",
        "carm/poses.jsonl",
        "carm/distortion/grid.dcm",
        "carm/distortion/model.json",
        "carm/distortion/frame.dcm",
        "carm/distortion/corrected/pose.json",
    ):
        assert p in text and (root / p).is_file(), p


def test_the_run_is_stored_rotated_and_reads_back_as_rendered(ran, features_2005):
    _, root, features_path = ran
    import pydicom

    ds = pydicom.dcmread(root / "carm" / "run.dcm")
    assert ds.SOPClassUID == "1.2.840.10008.5.1.4.1.1.12.1.1" and int(ds.NumberOfFrames) == SETTINGS.frames
    fov = ds.SharedFunctionalGroupsSequence[0].FieldOfViewSequence[0]
    assert int(fov.FieldOfViewRotation) == 90 and fov.FieldOfViewHorizontalFlip == "YES"
    # frame 1 as read (detector grid) is the render of the same seed at frame 1's true pose
    true = read_jsonl(root / "carm" / "run.truth.jsonl")[1]
    img, _ = realistic_image(
        features_2005,
        np.array(true["rotation"]),
        np.array(true["translation_mm"]),
        CAMERA,
        SETTINGS.condition,
        SETTINGS.seed,
        shape=SHAPE,
    )
    frame = list(read_frames(root / "carm" / "run.dcm"))[1]
    assert np.array_equal(frame.pixels, img) and frame.formation == "display" and frame.polarity == "dense-dark"
    assert np.array_equal(ds.pixel_array[1], np.rot90(img, -1)[:, ::-1])  # stored turned, then flipped


def test_the_truth_turns_about_the_isocentre(ran):
    _, root, _ = ran
    truth = read_jsonl(root / "carm" / "run.truth.jsonl")
    R = np.array([d["rotation"] for d in truth])
    t = np.array([d["translation_mm"] for d in truth])
    c = np.array([0.0, 0.0, SETTINGS.isocentre_mm])
    p = R[0].T @ (c - t[0])  # the fiducial-frame point at the isocentre
    assert np.allclose(np.einsum("kij,j->ki", R, p) + t, c, atol=1e-9)
    for k in range(1, len(truth)):
        turn = R[k] @ R[k - 1].T
        angle = math.degrees(math.acos(np.clip((np.trace(turn) - 1) / 2, -1, 1)))
        assert angle == pytest.approx(SETTINGS.step_deg, abs=1e-9)
        assert truth[k]["c_arm_angle_deg"] == pytest.approx(k * SETTINGS.step_deg)


def test_c_arm_orbit_of_zero_is_the_pose_and_turns_about_the_x_axis():
    R0, t0 = np.eye(3), np.array([5.0, -3.0, 650.0])
    R, t = c_arm_orbit(R0, t0, np.radians([0.0, 90.0]), 667.0)
    assert np.array_equal(R[0], R0) and np.allclose(t[0], t0)
    # the camera turned +90° about its x axis through (0, 0, 667): the fiducial's offset from the
    # isocentre (5, -3, -17) is seen as (5, -17, 3), and its axes turned the other way
    assert np.allclose(t[1], [5.0, -17.0, 667.0 + 3.0], atol=1e-9)
    assert np.allclose(R[1], [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-12)


def test_the_distortion_workflow_prints_what_it_wrote(ran):
    text, root, _ = ran
    d = root / "carm" / "distortion"
    model = json.loads((d / "model.json").read_text())
    m = re.search(rf"residual RMS ({NUM}) px", text)
    assert m and float(m.group(1)) == pytest.approx(model["rms_residual_px"], abs=0.0005 + 1e-9)
    true = json.loads((d / "frame.truth.json").read_text())
    R, t = np.array(true["rotation"]), np.array(true["translation_mm"])
    lines = text.splitlines()
    sd_depth = {}
    for name in ("uncorrected", "corrected"):
        pose = json.loads((d / name / "pose.json").read_text())
        (i,) = [k for k, ln in enumerate(lines) if ln.strip().startswith(f"{name}: ")]
        assert pose["converged"], pose.get("error")
        want = _expected(pose, R, t)
        assert np.allclose(_numbers(lines[i]), want, rtol=0, atol=0.0005 + 1e-9)
        depth = re.search(rf"depth error ({NUM}) mm, depth 1σ ({NUM}) mm", lines[i + 1])
        assert depth and np.allclose([float(v) for v in depth.groups()], [want[2], want[6]], atol=0.0005 + 1e-9)
        sd_depth[name] = want[6]
    assert json.loads((d / "corrected" / "pose.json").read_text())["distortion"] == "carm/distortion/model.json"
    # with a model no unmodelled distortion is left for the covariance to carry
    assert sd_depth["corrected"] < sd_depth["uncorrected"]


def test_a_frame_without_a_pose_is_reported_with_the_trackers_reason():
    pose = TrackedPose.failed("identification not confirmed:\n  no wire where the pose puts L1").to_dict()
    r = pose_report(pose, np.eye(3), np.zeros(3))
    assert not r["converged"] and "t_err_mm" not in r
    assert format_errors(r) == "NOT converged: identification not confirmed: no wire where the pose puts L1"
