"""Whether a blob is shaped like a ball: the blurred-sphere fit's contrast and residual, and the
acceptance test that refuses a labelling resting on blobs that are not balls."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, so3
from ftrac_design.segment import TrackOptions
from ftrac_design.segment.acceptance import misshapen, misshapen_balls, small_balls
from ftrac_design.segment.beads import Beads, fit_beads, sphere_profile
from ftrac_design.segment.body import pose_ball_radii_px

OPTS = TrackOptions().acceptance


def _pixel_integrated_ball(centre, r: float, s: float, amplitude: float, size: int = 41, sup: int = 10) -> np.ndarray:
    """A ball drawn independently of the fit's model: the chord 2√(r² − ρ²) on a grid ``sup`` ×
    finer than the pixels, blurred by σ = ``s`` px and averaged over each pixel's area (an
    integration the model leaves out)."""
    h = 1.0 / sup
    ax = (np.arange(size * sup) + 0.5) * h - 0.5
    X, Y = np.meshgrid(ax - centre[0], ax - centre[1])
    chord = 2 * np.sqrt(np.maximum(r * r - X * X - Y * Y, 0.0))
    fine = gaussian_filter(chord, s / h, mode="constant")
    return amplitude * fine.reshape(size, sup, size, sup).mean(axis=(1, 3))


@pytest.mark.parametrize("sigma", [0.02, 0.002, 0.0002])
def test_a_ball_drawn_another_way_is_ball_shaped_at_any_snr(sigma):
    """A pixel-integrated blurred sphere over a tilted background, with noise σ from an SNR of
    ~30 to ~3000: the fit's contrast is the drawn ball's peak over σ (within 5 %), and the
    ball is not misshapen; at an SNR of ~30 its residual is the noise (RMS within 0.75–1.3 σ)."""
    c, r, s, amp = (20.3, 19.6), 3.4, 0.8, 0.1
    yy, xx = np.mgrid[:41, :41]
    img = _pixel_integrated_ball(c, r, s, amp) + 0.3 + 0.002 * xx - 0.001 * yy
    img = img + np.random.default_rng(5).normal(0, sigma, img.shape)
    b = fit_beads(img, np.array([[20.0, 20.0]]), r, s, sigma)
    peak = amp * float(sphere_profile(np.zeros((1, 1)), np.array([r]), np.array([s]))[0, 0])
    assert b.contrast[0] == pytest.approx(peak / sigma, rel=0.05)
    assert not misshapen(b, OPTS)[0]
    if sigma >= 0.02:
        assert 0.75 < b.rms[0] < 1.3


@pytest.mark.parametrize("level", [0.55, 0.7])
def test_a_ball_clipped_flat_is_fitted_to_its_flanks_when_its_clipped_pixels_are_censored(level):
    """A ball drawn independently of the model (as above) over a tilted background, its core
    clipped flat at ``level`` × its peak (a display window's black), with noise of 1/70 of its
    peak: fitted with the clipped pixels censored (at least as dense as shown), its amplitude
    is within 10 % of the drawn one and its radius within 5 %, its residual is the noise, and
    its centre is no further off than the unclipped ball's fit; fitted as if the plateau were
    the ball, it comes out at under 80 % of its amplitude (a wider, flatter ball; its robust
    residual does not show it)."""
    c, r, s, amp, sigma = (20.3, 19.6), 3.4, 0.8, 0.1, 0.005
    yy, xx = np.mgrid[:41, :41]
    drawn = _pixel_integrated_ball(c, r, s, amp)
    img = drawn + 0.3 + 0.004 * (xx - 20) + np.random.default_rng(11).normal(0, sigma, drawn.shape)
    free = fit_beads(img, np.array([[20.0, 20.0]]), r, s, sigma)
    clip = 0.3 + level * float(drawn.max())
    cen = img >= clip
    assert cen.sum() >= 9
    img = np.minimum(img, clip)
    got = fit_beads(img, np.array([[20.0, 20.0]]), r, s, sigma, censored=cen)
    plain = fit_beads(img, np.array([[20.0, 20.0]]), r, s, sigma)
    assert got.amplitude[0] == pytest.approx(amp, rel=0.1)
    assert got.radius[0] == pytest.approx(r, rel=0.05)
    assert got.rms[0] < 1.15
    off = np.hypot(*(got.uv[0] - c))
    assert off <= max(np.hypot(*(free.uv[0] - c)), 0.02) + 0.02
    assert plain.amplitude[0] < 0.8 * amp


@pytest.mark.parametrize("glyph", list("2045MG"))
def test_a_burned_in_glyph_is_not_ball_shaped(glyph):
    """One character of a frame grabber's burned-in text (OpenCV's Hershey font at a 1024² frame's
    size, anti-aliased, 60 σ above its background): a blurred-sphere fit started at its
    centroid leaves a residual far above the noise and above a tenth of its contrast. A
    straight stroke ("/", "I") is not among them: the robust fit leaves its ends out as it
    leaves out a wire under a ball, and fits its middle as a ball on a wire; of "IMG 20/40"
    six glyphs are told, more than the two misshapen balls a labelling may use."""
    m = np.zeros((41, 41), np.uint8)
    cv2.putText(m, glyph, (13, 29), cv2.FONT_HERSHEY_SIMPLEX, 0.7, 255, 2, cv2.LINE_AA)
    ys, xs = np.nonzero(m)
    w = m[ys, xs].astype(float)
    start = np.array([[np.sum(xs * w) / w.sum(), np.sum(ys * w) / w.sum()]])
    sigma = 0.01
    img = 0.6 * m / 255.0 + 0.2 + np.random.default_rng(7).normal(0, sigma, m.shape)
    b = fit_beads(img, start, 3.4, 0.8, sigma)
    assert misshapen(b, OPTS)[0], (b.rms[0], b.contrast[0])


def _case(rms, contrast):
    """A scene whose blobs have the given fit RMS and contrast, and a labelling using them all."""
    n = len(rms)
    z = np.zeros(n)
    beads = Beads(np.zeros((n, 2)), z, z, z, z, np.asarray(rms, float), z, np.asarray(contrast, float))
    ids = [f"B{i + 1}" for i in range(n)]
    lab = SimpleNamespace(match={k: i for i, k in enumerate(ids)}, obs=SimpleNamespace(points=dict.fromkeys(ids)))
    return SimpleNamespace(beads=beads), lab


def test_a_labelling_on_more_than_the_allowed_misshapen_blobs_is_refused():
    """Nine blobs: a bright ball 5 σ off the model at 2.5 % of its contrast and a faint one at
    its noise are balls; 3.5 σ at 35 % of the contrast, or any residual above 3 σ on a blob
    darker than its background, is not. Two such blobs are allowed, three refuse."""
    good = [1.0, 5.0, 1.2, 0.9, 1.1, 1.0]
    good_c = [30.0, 200.0, 8.0, 25.0, 40.0, 12.0]
    two = good + [1.0, 3.5, 4.0], good_c + [20.0, 10.0, -5.0]
    three = good + [3.5, 3.5, 4.0], good_c + [20.0, 10.0, -5.0]
    assert misshapen_balls(*_case(*two), OPTS) is None
    reason = misshapen_balls(*_case(*three), OPTS)
    assert reason is not None and "3 of the 9 beads" in reason
    # balls the labelling matched but the solve did not use are not counted
    scene, lab = _case(*three)
    del lab.obs.points["B7"]
    assert misshapen_balls(scene, lab, OPTS) is None


def _drawn_balls(radii: np.ndarray, blur: float, seed: int) -> Beads:
    """Each ball of radius ``radii[i]`` (px) drawn independently of the fit's model (as above),
    blurred by ``blur`` px, with noise 1/40 of its peak, and fitted from the assumed radius of a
    2 mm ball at the workspace's depth."""
    rng = np.random.default_rng(seed)
    fits = []
    for r in radii:
        c = (20.0 + rng.uniform(-0.5, 0.5), 20.0 + rng.uniform(-0.5, 0.5))
        img = _pixel_integrated_ball(c, float(r), blur, 0.1)
        sigma = float(img.max()) / 40
        fits.append(fit_beads(img + 0.3 + rng.normal(0, sigma, img.shape), np.array([c]), 3.4, 0.8, sigma))
    return Beads(*(np.concatenate([getattr(b, k) for b in fits]) for k in Beads.__dataclass_fields__))


