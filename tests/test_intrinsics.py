"""Intrinsics as parameters: closed-form derivatives vs finite differences, Cramér–Rao bounds,
and the joint estimation over several images (recovers the truth, refuses what the data
cannot determine), also through ``ftrac-design solve --estimate-intrinsics``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftrac_design.analysis.information import feature_layout
from ftrac_design.cli.main import main
from ftrac_design.features import write_features
from ftrac_design.features.model import Features, PointFeature
from ftrac_design.pose import Camera, NoiseModel, SolverOptions, compile_problem
from ftrac_design.pose.simulate import Workspace, simulate_observation
from ftrac_design.reconstruct import intrinsics as ik

CAM = Camera()
TINY = SolverOptions(noise=NoiseModel(1e-5, 1e-5, 1e-5))


def poses(n, seed=0, features=None):
    beam = np.array([0.0, -1.0, 0.0]) if features is None else features.nominal_beam_direction
    return Workspace().sample(n, beam, np.random.default_rng(seed))


def with_intr(intr):
    return Camera(
        intr[0] * CAM.pixel_size_mm[0],
        (CAM.pixel_size_mm[0], intr[0] * CAM.pixel_size_mm[0] / intr[1]),
        (intr[2], intr[3]),
    )


def test_information_rows_vs_finite_differences(features_2005):
    """Bead rows: ∂u/∂(fx, fy, ox, oy) of the projection; contour rows: the same along the image
    normal of the projected curve (from the curve's own tangent), times 1/σ."""
    layout = feature_layout(features_2005)
    R, t = poses(3)
    noise = NoiseModel()
    rows = ik.information_rows(layout, CAM, R, t, noise)[..., 6:]
    w = CAM.pixel_size_mm[0] / noise.point_mm
    P2 = 2 * layout.n_points
    h = 1e-3
    for b in range(3):

        def q(intr, X):
            return with_intr(intr).project(X @ R[b].T + t[b])

        fd = np.zeros((len(layout.X), 2, 4))
        for j in range(4):
            d = np.zeros(4)
            d[j] = h
            fd[:, :, j] = (q(CAM.intrinsics + d, layout.X) - q(CAM.intrinsics - d, layout.X)) / (2 * h)
        uvrow = np.tile([0, 1], layout.n_points)
        assert np.allclose(rows[b, :P2], w * fd[np.arange(P2), uvrow], rtol=1e-6, atol=1e-9)
        tan = q(CAM.intrinsics, layout.X[P2:] + 1e-4 * layout.T[P2:]) - q(
            CAM.intrinsics, layout.X[P2:] - 1e-4 * layout.T[P2:]
        )
        nrm = np.stack([-tan[:, 1], tan[:, 0]], -1) / np.linalg.norm(tan, axis=-1, keepdims=True)
        expect = w * np.einsum("ni,nij->nj", nrm, fd[P2:])
        assert np.allclose(rows[b, P2:], expect, rtol=1e-5, atol=1e-8)


def test_solver_residual_jacobian_vs_finite_differences(features_2005):
    """∂ρ/∂(fx, fy, ox, oy) of the solver's whitened residuals (whitening held, as in an LM step)."""
    rng = np.random.default_rng(4)
    R, t = poses(1, 4)
    obs = simulate_observation(features_2005, CAM, R[0], t[0], 0.25, rng)
    prob = compile_problem(features_2005, [obs], NoiseModel())
    t1 = t + [0.3, -0.2, 2.0]  # off the solution: residuals ≠ 0
    rho, _, K, W = ik.residuals(prob, R, t1)
    h = 1e-3
    base = prob.intr.copy()
    for j in range(4):
        d = np.zeros(4)
        d[j] = h
        prob.intr[:] = base + d
        a = ik.residuals(prob, R, t1, W)[0]
        prob.intr[:] = base - d
        b = ik.residuals(prob, R, t1, W)[0]
        prob.intr[:] = base
        assert np.allclose(K[0, :, j], (a - b)[0] / (2 * h), rtol=1e-4, atol=1e-6 * np.abs(K[0, :, j]).max())


def test_crb_structure(features_2005):
    R, t = poses(50)
    one = ik.crb(features_2005, CAM, R, t)
    ten = ik.crb(features_2005, CAM, R, t, images=10)
    assert np.allclose(ten.std, one.std / np.sqrt(10))
    # freeing the intrinsics can only loosen the pose; depth most, f and t_z nearly one direction
    assert np.all(one.pose_std >= one.pose_std_known * (1 - 1e-9))
    assert np.median(one.pose_std[:, 5] / one.pose_std_known[:, 5]) > 10
    assert np.median(np.abs(one.corr_tz[:, 0])) > 0.99
    f_only = ik.crb(features_2005, CAM, R, t, params=("f",))
    assert np.all(f_only.std[:, 0] <= one.std[:, 0] * (1 + 1e-9))


def images(features, n, seed=0, e=0.0, camera_used=None):
    R, t = poses(n, seed, features)
    rng = np.random.default_rng(seed)
    return [simulate_observation(features, CAM, R[i], t[i], e, rng, solve_camera=camera_used) for i in range(n)], R, t


@pytest.mark.parametrize("which", ["f", "f,o", "all"])
def test_joint_estimation_recovers_true_intrinsics(features_2005, which):
    off = (3.0, -2.0) if which != "f" else (0.0, 0.0)
    obs, R, t = images(features_2005, 4, camera_used=CAM.perturbed(4.0, (0, 0), off))
    est = ik.estimate(features_2005, obs, params=ik.PARAMETER_SETS[which], options=TINY)
    assert est.ok, est.reason
    assert np.allclose(est.intrinsics, CAM.intrinsics, atol=1e-6)
    assert np.allclose(est.t, t, atol=1e-6) and np.allclose(est.R, R, atol=1e-9)
    assert est.camera.focal_length_mm == pytest.approx(1000.0, abs=1e-6)


def test_joint_estimation_refuses_a_model_that_does_not_fit(features_2005):
    obs, _, _ = images(features_2005, 4, camera_used=CAM.perturbed(4.0, (0, 0), (3.0, -2.0)))
    est = ik.estimate(features_2005, obs, params=("f",), options=TINY)
    assert not est.ok and "times the noise model" in est.reason


def test_joint_estimation_refuses_one_image_and_weak_data(features_2005):
    obs, _, _ = images(features_2005, 3)
    one = ik.estimate(features_2005, obs[:1], options=TINY)
    assert not one.ok and "at least 2" in one.reason
    weak = ik.estimate(features_2005, obs)  # the default 0.25 mm noise model
    assert not weak.ok and "bound f only" in weak.reason and weak.std[0] > 20


def test_joint_estimation_refuses_a_degenerate_set():
    """A plane seen from one direction (however many images) cannot fix f and the principal
    point (a homography has 8 degrees of freedom, pose + f, ox, oy are 9): rank test."""
    g = np.array([[x, 0.0, z] for x in (-15, 0, 15) for z in (-20, 0, 20)])
    plane = Features(
        "plane",
        None,
        None,
        np.array([0.0, -1.0, 0.0]),
        points=tuple(PointFeature(f"B{i}", c, 2.0) for i, c in enumerate(g)),
    )
    R, t = poses(1, 2)
    obs = [simulate_observation(plane, CAM, R[0], t[0] + [d, -d, 0.0], 0.0) for d in (0.0, 3.0, 6.0)]
    est = ik.estimate(plane, obs, params=ik.PARAMETER_SETS["f,o"], options=TINY)
    assert not est.ok and "rank-deficient" in est.reason


def test_cli_solve_estimate_intrinsics(tmp_path, features_2005, capsys):
    write_features(tmp_path / "f.json", features_2005)
    obs, _, _ = images(features_2005, 3, camera_used=CAM.perturbed(3.0, (0, 0), (2.0, 1.0)))
    (tmp_path / "obs.jsonl").write_text("".join(json.dumps(o.to_dict()) + "\n" for o in obs))
    args = [
        "solve",
        "--features",
        str(tmp_path / "f.json"),
        str(tmp_path / "obs.jsonl"),
        "-o",
        str(tmp_path / "p.jsonl"),
        "--estimate-intrinsics",
        "f,o",
    ]
    assert main(args + ["--segmentation-error-mm", "1e-5"]) == 0
    lines = [json.loads(s) for s in (tmp_path / "p.jsonl").read_text().splitlines()]
    assert len(lines) == 3 and all(d["camera"]["focal_length_mm"] == pytest.approx(1000.0, abs=1e-6) for d in lines)
    assert main(args) == 1  # default noise: refused, poses still written
    assert "intrinsics not estimated" in capsys.readouterr().err
    assert all("camera" not in json.loads(s) for s in (tmp_path / "p.jsonl").read_text().splitlines())
