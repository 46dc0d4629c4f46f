"""benchmarks/readability.py's matched filter against closed forms.

White noise of σ read through a zero-mean template of unit norm has σ; a ball of profile
``a·s`` read by its own template gives ``a·‖s − s̄‖`` (the template is ``(s − s̄)/‖s − s̄‖``), so
its signal-to-clutter ratio on white noise is ``a·‖s − s̄‖ / σ``, up to the noise at the ball
and the ±1 px search for the sub-pixel phase.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import readability as rb  # noqa: E402


@pytest.mark.parametrize("radius, blur", [(3.4, 0.8), (3.4, 1.8), (1.7, 2.0)])
def test_template_zero_mean_unit_norm(radius, blur):
    t = rb.ball_template(radius, blur)
    assert t.shape[0] == t.shape[1] == 2 * math.ceil(radius + 3 * blur + 2) + 1
    assert abs(t.sum()) < 1e-9
    assert np.linalg.norm(t) == pytest.approx(1.0)
    # a ball is brightest at its centre: the template peaks there
    c = t.shape[0] // 2
    assert t[c, c] == t.max()


def _ball(radius: float, blur: float, half: int) -> np.ndarray:
    """A ball's blurred chord profile on a (2·half + 1)² window, built independently of the
    module: 16 sub-samples per pixel, scipy's Gaussian, pixel means."""
    sub = 16
    x = (np.arange((2 * half + 1) * sub) + 0.5) / sub - (half + 0.5)
    chord = 2.0 * np.sqrt(np.clip(radius**2 - x[:, None] ** 2 - x[None, :] ** 2, 0.0, None))
    chord = gaussian_filter(chord, blur * sub, mode="constant")
    return chord.reshape(2 * half + 1, sub, 2 * half + 1, sub).mean(axis=(1, 3))


@pytest.mark.parametrize("radius, blur", [(3.4, 0.8), (3.4, 1.8), (1.7, 2.0)])
def test_template_is_the_ball_profile(radius, blur):
    t = rb.ball_template(radius, blur)
    s = _ball(radius, blur, t.shape[0] // 2)
    s = s - s.mean()
    assert float((s / np.linalg.norm(s) * t).sum()) > 1 - 1e-5


def test_ball_on_white_noise_reads_its_closed_form():
    rng = np.random.default_rng(5)
    radius, blur, sigma = 3.4, 1.8, 2.0
    half = rb.ball_template(radius, blur).shape[0] // 2
    s = _ball(radius, blur, half)
    img = rng.normal(0.0, sigma, (400, 400))
    uv = np.array([[120.0, 140.0], [200.0, 150.0], [280.0, 160.0], [150.0, 260.0], [250.0, 270.0]])
    amplitude = 2.0
    for u, v in uv.astype(int):
        img[v - half : v + half + 1, u - half : u + half + 1] += amplitude * s
    z = rb.clutter_z(img, uv, np.full(len(uv), radius), blur)
    expected = amplitude * np.linalg.norm(s - s.mean()) / sigma
    assert 10 < expected < 40
    # the noise at the ball (unit σ in z) and the ±1 px search for the phase
    assert np.all(np.abs(z - expected) < 3.0), (z, expected)


def test_noise_alone_reads_no_ball():
    rng = np.random.default_rng(6)
    img = rng.normal(0.0, 3.0, (300, 300))
    uv = np.array([[100.0, 100.0], [150.0, 120.0], [200.0, 180.0], [120.0, 200.0]])
    z = rb.clutter_z(img, uv, np.full(len(uv), 3.4), 1.2)
    # the largest of 9 neighbouring responses of unit-σ noise: rarely above 3.5
    assert np.all(z < 3.5), z
    assert rb.readable(list(z), 4.0) == 0


def test_clutter_measured_where_the_field_is_exposed():
    rng = np.random.default_rng(7)
    img = rng.normal(0.0, 1.0, (300, 300))
    # an unexposed half of constant value would shrink the spread if it were counted
    img[:, 160:] = 0.0
    valid = np.zeros(img.shape, bool)
    valid[:, :160] = True
    uv = np.array([[60.0, 100.0], [100.0, 150.0], [80.0, 200.0]])
    z_masked = rb.clutter_z(img, uv, np.full(3, 3.4), 1.0, valid)
    z_all = rb.clutter_z(img, uv, np.full(3, 3.4), 1.0)
    assert np.all(np.abs(z_masked) < 3.5)
    assert np.max(np.abs(z_all)) >= np.max(np.abs(z_masked))


def test_density_polarity():
    a = np.array([[100.0, 10.0]])
    # linear counts: the denser (fewer counts) pixel reads larger
    d = rb.density(a, "linear", "dense-dark")
    assert d[0, 1] > d[0, 0]
    assert rb.density(a, "display", "dense-dark")[0, 1] > rb.density(a, "display", "dense-dark")[0, 0]
    assert rb.density(a, "display", "dense-bright")[0, 0] > rb.density(a, "display", "dense-bright")[0, 1]
