"""The image path's reported uncertainty and its whole-image retry: the pose
covariance is the per-feature-type sandwich of :func:`ftrac_design.segment.noise.calibrated_covariance`
(components scale it exactly, the estimate does not move, and the z-scores of rendered
images are near unit), and a region whose answer is limited by the view itself is not
searched again on the whole image."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftrac_design.pose import Camera, Pose
from ftrac_design.pose.observation import Observation
from ftrac_design.pose.problem import NoiseModel, compile_problem, evaluate
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.pose.solver import SolverOptions, refine_pose
from ftrac_design.segment import TrackOptions, TrackResult, track_image
from ftrac_design.segment.detection import scales
from ftrac_design.segment.noise import calibrated_covariance
from ftrac_design.segment.region import resolvable_beads, view_limited
from ftrac_design.xray import render

#: the simulator's camera is a pinhole: no unmodelled distortion in the covariance
PINHOLE = TrackOptions(distortion_prior_mm=0.0)


@pytest.fixture(scope="module")
def rendered(f2005):
    features = f2005
    R, t = Workspace().sample(24, features.nominal_beam_direction, np.random.default_rng(3))
    return (
        R,
        t,
        [render(features, R[k], t[k], Camera(), rng=np.random.default_rng(300 + k)).raw for k in range(len(R))],
    )


def test_variance_components_scale_the_covariance_and_leave_the_estimate(f2005, rendered):
    features = f2005
    R, t, imgs = rendered
    one = track_image(
        imgs[0],
        features,
        Camera(),
        TrackOptions(
            variance_point=1, variance_line=1, variance_ellipse=1, distortion_prior_mm=0.0, contour_offset_px=0.0
        ),
    )
    two = track_image(
        imgs[0],
        features,
        Camera(),
        TrackOptions(
            variance_point=2, variance_line=2, variance_ellipse=2, distortion_prior_mm=0.0, contour_offset_px=0.0
        ),
    )
    mixed = track_image(imgs[0], features, Camera(), TrackOptions(distortion_prior_mm=0.0, contour_offset_px=0.0))
    assert one.pose.converged and two.pose.converged and mixed.pose.converged
    for r in (two, mixed):
        assert np.array_equal(r.pose.rotation, one.pose.rotation)
        assert np.array_equal(r.pose.translation_mm, one.pose.translation_mm)
    np.testing.assert_allclose(two.pose.covariance, 2 * one.pose.covariance, rtol=1e-9, atol=0)
    # equal unit components: ν/(ν − 2) s² (JᵀJ)⁻¹ of the whitened pose residuals, the
    # covariance of a Student-t error whose scale s² = χ²/ν is estimated from ν = m − 6
    prob = compile_problem(features, [one.observation], one.noise)
    ev = evaluate(prob, one.pose.rotation[None], one.pose.translation_mm[None], jac=True)
    J, rho = ev.J[0], ev.rho[0]
    nu = len(rho) - 6
    s2 = max(float(rho @ rho) / nu, 0.02)
    assert one.diagnostics.variance_factor == pytest.approx(s2, rel=1e-9)
    np.testing.assert_allclose(one.pose.covariance, nu / (nu - 2) * s2 * np.linalg.inv(J.T @ J), rtol=1e-6, atol=0)
    # components between 1 and 2: the covariance lies between 1 and 2 times the plain one
    # (Loewner order: the sandwich is linear and monotone in each component)
    c, c1 = mixed.pose.covariance, one.pose.covariance
    assert np.linalg.eigvalsh(2 * c1 - c).min() > -1e-9 * np.abs(c1).max()
    assert np.linalg.eigvalsh(c - c1).min() > -1e-9 * np.abs(c1).max()
    assert not np.allclose(c, c1) and not np.allclose(c, 2 * c1)


def test_pose_errors_are_near_unit_z_scores(f2005, rendered):
    """24 rendered workspace images of ftrac_2005 (fixed seeds): the error on every axis,
    divided by its reported σ, has a robust spread (the median |z| over 0.6745: 1 for a unit
    normal) between 0.4 and 1.3 (rz stays conservative, ~0.8; depth 1.04, which without the
    ellipses' offset in the covariance, ``TrackOptions.contour_offset_px``, read 1.99), and no
    error is beyond 5 σ. The spread is the median's, not the RMS: one image in 24
    with a 3.5 σ tilt error (a contour biased by the body's edge) moved the RMS of rx from 1.0
    to 1.4."""
    features = f2005
    R, t, imgs = rendered
    z = []
    for k, img in enumerate(imgs):
        res = track_image(img, features, Camera(), PINHOLE)
        if not res.pose.converged:
            continue
        dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R[k], t[k])
        z.append(np.r_[dr, dt] / np.sqrt(np.diag(res.pose.covariance)))
    assert len(z) >= 20
    spread = np.median(np.abs(z), 0) / 0.6745  # median |z| of a unit normal: 0.6745
    assert np.all(spread < 1.3) and np.all(spread > 0.4), spread
    assert np.abs(z).max() < 5.0


def _looking_down_a_line(features, depth_mm=650.0):
    """A pose at which line L1 points at the source: its balls all project onto the
    principal point (exactly: the line passes through the centre of projection)."""
    ln = features.lines[0]
    d = np.asarray(ln.end, float) - np.asarray(ln.start, float)
    d /= np.linalg.norm(d)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(d, z)
    s, c = np.linalg.norm(v), float(d @ z)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    R = np.eye(3) + K + K @ K * ((1 - c) / s**2) if s > 1e-12 else np.eye(3)
    t = -R @ np.asarray(ln.start, float) + depth_mm * z
    on = [
        k
        for k, p in enumerate(features.point_centers())
        if np.linalg.norm(np.cross(p - np.asarray(ln.start, float), d)) < 1e-6
    ]
    return R, t, on


def _result(R, t, n_points, error):
    pose = Pose(R, t, False, 1.0, None, {}, 0, error)
    obs = Observation(Camera(), {f"B{k + 1}": np.zeros(2) for k in range(n_points)}, {}, {}, origin="<test>")
    return TrackResult(pose, obs, {}, None, None, "dense-dark", None)


def test_resolvable_beads_leave_out_the_overlapping_ones(f2005):
    features = f2005
    cam, opts = Camera(), TrackOptions()
    R, t, on = _looking_down_a_line(features)
    assert len(on) >= 3
    sc = scales(features, cam, opts.finding)
    uv = cam.project(features.point_centers() @ R.T + t)
    n = resolvable_beads(features, cam, Pose(R, t, True, 1.0, None, {}, 0, None), (1024, 1024), sc)
    # the balls on L1 coincide; every other ball counts only if it is clear of all the others
    P = len(features.points)
    assert n <= P - len(on)
    np.testing.assert_allclose(uv[on], np.tile(cam.principal_point_px, (len(on), 1)), atol=1e-9)
    sep = 2 * sc.bead_radius_px + 2 * opts.blur_px
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(P) * 1e9
    assert n == int((dd.min(1) >= sep).sum())
    # moved off the image entirely: none
    far = resolvable_beads(
        features, cam, Pose(R, t + np.array([400.0, 0, 0]), True, 1.0, None, {}, 0, None), (1024, 1024), sc
    )
    assert far == 0


def test_view_limited_only_for_too_little_evidence_that_the_view_caps(f2005):
    features = f2005
    cam, opts = Camera(), TrackOptions()
    sc, accept = scales(features, cam, opts.finding), opts.acceptance
    R, t, on = _looking_down_a_line(features)
    need = min(opts.min_beads, len(features.points))
    capped = resolvable_beads(features, cam, Pose(R, t, True, 1.0, None, {}, 0, None), (1024, 1024), sc)
    err = "too little evidence: 3 beads could be used (need 5 to confirm the labelling)"
    assert view_limited(_result(R, t, 3, err), features, cam, (1024, 1024), sc, accept) == (capped < need)
    # other reasons, or a region answer that a larger field could change, search again
    assert not view_limited(_result(R, t, 3, "ambiguous identification: ..."), features, cam, (1024, 1024), sc, accept)
    Rw, tw = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(0))
    assert resolvable_beads(features, cam, Pose(Rw[0], tw[0], True, 1.0, None, {}, 0, None), (1024, 1024), sc) >= need
    assert not view_limited(_result(Rw[0], tw[0], 3, err), features, cam, (1024, 1024), sc, accept)


def test_unmodelled_distortion_adds_its_covariance(f2005, rendered):
    """The distortion term is Σₖ σ² Δθₖ Δθₖᵀ with Δθ the least-squares pose shift of each
    mode's displacement of the observed features: the same estimate, the covariance larger
    by exactly that (a pinhole pose of an intensifier image is biased in depth)."""
    from ftrac_design.segment.noise import distortion_covariance

    features = f2005
    R, t, imgs = rendered
    plain = track_image(imgs[1], features, Camera(), PINHOLE)
    prior = track_image(imgs[1], features, Camera(), TrackOptions(distortion_prior_mm=1.5))
    assert plain.pose.converged and prior.pose.converged
    assert np.array_equal(plain.pose.translation_mm, prior.pose.translation_mm)
    extra = distortion_covariance(features, plain.observation, plain.pose, plain.noise, 1.5)
    np.testing.assert_allclose(
        prior.pose.covariance, plain.pose.covariance + extra, rtol=1e-9, atol=1e-12 * np.abs(extra).max()
    )
    # depth gains the most, and the term scales as σ²
    assert np.argmax(np.diag(extra)) == 5
    np.testing.assert_allclose(
        distortion_covariance(features, plain.observation, plain.pose, plain.noise, 3.0), 4 * extra, rtol=1e-9
    )


def test_the_distortion_term_follows_the_solver_where_a_contour_s_fit_is_fragile(f2005, displaced_by_mode):
    """An observation segmented from a pincushioned image (tests/data, its origin inside)
    with one ellipse read along a short, thin arc: its fitted conic — and so its whitening —
    changes with the displacement, so the undisplaced observation's Jacobian predicts a
    fifteenth of the depth shift. Each mode's shift in the term is the solver's own, solved
    from the pose on the displaced observation (depth within 3 %), and the pose's depth error
    from the image's 1.34 mm pincushion lies inside the covariance the term gives."""
    import json
    from pathlib import Path

    from ftrac_design.pose import NoiseModel, SolverOptions, observation_from_dict, refine_pose
    from ftrac_design.segment.noise import distortion_covariance

    d = json.loads((Path(__file__).parent / "data" / "distortion_arc_observation.json").read_text(encoding="utf-8"))
    obs = observation_from_dict(d["observation"])
    nd = d["noise"]
    noise = NoiseModel(nd["point_mm"], nd["line_mm"], nd["ellipse_mm"], tuple((k, v) for k, v in nd["points"].items()))
    R, t = np.array(d["pose"]["rotation"]), np.array(d["pose"]["translation_mm"])
    base = refine_pose(f2005, obs, R, t, SolverOptions(noise=noise))
    assert base.converged
    moved_z = []
    for k in range(4):
        moved = refine_pose(
            f2005, displaced_by_mode(obs, k), base.rotation, base.translation_mm, SolverOptions(noise=noise)
        )
        moved_z.append(float(moved.translation_mm[2] - base.translation_mm[2]))
    got = distortion_covariance(f2005, obs, base, noise, 1.0)
    want_var = sum((w * z) ** 2 for w, z in zip((1.0, 1.0, 0.4, 0.4), moved_z))
    assert abs(moved_z[0]) > 2.0  # the pincushion's mode moves it millimetres in depth
    assert np.sqrt(got[5, 5]) == pytest.approx(np.sqrt(want_var), rel=0.03)
    # the image's 1.34 mm of pincushion put the pose 5.0 mm too near: 3.7 mm per mm, within
    # 1.5 of the term's depth σ at 1 mm
    assert 5.0 / 1.34 < 1.5 * np.sqrt(got[5, 5])


def test_distortion_modes_are_the_closed_form():
    """1 mm at 100 mm from the principal point, cubic in the radius (pincushion) and a
    rotation growing with its square (S): at 50 mm, 0.125 mm radially / tangentially; the
    pincushion's centre moved along u and v (−∂/∂c of |p − c|²(p − c), scaled to 1 mm at
    100 mm along the move: ⅓ mm across it)."""
    from ftrac_design.segment.noise import distortion_modes

    cam = Camera(1000.0, (0.5, 0.5), (100.0, 200.0))
    uv = np.array([[100.0 + 100.0, 200.0], [100.0, 200.0 + 200.0], [100.0, 200.0], [300.0, 200.0]])
    pin, s, cu, cv = distortion_modes(cam, uv, 100.0)  # 50 mm, 100 mm, centre, 100 mm
    np.testing.assert_allclose(pin, [[0.25, 0.0], [0.0, 2.0], [0.0, 0.0], [2.0, 0.0]], atol=1e-12)  # px
    np.testing.assert_allclose(s, [[0.0, 0.25], [-2.0, 0.0], [0.0, 0.0], [0.0, 2.0]], atol=1e-12)
    np.testing.assert_allclose(cu[1:], [[2 / 3, 0.0], [0.0, 0.0], [2.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(cv[1:], [[0.0, 2.0], [0.0, 0.0], [0.0, 2 / 3]], atol=1e-12)


def test_student_t_factor_makes_the_mean_chi2_of_the_error_six(f2005):
    """Nine balls (ν = 18 − 6 = 12 residual dof), Gaussian noise at exactly the model's σ,
    1,000 seeded draws refined from the truth: the error's χ² under the reported covariance,
    s² (JᵀJ)⁻¹ · ν/(ν − 2) with unit components, averages 6 (the pose's dimension), as the
    covariance of a Student-t error must (E[6 F(6, ν)] = 6 ν/(ν − 2)); with s² (JᵀJ)⁻¹ alone it
    would average 7.2, 8 standard errors away (6.01 ± 0.14 measured)."""
    features, cam = f2005, Camera()
    noise = NoiseModel(point_mm=0.2, line_mm=0.2, ellipse_mm=0.2)
    unit = replace(TrackOptions().labelling.noise, variance_point=1.0)
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(5))
    R, t = R[0], t[0]
    uv = cam.project(features.point_centers() @ R.T + t)
    sigma_px = noise.point_mm / np.asarray(cam.pixel_size_mm)
    rng = np.random.default_rng(6)
    opts = SolverOptions(noise=noise)
    c2 = []
    for _ in range(1000):
        pts = uv + rng.normal(size=uv.shape) * sigma_px
        obs = Observation(cam, {p.id: pts[k] for k, p in enumerate(features.points)}, {}, {}, origin="<test>")
        pose = refine_pose(features, obs, R, t, opts)
        assert pose.converged
        s2 = calibrated_covariance(features, obs, pose, noise, unit)
        assert s2 is not None
        dr, dt = pose_errors(pose.rotation, pose.translation_mm, R, t)
        e = np.r_[dr, dt]
        c2.append(float(e @ np.linalg.solve(pose.covariance, e)))
    c2 = np.asarray(c2)
    se = c2.std() / np.sqrt(len(c2))
    assert abs(c2.mean() - 6.0) < 3 * se, (c2.mean(), se)
    assert abs(c2.mean() * 12 / 10 - 6.0) > 5 * se
