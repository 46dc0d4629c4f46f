"""Every pose file the package writes, read and written again through ``TrackedPose``: ``solve``'s
pose.json and JSON Lines, ``track``'s pose.json of an image (refined on its intensities too) and
the JSON Lines of a run (tracked, re-identified and lost frames, a frame whose tracking raised):
each object comes back the same, to the byte. And what the record's reader refuses."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_fuzz_observation import BASE, FEATURE_FILES, FEATURES

from ftrac_design.cli.main import main
from ftrac_design.errors import InputError
from ftrac_design.images import write_dicom
from ftrac_design.pose import Camera, Diagnostics, Pose, Provenance, Timing, TrackedPose, read_tracked_poses
from ftrac_design.pose.io import pose_text
from ftrac_design.pose.simulate import Workspace
from ftrac_design.workflows import track_run
from ftrac_design.xray import ImagingModel, render

SHAPE = (384, 384)
CAM = Camera(1000.0, (0.44, 0.44), ((SHAPE[1] - 1) / 2, (SHAPE[0] - 1) / 2))
FEATS = str(FEATURE_FILES["ftrac_2005"])


def _round_trips(path: Path) -> list[TrackedPose]:
    """Each object of ``path`` read as a TrackedPose and written again: the same text."""
    text = path.read_text("utf-8")
    records = read_tracked_poses(path)
    jsonl = path.suffix == ".jsonl"
    again = "".join(pose_text(r, jsonl) for r in records)
    assert again == text, path
    for r in records:
        assert TrackedPose.from_dict(r.to_dict(), "again").to_dict() == r.to_dict()
    return records


@pytest.fixture(scope="module")
def counts():
    features = FEATURES["ftrac_2005"]
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(0))
    rad = render(features, R[0], t[0], CAM, ImagingModel(image_shape=SHAPE), rng=np.random.default_rng(0))
    return np.asarray(rad.raw, np.uint16)


def test_solve_writes_records(tmp_path):
    obs = tmp_path / "obs.json"
    obs.write_text(json.dumps(BASE[("ftrac_2005", 0, False)]))
    assert main(["solve", "--features", FEATS, str(obs), "-o", str(tmp_path / "pose.json")]) == 0
    (one,) = _round_trips(tmp_path / "pose.json")
    assert one.pose.converged and one.pose.origin and one.status is None and one.diagnostics is None
    lines = tmp_path / "obs.jsonl"
    lines.write_text(
        obs.read_text().replace("\n", "") + "\n" + json.dumps({**json.loads(obs.read_text()), "points": {}})
    )
    main(["solve", "--features", FEATS, str(lines), "-o", str(tmp_path / "poses.jsonl")])
    assert len(_round_trips(tmp_path / "poses.jsonl")) == 2


def test_track_writes_records_of_an_image_and_of_a_run(counts, tmp_path, monkeypatch):
    one = write_dicom(tmp_path / "one.dcm", counts, CAM, kind="xa")
    assert (
        main(["track", "--features", FEATS, str(one), "-o", str(tmp_path / "pose.json"), "--refine", "intensity"]) == 0
    )
    (rec,) = _round_trips(tmp_path / "pose.json")
    assert rec.pose.converged and rec.diagnostics.intensity.refined is not None
    assert rec.provenance.image == str(one) and rec.provenance.camera == CAM and rec.provenance.frame is None

    blank = np.full(SHAPE, int(np.median(counts)), np.uint16)
    run = write_dicom(tmp_path / "run.dcm", np.stack([counts, counts, blank, counts]), CAM, kind="xa")
    assert main(["track", "--features", FEATS, str(run), "-o", str(tmp_path / "poses.jsonl")]) == 1
    records = _round_trips(tmp_path / "poses.jsonl")
    assert [r.status for r in records] == ["re-identified", "tracked", "lost", "re-identified"]
    assert [r.provenance.frame for r in records] == [0, 1, 2, 3] and records[1].timing.read_ms is not None

    real = track_run.track_pixels

    def raising(frame, setup, tracker=None):
        if frame.index == 1:
            raise RuntimeError("a bad frame")
        return real(frame, setup, tracker)

    monkeypatch.setattr(track_run, "track_pixels", raising)
    assert main(["track", "--features", FEATS, str(run), "-o", str(tmp_path / "raised.jsonl")]) == 1
    raised = _round_trips(tmp_path / "raised.jsonl")
    assert raised[1].status == "lost" and "a bad frame" in raised[1].pose.error


def test_a_record_keeps_what_it_is_given():
    """Every part of a record survives the format: NaN as null, the diagnostics' kinds."""
    pose = Pose(np.eye(3), np.array([1.0, 2.0, 600.0]), False, float("nan"), np.eye(6), {"B1": 0.1}, 7, "refused")
    diag = Diagnostics(polarity="dense-dark", blobs=9, variance_factor=float("nan"), roi=[1, 2, 3, 4], path="lost")
    rec = TrackedPose(
        pose,
        "lost",
        diag,
        Provenance("a.dcm", 3, 0.1, CAM, {"focal_length": "--camera"}, ("a note",), "model.json"),
        Timing(12.3456, "lost", 1.5),
        "tracking lost: 2 balls",
    )
    d = rec.to_dict()
    assert d["rms_residual_px"] is None and d["segmentation"]["variance_factor"] is None
    assert d["timing"] == {"elapsed_ms": 12.346, "path": "lost", "read_ms": 1.5}
    back = TrackedPose.from_dict(json.loads(json.dumps(d)), "x")
    assert back.to_dict() == d and back.source == "x"
    np.testing.assert_array_equal(back.pose.rotation, np.eye(3))  # a refused pose keeps its numbers
    assert replace(back, source="").provenance == rec.provenance


@pytest.mark.parametrize(
    "change, key",
    [
        ({"status": "found"}, "status"),
        ({"frame": -1}, "frame"),
        ({"covariance_order": ["tx", "ty", "tz", "rx", "ry", "rz"]}, "covariance_order"),
        ({"camera": {"focal_length_mm": -1}}, "camera"),
        ({"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}, "rotation"),
        ({"format": "ftrac-observation"}, "format"),
    ],
)
def test_the_reader_refuses_what_a_reader_would_act_on_wrongly(change, key):
    d = TrackedPose(Pose(np.eye(3), np.array([0.0, 0.0, 600.0]), True, 0.1, None, {}, 3)).to_dict()
    with pytest.raises(InputError) as err:
        TrackedPose.from_dict({**d, **change}, "p.jsonl:2")
    assert err.value.file == "p.jsonl:2" and key in str(err.value)
