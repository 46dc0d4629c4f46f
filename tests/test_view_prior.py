"""The view as known beforehand (:class:`ftrac_design.segment.ViewPrior`, ``track --expect-view``):
only labellings whose rotation it admits are looked for and given out.

A small fiducial far from the source is seen in near-affine projection, where a labelling
rotated 135–180° puts every ball and wire within a fraction of a pixel of the right one's: the
tracker refuses that tie unless the image's pixels settle it, and a prior decides it. The
realism benchmark's ftrac_mini log image 12 of tuning seed 21 (20 per condition) is such a
tie: the right labelling and one 180° off, the pixels preferring the right one by 2.9 units
(3 settle a tie).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from test_fuzz_observation import FEATURE_FILES

from ftrac_design.cli.main import main
from ftrac_design.pose import read_tracked_poses, so3
from ftrac_design.pose.simulate import pose_errors
from ftrac_design.segment import TrackOptions, ViewPrior, track_image

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


def _turned(R: np.ndarray, angle_rad: float, seed: int) -> np.ndarray:
    """``R`` turned by ``angle_rad`` about a random axis (on the left)."""
    axis = np.random.default_rng(seed).normal(size=3)
    return so3.exp(axis / np.linalg.norm(axis) * angle_rad) @ R


def test_a_view_prior_admits_the_rotations_within_its_angle():
    R0 = so3.exp(np.array([0.4, -1.1, 0.3]))
    prior = ViewPrior(R0, math.radians(30.0))
    near = np.stack([_turned(R0, math.radians(29.9), s) for s in range(20)])
    far = np.stack([_turned(R0, math.radians(30.1), s) for s in range(20)])
    assert prior.admits(near).all() and not prior.admits(far).any()
    assert prior.admits(far, margin_rad=math.radians(0.2)).all()
    assert bool(prior.admits(R0))
    for bad in (np.diag([1.0, 1.0, -1.0]), 1.01 * R0, np.full((3, 3), np.nan), np.eye(2)):
        with pytest.raises(ValueError, match="rotation"):
            ViewPrior(bad, 0.5)
    for angle in (0.0, -0.1, math.pi + 1e-6, math.nan):
        with pytest.raises(ValueError, match="angle"):
            ViewPrior(R0, angle)


@pytest.fixture(scope="module")
def tie():
    import track_realism

    img, R, t, camera, _ = track_realism.make_image("ftrac_mini", "log", 12, 21, 20)
    return img, R, t, camera, track_realism.preset_features("ftrac_mini")


def test_a_prior_decides_a_near_mirror_tie(tie):
    """Without a prior the image is refused as a tie of the right labelling and one over 100°
    off; with one 25° off the truth and 45° wide it gives the right pose (its depth, 3 mm off,
    inside its own covariance); every answer a prior
    lets through lies within it, a wrong prior's too (the caller's word, not the image's); a
    prior far from both answers leaves none."""
    img, R, t, camera, features = tie
    res = track_image(img, features, camera)
    assert not res.pose.converged and res.pose.error.startswith("ambiguous identification")
    off = sorted(np.degrees(so3.angle(np.asarray(a["rotation"]), R)) for a in res.diagnostics.alternatives)
    assert off[0] < 1.0 and off[1] > 100.0

    right = track_image(
        img, features, camera, TrackOptions(view=ViewPrior(_turned(R, math.radians(25), 0), math.pi / 4))
    )
    assert right.pose.converged, right.pose.error
    dr, dt = pose_errors(right.pose.rotation, right.pose.translation_mm, R, t)
    e = np.concatenate([dr, dt])
    assert np.degrees(np.linalg.norm(dr)) < 0.5 and e @ np.linalg.solve(right.pose.covariance, e) < 16.8

    rival = next(
        np.asarray(a["rotation"]) for a in res.diagnostics.alternatives if so3.angle(np.asarray(a["rotation"]), R) > 1
    )
    wrong = track_image(img, features, camera, TrackOptions(view=ViewPrior(rival, math.pi / 4)))
    assert not wrong.pose.converged or so3.angle(wrong.pose.rotation, rival) <= math.pi / 4

    # a view 90° from the truth about an axis in the image plane, 30° wide: neither answer
    aside = so3.exp(np.array([math.pi / 2, 0.0, 0.0])) @ R
    assert min(so3.angle(aside, R), so3.angle(aside, rival)) > math.radians(60)
    none = track_image(img, features, camera, TrackOptions(view=ViewPrior(aside, math.radians(30))))
    assert not none.pose.converged and "within 30° of the expected view" in none.pose.error


def test_a_prior_that_admits_every_view_changes_nothing(tie):
    """A prior 180° wide admits every rotation: the same answer, bit for bit, as none (the
    reasons of the image's other looks may name the view they were searched within)."""
    img, R, t, camera, features = tie
    a = track_image(img, features, camera).pose
    b = track_image(img, features, camera, TrackOptions(view=ViewPrior(_turned(R, 2.0, 1), math.pi))).pose
    assert a.converged == b.converged and a.error.split(" (")[0] == b.error.split(" (")[0]
    assert np.array_equal(a.rotation, b.rotation) and np.array_equal(a.translation_mm, b.translation_mm)


def _pose_file(path: Path, R: np.ndarray) -> Path:
    path.write_text(
        json.dumps(
            {
                "format": "ftrac-pose",
                "version": 1,
                "rotation": np.asarray(R).tolist(),
                "translation_mm": [0.0, 0.0, 600.0],
                "converged": True,
            }
        )
    )
    return path


def test_track_expect_view_reaches_the_tracker(tie, tmp_path, capsys):
    """``track --expect-view POSE.json --view-within-deg 45`` gives the tie's right pose (exit 0),
    its pose file recording the prior (``expected_view``); a pose file whose rotation is not a
    rotation, or that holds two poses, is bad input: exit 2, one line naming the file and the
    key, nothing written."""
    img, R, t, camera, _ = tie
    np.save(tmp_path / "tie.npy", img)
    (tmp_path / "cam.json").write_text(json.dumps(camera.to_dict()))
    base = [
        "track",
        "--features",
        str(FEATURE_FILES["ftrac_mini"]),
        str(tmp_path / "tie.npy"),
        "--camera",
        str(tmp_path / "cam.json"),
    ]
    out = tmp_path / "pose.json"
    view = _pose_file(tmp_path / "view.json", _turned(R, math.radians(25), 0))
    assert main([*base, "-o", str(out), "--expect-view", str(view), "--view-within-deg", "45"]) == 0
    pose = json.loads(out.read_text())
    assert np.degrees(so3.angle(np.array(pose["rotation"]), R)) < 0.5
    # the pose says it rests on the caller's prior, and reads back with it
    assert pose["expected_view"] == {"file": str(view), "within_deg": 45.0}
    assert read_tracked_poses(out)[0].provenance.expected_view == pose["expected_view"]

    bad = _pose_file(tmp_path / "bad.json", 2.0 * np.eye(3))
    capsys.readouterr()
    out2 = tmp_path / "other.json"
    assert main([*base, "-o", str(out2), "--expect-view", str(bad)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(bad) in err and "rotation" in err and "Traceback" not in err
    two = tmp_path / "two.jsonl"
    two.write_text(view.read_text() + "\n" + view.read_text() + "\n")
    assert main([*base, "-o", str(out2), "--expect-view", str(two)]) == 2
    err = capsys.readouterr().err
    assert str(two) in err and "one pose" in err and not out2.exists()
