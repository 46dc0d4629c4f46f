"""Internal reliability: a feature that alone fixes a direction of the pose is checked by no
other, so an error in it (a ball fitted on the wrong blob) moves the pose and shows in no
residual. Its redundancy number — 1 − the whitened hat matrix's diagonal — is then 0, and
:func:`ftrac_design.segment.acceptance.uncontrolled` refuses a pose that rests on it."""

from __future__ import annotations

import numpy as np
import pytest
from test_fuzz_observation import FEATURES

from ftrac_design.pose import Camera, NoiseModel, SolverOptions, refine_pose
from ftrac_design.pose.simulate import Workspace, simulate_observation
from ftrac_design.segment import TrackOptions
from ftrac_design.segment.noise import redundancy_numbers

LINE_BALLS = {"B1", "B2", "B3", "B4"}  # ftrac_2005's four balls on L1


@pytest.fixture(scope="module")
def view():
    features = FEATURES["ftrac_2005"]
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(3))
    return features, Camera(), R[0], t[0]


def _numbers(view, include):
    features, cam, R, t = view
    obs = simulate_observation(features, cam, R, t, include=include)
    noise = NoiseModel()
    pose = refine_pose(features, obs, R, t, SolverOptions(noise=noise))
    return redundancy_numbers(features, obs, pose, noise)


def test_the_balls_of_one_wire_line_checked_by_nothing_else(view):
    """Four collinear balls and their wire fix every direction but the turn about the wire;
    one more ball fixes that turn alone: its redundancy is ~0 (an error in it is absorbed;
    not exactly 0 as the balls sit a little off the wire's axis),
    while the collinear ones check each other."""
    features, *_ = view
    assert {p.id for p in features.points} >= LINE_BALLS | {"B7"}
    r = _numbers(view, LINE_BALLS | {"B7", "L1"})
    assert r["B7"] < 1e-3, r
    assert min(r[b] for b in LINE_BALLS) > 0.1, r


def test_every_feature_of_a_full_view_is_checked(view):
    features, *_ = view
    r = _numbers(view, None)
    ids = [f.id for f in (*features.points, *features.lines, *features.ellipses)]
    assert set(r) == set(ids)
    assert min(r.values()) > TrackOptions().min_feature_redundancy * 2, r
    # a redundancy number is a share of the row's error: between 0 and 1
    assert all(0.0 <= v <= 1.0 + 1e-12 for v in r.values())
