"""Conditioning analysis: the batched information is the solver's JᵀJ, the metrics are
right on closed-form cases, the singular values behave as geometry says (roll invariance on
the principal ray, an ellipse going blind edge-on), removing a feature costs accuracy, and
the predicted errors are the solver's actual errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MODELS, PRESETS

from ftrac_design.analysis import (
    AnalysisSettings,
    Thresholds,
    analyse_poses,
    blind_spot_atlas,
    feature_information,
    feature_layout,
    pose_metrics,
    score_design,
    total_information,
)
from ftrac_design.analysis.sampling import isocentre_poses, workspace_poses
from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, NoiseModel, SolverOptions, evaluate, solve_batch
from ftrac_design.pose.simulate import (
    Workspace,
    pose_errors,
    rotations_from_beams,
    simulate_observation,
    synthetic_problem,
)
from ftrac_design.pose.solver import parameter_scale


@pytest.fixture(scope="module")
def presets():
    return {p: compute_features(load_design(MODELS / f"{p}.toml")) for p in PRESETS}


@pytest.mark.parametrize("name", PRESETS)
def test_batched_information_is_the_solvers_jacobian(presets, name):
    """Σ_f I_f and each I_f equal JᵀJ of the solver's whitened Jacobian (all of it, and the
    rows of that feature) at 25 workspace poses, evaluated one pose at a time."""
    f = presets[name]
    R, t = workspace_poses(Workspace(), f.nominal_beam_direction, 25, seed=7)
    layout = feature_layout(f)
    cam = Camera()
    per = feature_information(layout, cam, R, t)
    total = total_information(layout, cam, R, t)
    np.testing.assert_allclose(per.sum(1), total, rtol=1e-10, atol=1e-12 * np.abs(total).max())
    for i in range(len(R)):
        prob = synthetic_problem(f, cam, R[i], t[i])
        J = evaluate(prob, R[i : i + 1], t[i : i + 1]).J[0]
        scale = np.abs(J.T @ J).max()
        np.testing.assert_allclose(total[i], J.T @ J, rtol=0, atol=1e-9 * scale)
        for fid, rows in prob.row_groups():
            Jf = J[rows]
            np.testing.assert_allclose(per[i, layout.index(fid)], Jf.T @ Jf, rtol=0, atol=1e-9 * scale)


def test_batch_equals_one_pose_at_a_time(presets):
    f = presets["ftrac_2005"]
    R, t = workspace_poses(Workspace(), f.nominal_beam_direction, 40, seed=3)
    batch = analyse_poses(f, R, t, detail=True, chunk=16)
    for i in (0, 17, 39):
        one = analyse_poses(f, R[i : i + 1], t[i : i + 1], detail=True)
        np.testing.assert_allclose(one.overall.sigma[0], batch.overall.sigma[i], rtol=1e-10)
        np.testing.assert_allclose(one.overall.translation_std_mm[0], batch.overall.translation_std_mm[i], rtol=1e-9)
        np.testing.assert_allclose(one.rank_ratio[0], batch.rank_ratio[i], rtol=1e-8)


def test_metrics_on_a_diagonal_information_matrix():
    """Closed form: I = diag(λ), H = 1 → σ = √λ, cond, D-optimality, amplification, std = 1/√λ."""
    lam = np.array([4.0, 9.0, 16.0, 25.0, 100.0, 400.0])
    m = pose_metrics(np.diag(lam)[None], np.ones(6), m=30)
    np.testing.assert_allclose(m.sigma[0], np.sqrt(lam)[::-1])
    assert m.condition[0] == pytest.approx(20.0 / 2.0)
    assert m.sigma_min[0] == pytest.approx(2.0)
    assert m.d_optimality[0] == pytest.approx(np.prod(np.sqrt(lam)) ** (1 / 6) / np.sqrt(30))
    assert m.noise_amplification[0] == pytest.approx(4.0 / 20.0)
    np.testing.assert_allclose(m.rotation_std_rad[0], 1 / np.sqrt(lam[:3]))
    np.testing.assert_allclose(m.translation_std_mm[0], 1 / np.sqrt(lam[3:]))
    # parameter scaling changes the singular values but not the predicted errors
    h = np.array([0.1, 0.1, 0.1, 1, 1, 1])
    ms = pose_metrics(np.diag(lam)[None], h, m=30)
    np.testing.assert_allclose(ms.translation_std_mm, m.translation_std_mm)
    np.testing.assert_allclose(ms.rotation_std_rad, m.rotation_std_rad)
    assert ms.condition[0] != pytest.approx(m.condition[0])
    # a rank-deficient set is singular: infinite condition and errors
    sing = pose_metrics(np.diag([0, 1, 1, 1, 1, 1.0])[None], np.ones(6), m=6)
    assert np.isinf(sing.condition[0]) and np.isinf(sing.translation_rms_mm[0])


@pytest.mark.parametrize("name", ["ftrac_2005", "nine_bead"])
def test_singular_values_invariant_to_roll_on_the_principal_ray(presets, name):
    f = presets[name]
    beam = np.array([0.3, -1.0, 0.2])
    rolls = np.linspace(0, 2 * np.pi, 9)
    R = rotations_from_beams(np.repeat(beam[None] / np.linalg.norm(beam), len(rolls), 0), rolls)
    t = np.tile([0.0, 0.0, 667.0], (len(rolls), 1))
    m = analyse_poses(f, R, t, detail=False).overall
    np.testing.assert_allclose(m.sigma, np.repeat(m.sigma[:1], len(rolls), 0), rtol=1e-9)
    np.testing.assert_allclose(m.translation_rms_mm, m.translation_rms_mm[0], rtol=1e-9)
    # off the principal ray the perspective is not symmetric: the same rolls do change them
    off = analyse_poses(f, R, t + [40.0, 0.0, 0.0], detail=False).overall
    assert np.ptp(off.sigma[:, -1]) / off.sigma[0, -1] > 1e-4


def test_single_ellipse_goes_singular_edge_on_and_the_atlas_names_it(presets):
    f = presets["ftrac_2005"]
    e1 = f.subset({"E1"})
    el = e1.ellipses[0]
    # looking along E1's plane at its centre (the plane contains the source): edge-on
    ratios = {}
    for ang in (0.0, 1.0, 30.0):
        a = np.radians(ang)
        d = np.cos(a) * el.major_axis + np.sin(a) * el.normal
        R = rotations_from_beams(d[None], np.zeros(1))
        t = np.array([[0.0, 0.0, 667.0]]) - R[0] @ el.center
        pa = analyse_poses(e1, R, t)
        ratios[ang] = pa.rank_ratio[0, 0]
        assert pa.view_angle_deg[0, 0] == pytest.approx(ang, abs=1e-6)
    assert ratios[0.0] < 1e-6 * ratios[30.0]  # rank lost exactly edge-on
    assert ratios[0.0] < ratios[1.0] < ratios[30.0]  # and approached continuously
    atlas = blind_spot_atlas(e1, AnalysisSettings(), step_deg=4.0)
    doc = atlas.to_dict()
    assert doc["attainable_rank"] == 5 and doc["singular_fraction_of_sphere"] == 1.0  # 5 numbers, 6 DOF
    worst = doc["worst_directions"][0]
    assert worst["responsible"][0]["id"] == "E1"
    assert worst["responsible"][0]["reason"] == "seen edge-on"
    assert worst["responsible"][0]["view_angle_deg"] < 2.0
    # the named direction lies in E1's plane (up to the perspective of the off-axis centre)
    assert abs(np.asarray(worst["beam_direction"]) @ el.normal) < np.sin(np.radians(4.0))
    assert worst["rank_ratio"] < 0.01 * doc["rank_ratio"]["median"]


def test_full_design_is_not_blind_where_one_ellipse_is(presets):
    """The paper's argument (§II.A.2): another feature covers each ellipse's singularity."""
    f = presets["ftrac_2005"]
    doc = blind_spot_atlas(f, AnalysisSettings(), step_deg=4.0).to_dict()
    assert doc["singular_fraction_of_sphere"] == 0.0
    assert doc["condition"]["worst"] < 2 * doc["condition"]["median"]
    assert doc["blind_fraction_of_sphere"]["E1"] > 0.01  # E1 alone does go blind somewhere
    named = {r["id"] for w in doc["worst_directions"] for r in w["responsible"]}
    assert named <= {"E1", "E2"}


def test_missing_feature_scores_worse(presets):
    f = presets["ftrac_2005"]
    settings = AnalysisSettings(poses=3000, seed=1)
    full = score_design(f, settings)
    for drop in ("E1", "L2", "B4"):
        less = score_design(f.subset(set(f.ids) - {drop}), settings)
        for key in ("translation_mm", "rotation_deg"):
            assert less.figures[key]["p95"] > full.figures[key]["p95"]
            assert less.figures[key]["worst"] > full.figures[key]["worst"]
        loss = next(p for p in full.per_feature if p["id"] == drop)["without"]
        assert loss["translation_loss"] > 1.0 and loss["rotation_loss"] > 1.0
    # the ellipses carry this design: losing one costs far more than losing a bead
    by = {p["id"]: p["without"]["translation_loss"] for p in full.per_feature}
    assert by["E1"] > 1.3 > by["B4"]


def test_thresholds_decide_the_verdict(presets):
    f = presets["ftrac_2005"]
    settings = AnalysisSettings(poses=500)
    ok = score_design(f, settings)
    assert ok.passed
    tight = score_design(f, settings, Thresholds(max_translation_mm=0.2))
    assert not tight.passed
    assert [c["passed"] for c in tight.checks] == [False, True, True]


def test_lines_alone_cannot_see_a_slide_along_them(presets):
    s = score_design(presets["ftrac_2005"], AnalysisSettings(poses=200))
    assert s.groups["lines"]["singular_fraction"] == 1.0
    assert s.groups["ellipses"]["singular_fraction"] == 0.0
    assert s.groups["points"]["translation_mm"]["p95"] > s.figures["translation_mm"]["p95"]


def test_predicted_errors_match_solver_monte_carlo(presets):
    """400 workspace images solved with no initial guess: the RMS error per axis is within
    20 % of the predicted (Cramér–Rao) RMS. (benchmarks/analysis_validation.py: 1000 poses.)"""
    f = presets["ftrac_2005"]
    e = 0.25
    R, t = workspace_poses(Workspace(), f.nominal_beam_direction, 400, seed=11)
    rng = np.random.default_rng(12)
    cam = Camera()
    obs = [simulate_observation(f, cam, R[i], t[i], e, rng) for i in range(len(R))]
    poses = solve_batch(f, obs, SolverOptions(noise=NoiseModel.from_segmentation_error(e)))
    assert all(p.converged for p in poses)
    dr, dt = pose_errors(np.array([p.rotation for p in poses]), np.array([p.translation_mm for p in poses]), R, t)
    pred = analyse_poses(f, R, t, cam, NoiseModel.from_segmentation_error(e), detail=False).overall
    actual = np.sqrt(np.mean(np.concatenate([dr, dt], 1) ** 2, 0))
    predicted = np.sqrt(np.mean(np.concatenate([pred.rotation_std_rad, pred.translation_std_mm], 1) ** 2, 0))
    ratio = predicted / actual
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def test_scaling_matches_the_solver(presets):
    f = presets["ftrac_mini"]
    R, t = isocentre_poses(np.array([[0.0, -1.0, 0.0]]), 667.0)
    m = analyse_poses(f, R, t, detail=False).overall
    info = total_information(feature_layout(f), Camera(), R, t)
    h = parameter_scale(f)
    sv = np.sqrt(np.linalg.eigvalsh(info[0] * np.outer(h, h)))[::-1]
    np.testing.assert_allclose(m.sigma[0], sv, rtol=1e-9)


def test_workspace_sampler_cone_whole_sphere_and_ranges(presets):
    from ftrac_design.analysis.sampling import angle_from

    f = presets["ftrac_2005"]
    nb = f.nominal_beam_direction
    R, t = workspace_poses(Workspace(), nb, 4000, seed=2)
    polar, _ = angle_from(nb, R[:, 2])
    assert polar.max() <= 25.0 + 1e-9 and polar.max() > 24.0
    # uniform over the cap: the share within 12.5° is the cap-area ratio
    share = (1 - np.cos(np.radians(12.5))) / (1 - np.cos(np.radians(25.0)))
    assert np.mean(polar <= 12.5) == pytest.approx(share, abs=0.03)
    assert np.all(np.abs(t[:, :2]) <= 25.0) and np.all(np.abs(t[:, 2] - 667.0) <= 25.0)
    Rs, _ = workspace_poses(Workspace(cone_deg=180.0), nb, 4000, seed=2)
    ps, _ = angle_from(nb, Rs[:, 2])
    assert ps.max() > 170.0 and np.mean(ps > 90.0) == pytest.approx(0.5, abs=0.03)  # whole sphere
    # roll range: the camera x axis stays within the allowed roll of the reference frame
    Rr, _ = workspace_poses(Workspace(roll_deg=(0.0, 90.0)), nb, 500, seed=3)
    R0 = rotations_from_beams(Rr[:, 2], np.zeros(len(Rr)))
    roll = np.degrees(np.arctan2(np.einsum("bi,bi->b", Rr[:, 0], R0[:, 1]), np.einsum("bi,bi->b", Rr[:, 0], R0[:, 0])))
    assert roll.min() >= -1e-9 and roll.max() <= 90.0 + 1e-9 and roll.max() > 85.0
