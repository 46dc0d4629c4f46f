"""Contour fits and their covariances; rotations; the simulation's error model."""

from __future__ import annotations

import math

import numpy as np

from ftrac_design.pose import so3
from ftrac_design.pose.fitting import conic_center_and_axes, conic_from_coefficients, conic_vector, fit_conic, fit_line
from ftrac_design.pose.simulate import Workspace, segmentation_noise


def _ellipse(n, cx=300.0, cy=200.0, a=80.0, b=30.0, phi=0.3, s0=0.0):
    s = s0 + np.linspace(0, 2 * np.pi, n, endpoint=False)
    c, si = math.cos(phi), math.sin(phi)
    x, y = a * np.cos(s), b * np.sin(s)
    return np.c_[cx + c * x - si * y, cy + si * x + c * y]


def test_conic_fit_is_exact_on_exact_points():
    f = fit_conic(_ellipse(24)[None])
    c, a, b = conic_center_and_axes(f.theta[0])
    centre = f.center[0] + f.scale[0] * c
    assert np.allclose(centre, [300, 200], atol=1e-9)
    assert np.isclose(a * f.scale[0], 80, atol=1e-9) and np.isclose(b * f.scale[0], 30, atol=1e-9)
    assert f.rss[0] < 1e-18


def test_conic_fit_covariance_matches_monte_carlo():
    """The information matrix predicts the scatter of the fitted conic (σ = 0.5 px)."""
    rng = np.random.default_rng(0)
    pts = _ellipse(24, a=60, b=20)
    n, sigma = 3000, 0.5
    noisy = pts[None] + rng.normal(0, sigma, (n, 24, 2))
    fits = fit_conic(noisy)
    ref = fit_conic(pts[None])
    # compare the fitted curves where it matters: Sampson distance of the true points to each fit
    from ftrac_design.pose.fitting import sampson_theta_jacobian

    q = (pts - fits.center[:, None]) / fits.scale[:, None, None]
    d, _ = sampson_theta_jacobian(fits.theta, q[..., 0], q[..., 1])
    d = d * fits.scale[:, None]  # px, (n, 24)
    # predicted: G Σ Gᵀ with Σ = σ² Λ⁻¹ at the true conic
    qr = (pts - ref.center[0]) / ref.scale[0]
    _, dd = sampson_theta_jacobian(ref.theta[0], qr[:, 0], qr[:, 1])
    G = dd @ ref.basis[0] * ref.scale[0]
    pred = sigma**2 * np.einsum("ij,jk,ik->i", G, np.linalg.inv(ref.info[0]), G)
    emp = d.var(0)
    assert np.all(np.abs(emp / pred - 1) < 0.15), emp / pred


def test_line_fit_and_its_information():
    rng = np.random.default_rng(1)
    s = np.linspace(-50, 50, 12)
    d = np.array([math.cos(0.4), math.sin(0.4)])
    pts = np.array([100.0, 50.0]) + s[:, None] * d
    f = fit_line(pts[None])
    assert abs(abs(f.normal[0] @ d)) < 1e-12
    assert f.rss[0] < 1e-20
    sigma = 0.3
    noisy = pts[None] + rng.normal(0, sigma, (4000, 12, 2))
    fits = fit_line(noisy)
    ang = np.arctan2(fits.normal[:, 1], fits.normal[:, 0])
    ang = np.unwrap(ang - ang[0]) + ang[0]
    pred_var_angle = sigma**2 / f.info[0, 0, 0]
    assert abs(ang.var() / pred_var_angle - 1) < 0.1


def test_conic_from_coefficients_is_the_same_curve():
    pts = _ellipse(30)
    f = fit_conic(pts[None])
    # back to pixel coefficients, then re-normalised
    s, m = f.scale[0], f.center[0]
    N = np.array([[1 / s, 0, -m[0] / s], [0, 1 / s, -m[1] / s], [0, 0, 1]])
    from ftrac_design.pose.fitting import conic_matrix

    C = N.T @ conic_matrix(f.theta[0]) @ N
    g = conic_from_coefficients(conic_vector(C)[None])
    c, a, b = conic_center_and_axes(g.theta[0])
    assert np.allclose(g.center[0] + g.scale[0] * c, [300, 200], atol=1e-8)
    assert np.isclose(a * g.scale[0], 80, rtol=1e-9)


def test_so3_round_trip_and_spread():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(200, 3))
    v *= (rng.uniform(0, np.pi - 1e-3, 200) / np.linalg.norm(v, axis=1))[:, None]
    R = so3.exp(v)
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-13)
    assert np.allclose(so3.log(R), v, atol=1e-9)
    # the scalar one-rotation path agrees with the batched one, down to the Taylor branch
    for vi in np.concatenate([v[:20], v[:5] * 1e-4, v[:5] * 1e-8, np.zeros((1, 3))]):
        assert np.allclose(so3.exp(vi[None]), so3.exp(np.stack([vi, vi]))[:1], atol=1e-15, rtol=0)
    S = so3.spread_rotations(96)
    assert np.allclose(np.linalg.det(S), 1.0)
    # evenly spread: no two seeds closer than 15°, every random rotation within 60° of one
    ang = so3.angle(S[:, None], S[None])
    ang[np.arange(96), np.arange(96)] = np.inf
    assert np.degrees(ang.min()) > 15
    Rr = so3.uniform_rotations(500, rng)
    assert np.degrees(so3.angle(Rr[:, None], S[None]).min(1).max()) < 60


def test_workspace_stays_in_its_cone():
    beam = np.array([0.0, -1.0, 0.0])
    R, t = Workspace(cone_deg=25).sample(5000, beam, np.random.default_rng(3))
    beams = R[:, 2, :]  # camera +z in F is the third row of R (F → X)
    ang = np.degrees(np.arccos(np.clip(beams @ beam, -1, 1)))
    assert ang.max() <= 25.0 + 1e-9 and ang.max() > 24.0
    assert np.all(np.abs(t[:, :2]) <= 25.0) and np.all(np.abs(t[:, 2] - 667) <= 25.0)


def test_segmentation_noise_is_the_papers_uniform_magnitude():
    rng = np.random.default_rng(4)
    d = segmentation_noise((200000,), 0.25, (0.5, 0.5), rng) * 0.5  # back to mm
    mag = np.linalg.norm(d, axis=1)
    assert mag.max() <= 0.25 + 1e-12
    assert abs(np.mean(mag) - 0.125) < 0.002  # uniform in [0, e]
    assert abs(d[:, 0].std() - 0.25 / math.sqrt(6)) < 0.001  # per-axis σ = e/√6