def test_balls_smaller_than_the_pose_lets_them_look_are_refused():
    """nine_bead's balls drawn at the radii a pose 660 mm from the source gives them (focal
    length × radius / depth, ~3.4 px) under 0.6 px of blur: their fitted second moments are
    r²/5 + σ² within 15 %, and a labelling at that pose keeps them; the same balls under a pose
    at half the depth, which would show them twice as wide, are refused as too small, and so
    are they under the true pose when the design says its balls are 1.5 times as large. Fewer
    than three balls decide nothing."""
    features = compute_features(load_design("nine_bead"))
    cam = Camera()
    R = so3.exp(np.array([0.3, -0.2, 0.1]))
    near = SimpleNamespace(rotation=R, translation_mm=np.array([4.0, -3.0, 330.0]))
    true = SimpleNamespace(rotation=R, translation_mm=np.array([4.0, -3.0, 660.0]))
    radii = pose_ball_radii_px(features, cam, true)
    assert 3.0 < float(np.median(radii)) < 4.0
    beads = _drawn_balls(radii, 0.6, seed=3)
    assert beads.second_moment_px2 == pytest.approx(radii**2 / 5 + 0.36, rel=0.15)
    ids = [p.id for p in features.points]

    def lab(pose, used=ids):
        return SimpleNamespace(
            pose=pose, match={k: ids.index(k) for k in used}, obs=SimpleNamespace(points=dict.fromkeys(used))
        )

    scene = SimpleNamespace(beads=beads, features=features, camera=cam)
    assert small_balls(scene, lab(true), OPTS) is None
    reason = small_balls(scene, lab(near), OPTS)
    assert reason is not None and "9 beads used are smaller" in reason
    larger = replace(features, points=tuple(replace(p, diameter=1.5 * p.diameter) for p in features.points))
    assert small_balls(SimpleNamespace(beads=beads, features=larger, camera=cam), lab(true), OPTS) is not None
    assert small_balls(scene, lab(near, ids[:2]), OPTS) is None
