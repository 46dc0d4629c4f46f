"""Where a labelling's refinement goes when its contours mislead it, and which of the best
labelling's two versions — before and after the body's projection was subtracted at its pose —
the tracker keeps.

A stage whose contours were gathered on the wrong wire does not converge; the next stage must
then start where the stage's balls put the fiducial, not where the failed solve left it (tens
of mm away, where the tight stage matches too few balls). Where the last stage fails, its
features are judged at the pose it started from, not where the failed solve went. And the
subtraction's version replaces the first unless it explains exactly the same features at a
worse misfit."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, NoiseModel
from ftrac_design.pose.simulate import Workspace, simulate_observation
from ftrac_design.segment import TrackOptions, identify, labelling
from ftrac_design.segment.beads import Beads
from ftrac_design.segment.detection import Scales


def _view(seed: int = 3):
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(seed))
    cam = Camera()
    obs = simulate_observation(features, cam, R[0], t[0], 0.05, np.random.default_rng(seed + 1))
    return features, cam, R[0], t[0], obs


def _scene(features, cam, obs):
    uv = np.array([obs.points[p.id] for p in features.points])
    n = len(uv)
    beads = Beads(
        uv, np.full(n, 3.0), np.full(n, 0.8), np.ones(n), np.full(n, 0.05), np.ones(n), np.ones(n), np.full(n, 20.0)
    )
    # the sizes the stages read (the ridge and top-hat sizes are not read here)
    scales = Scales(
        bead_radius_px=3.0, wire_px=1.0, pixel_mm=cam.pixel_size_mm[0], ridge_sigma_px=1.0, disc_px=8, blur_px=0.8
    )
    return SimpleNamespace(features=features, camera=cam, beads=beads, scales=scales)


@pytest.fixture
def stages(monkeypatch):
    """The contour gathering stubbed: the wide stage reads ellipse E1 8 px off its image (a
    neighbouring wire's ridge), the tight stage reads every curve right — where it is asked at
    a pose within 2 mm of the truth, and nothing elsewhere. Returns the poses (R, t) each
    stage was gathered at."""
    features, cam, R, t, obs = _view()
    asked: list[tuple[int, np.ndarray, np.ndarray]] = []

    def contours(scene, R_, t_, blur, stage, opts):
        asked.append((stage, R_, t_))
        if stage == 0:
            wrong = {k: v.points + (8.0 if k == "E1" else 0.0) for k, v in obs.ellipses.items()}
            return identify.Contours({k: v.points for k, v in obs.lines.items()}, wrong)
        if np.linalg.norm(t_ - t) > 2.0:
            return identify.Contours()
        return identify.Contours(
            {k: v.points for k, v in obs.lines.items()}, {k: v.points for k, v in obs.ellipses.items()}
        )

    monkeypatch.setattr(labelling, "_contours", contours)
    monkeypatch.setattr(labelling, "measured_noise", lambda *a, **k: NoiseModel())
    return features, cam, R, t, obs, asked


def test_a_stage_misled_by_its_contours_hands_the_next_stage_the_balls_pose(stages):
    features, cam, R, t, obs, asked = stages
    scene = _scene(features, cam, obs)
    R0 = Rotation.from_rotvec([0.002, -0.001, 0.001]).as_matrix() @ R
    h = identify.BeadHypothesis(R0, t + np.array([0.1, -0.1, 0.5]), {}, 9, 0.2)
    lab, _ = labelling._staged_solve(scene, h, 0, TrackOptions().labelling)
    first, last = asked[0], asked[-1]
    assert first[0] == 0 and last[0] == 2
    # the wide stage's own solve failed on the wrong ellipse ...
    assert np.linalg.norm(last[2] - t) < 2.0
    # ... and the tight stage, gathered at the balls' pose, gives the pose with every feature
    assert lab.pose.converged and len(lab.obs.ellipses) == 2 and len(lab.obs.points) == 9
    assert np.linalg.norm(lab.pose.translation_mm - t) < 1.0


def test_the_misled_stage_did_fail_without_the_balls_pose(stages, monkeypatch):
    """The fixture's wide stage really misleads: with the restart disabled, the tight stage
    is asked where the failed solve went and finds no curve."""
    features, cam, R, t, obs, asked = stages
    monkeypatch.setattr(labelling, "_balls_alone", lambda *a, **k: None)
    h = identify.BeadHypothesis(R, t + np.array([0.1, -0.1, 0.5]), {}, 9, 0.2)
    lab, _ = labelling._staged_solve(_scene(features, cam, obs), h, 0, TrackOptions().labelling)
    assert np.linalg.norm(asked[-1][2] - t) > 2.0
    assert not lab.obs.ellipses


@pytest.fixture
def misled_last_stage(monkeypatch):
    """The contour gathering stubbed the other way round, on five of the nine balls: the wide
    stage reads every curve right; the last (tight) stage no line, ellipse E2 right and E1 8 px
    off its image — as a conic fitted to a short arc of it can read (fluoroscopy dose, realism
    seed 2137: a pose 0.3° and 0.7 mm off went 81 mm away at that stage)."""
    features, cam, R, t, obs = _view()

    def contours(scene, R_, t_, blur, stage, opts):
        ellipses = {k: v.points + (8.0 if stage == 2 and k == "E1" else 0.0) for k, v in obs.ellipses.items()}
        return identify.Contours({k: v.points for k, v in obs.lines.items()} if stage == 0 else {}, ellipses)

    monkeypatch.setattr(labelling, "_contours", contours)
    monkeypatch.setattr(labelling, "measured_noise", lambda *a, **k: NoiseModel())
    scene = _scene(features, cam, obs)
    scene.beads = scene.beads.take(np.array([0, 2, 4, 6, 8]))
    h = identify.BeadHypothesis(R, t + np.array([0.1, -0.1, 0.5]), {}, 5, 0.2)
    return scene, h, t


def test_a_last_stage_that_fails_has_its_features_judged_where_it_started(misled_last_stage):
    scene, h, t = misled_last_stage
    opts = TrackOptions().labelling
    lab, start = labelling._staged_solve(scene, h, 0, opts)
    # the tight stage's solve failed, far away, from the wide stage's converged pose
    assert not lab.pose.converged and np.linalg.norm(lab.pose.translation_mm - t) > 10.0
    assert start is not None and np.linalg.norm(start[1] - t) < 1.0
    kept = labelling._drop_inconsistent(scene, lab, opts, start)
    assert kept.pose.converged and list(kept.removed) == ["E1"]
    assert np.linalg.norm(kept.pose.translation_mm - t) < 1.0
    # judged where the failed solve went instead, two right balls are dropped and no pose found
    lost = labelling._drop_inconsistent(scene, lab, opts)
    assert not lost.pose.converged and "E1" not in lost.removed


def test_a_last_stage_that_converges_hands_on_no_start(stages):
    features, cam, R, t, obs, asked = stages
    h = identify.BeadHypothesis(R, t + np.array([0.1, -0.1, 0.5]), {}, 9, 0.2)
    lab, start = labelling._staged_solve(_scene(features, cam, obs), h, 2, TrackOptions().labelling)
    assert lab.pose.converged and start is None
