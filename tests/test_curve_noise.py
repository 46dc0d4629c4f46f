"""A curve type's contour σ in the image path's noise model: the scatter about the curves' own
fits, pooled with a prior from the labelling's balls, so that a short arc — a conic through six
points keeps one degree of freedom — is not taken for a precise one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ftrac_design.pose import Camera
from ftrac_design.pose.fitting import fit_conic
from ftrac_design.pose.observation import CurveObservation, Observation
from ftrac_design.segment import TrackOptions
from ftrac_design.segment.beads import Beads
from ftrac_design.segment.noise import measured_noise

OPTS = TrackOptions().labelling.noise
PIX = 0.3


def _arc(n: int, rng: np.random.Generator, sigma_px: float) -> np.ndarray:
    """``n`` points on a quarter of an ellipse (semi-axes 60 and 35 px), moved along the normal
    by Gaussian noise of ``sigma_px``."""
    a, b = 60.0, 35.0
    th = np.linspace(0.2, 0.2 + math.pi / 2, n)
    p = np.stack([500 + a * np.cos(th), 400 + b * np.sin(th)], -1)
    nrm = np.stack([b * np.cos(th), a * np.sin(th)], -1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return p + nrm * rng.normal(0.0, sigma_px, n)[:, None]


def _balls(sigma_px: float, n: int = 5) -> tuple[Beads, dict[str, int]]:
    ones = np.ones(n)
    beads = Beads(
        uv=np.arange(2 * n, dtype=float).reshape(n, 2) * 20,
        radius=3.4 * ones,
        blur=0.8 * ones,
        amplitude=ones,
        sigma_px=sigma_px * ones,
        rms=ones,
        response=ones,
        contrast=10 * ones,
    )
    return beads, {f"B{i + 1}": i for i in range(n)}


def _ellipse_sigma_px(pts: np.ndarray, beads: Beads, match: dict[str, int]) -> float:
    obs = Observation(Camera(), {k: beads.uv[j] for k, j in match.items()}, {}, {"E1": CurveObservation(pts)})
    return measured_noise(obs, beads, match, PIX, 0.8, OPTS).ellipse_mm / PIX


def test_a_six_point_arc_s_sigma_is_its_scatter_pooled_with_the_balls_prior():
    """σ² = (rss + ν₀ (κ s̃)²) / (dof + ν₀) + n σ_sys² (px), s̃ the balls' median fit σ."""
    pts = _arc(6, np.random.default_rng(3), 0.3)
    f = fit_conic(pts)
    assert f.dof == 1
    beads, match = _balls(0.24)
    nu, kappa, sys = OPTS.curve_prior_dof, OPTS.curve_prior_scale, OPTS.sys_curve_px
    expect = math.sqrt((f.rss + nu * (kappa * 0.24) ** 2) / (f.dof + nu) + 6 * sys**2)
    assert nu > 0 and _ellipse_sigma_px(pts, beads, match) == pytest.approx(expect)


def test_without_a_ball_the_scatter_is_the_curves_own():
    pts = _arc(6, np.random.default_rng(3), 0.3)
    f = fit_conic(pts)
    beads, _ = _balls(0.24)
    expect = math.sqrt(f.rss / f.dof + 6 * OPTS.sys_curve_px**2)
    assert _ellipse_sigma_px(pts, beads, {}) == pytest.approx(expect)


def test_a_long_arc_s_sigma_is_its_own_scatter_whatever_the_balls_say():
    """80 contour points: the prior's few degrees of freedom barely move the estimate."""
    pts = _arc(80, np.random.default_rng(4), 0.3)
    f = fit_conic(pts)
    own = math.sqrt(f.rss / f.dof)
    for s_ball in (0.05, 0.6):
        beads, match = _balls(s_ball)
        random = math.sqrt(_ellipse_sigma_px(pts, beads, match) ** 2 - 80 * OPTS.sys_curve_px**2)
        assert random == pytest.approx(own, rel=0.15)


def test_short_arcs_are_seldom_given_a_third_of_their_noise():
    """Six points at 0.3 px of noise, balls whose fits see the same image: without the prior,
    a χ²₁ scatter puts the σ below a third of the truth in about a quarter of the draws
    (P(χ²₁ < 1/9) = 0.26); with it, in none."""
    rng = np.random.default_rng(11)
    beads, match = _balls(0.3 / OPTS.curve_prior_scale)
    low_own, low_model = 0, 0
    draws = 400
    for _ in range(draws):
        pts = _arc(6, rng, 0.3)
        f = fit_conic(pts)
        low_own += math.sqrt(f.rss / f.dof) < 0.1
        low_model += _ellipse_sigma_px(pts, beads, match) < 0.1
    assert 0.18 < low_own / draws < 0.34
    assert low_model == 0
