"""A labelling whose wire contours could not be measured, confirmed by the learned detector's
wire map alone, must explain all but one of a wire design's balls; so must one whose wire
contours appeared only once the body's projection was subtracted at its pose. A pose resting on
balls alone must fit them as well as balls fit: its χ² no more improbable than the probability
at which one feature is dropped."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.stats import chi2

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_pose
from ftrac_design.pose.simulate import Workspace, simulate_observation
from ftrac_design.segment import TrackOptions, acceptance, evidence, identify
from ftrac_design.segment.labelling import Labelling
from ftrac_design.segment.noise import calibrated_covariance


@pytest.mark.parametrize(
    ("preset", "balls", "refused"), [("ftrac_2005", 8, False), ("ftrac_2005", 7, True), ("nine_bead", 7, False)]
)
def test_a_labelling_confirmed_by_the_network_alone_needs_all_but_one_ball(preset, balls, refused, monkeypatch):
    """No wire contour measured, every wire confirmed by the network: 8 of ftrac_2005's 9
    balls are enough, 7 are not (a near-mirror labelling can fit 7 of 9). A design with no
    wires keeps its own rule: all but two balls (7 of nine_bead's 9)."""
    features = compute_features(load_design(preset))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = [p.id for p in features.points][:balls]
    obs = simulate_observation(features, Camera(), R[0], t[0], include=set(ids))
    assert len(obs.points) == balls and not obs.lines and not obs.ellipses
    monkeypatch.setattr(evidence, "learned_confirms_wires", lambda *a, **k: True)
    lab = _labelling(obs, R[0], t[0])
    why = acceptance.too_little_evidence(SimpleNamespace(features=features), lab, TrackOptions().acceptance)
    if refused:
        assert why is not None and f"{balls} beads and no wires cannot verify" in why and "need ≥ 8" in why
    else:
        assert why is None


def _labelling(obs, R, t, wires_at_first: bool = True) -> Labelling:
    pose = SimpleNamespace(rotation=R, translation_mm=t)
    return Labelling(pose, obs, None, {}, identify.Contours(), {}, wires_at_first=wires_at_first)


@pytest.mark.parametrize(("balls", "at_first", "refused"), [(7, True, False), (7, False, True), (8, False, False)])
def test_wire_contours_seen_only_after_the_body_subtraction_do_not_confirm_a_labelling(
    balls, at_first, refused, monkeypatch
):
    """Seven of ftrac_2005's balls and one ellipse's contour: enough when the labelling explained
    a wire before the body was subtracted, not when that contour appeared only after it (a
    near-mirror labelling's ellipse on the other ellipse's image); eight balls are enough
    either way."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = [p.id for p in features.points][:balls]
    obs = simulate_observation(features, Camera(), R[0], t[0], include=set(ids) | {"E1"})
    assert len(obs.points) == balls and list(obs.ellipses) == ["E1"] and not obs.lines
    monkeypatch.setattr(evidence, "learned_confirms_wires", lambda *a, **k: False)
    lab = _labelling(obs, R[0], t[0], wires_at_first=at_first)
    assert lab.confirmed_by_wires is at_first
    why = acceptance.too_little_evidence(SimpleNamespace(features=features), lab, TrackOptions().acceptance)
    if refused:
        assert why is not None and "wires seen only after the body's subtraction cannot verify" in why
    else:
        assert why is None


@pytest.mark.parametrize(
    ("factor", "curves", "refused"), [(0.98, False, False), (1.02, False, True), (3.0, True, False)]
)
def test_balls_alone_are_refused_where_their_chi2_is_less_probable_than_a_dropped_feature(factor, curves, refused):
    """Eight balls (χ² with 10 degrees of freedom): a variance factor just inside the χ²₁₀
    quantile at ``feature_p_value`` passes and one just beyond it is refused; a pose that also
    explains a wire contour is judged by the wire, not by this test."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = {p.id for p in features.points[:8]} | ({"E1"} if curves else set())
    obs = simulate_observation(features, Camera(), R[0], t[0], include=ids)
    opts = TrackOptions().acceptance
    vf = factor * chi2.isf(opts.feature_p_value, 10) / 10
    lab = replace(_labelling(obs, R[0], t[0]), variance_factor=vf)
    why = acceptance.balls_misfit(lab, opts)
    assert (why is not None and "χ²10" in why) if refused else why is None


def test_balls_at_the_noise_they_were_measured_with_pass():
    """Balls displaced by the noise model's own σ, the pose solved and its variance factor
    calibrated as the tracker does: the test does not refuse them (20 views)."""
    features = compute_features(load_design("ftrac_mini"))
    Rs, ts = Workspace().sample(20, features.nominal_beam_direction, np.random.default_rng(5))
    ids = {p.id for p in features.points}
    noise, opts = NoiseModel(), TrackOptions().acceptance
    for k, (R, t) in enumerate(zip(Rs, ts)):
        # a uniform magnitude in [0, e] mm has a per-axis σ of e / √6: the model's σ for e = 0.25 mm
        obs = simulate_observation(features, Camera(), R, t, 0.25, np.random.default_rng(100 + k), include=ids)
        pose = solve_pose(features, obs, SolverOptions(noise=noise))
        vf = calibrated_covariance(features, obs, pose, noise)
        assert pose.converged and vf is not None
        assert acceptance.balls_misfit(replace(_labelling(obs, R, t), variance_factor=vf), opts) is None
