"""Pixel-level localisation precision of balls and wires by size (xray/localization.py), and
the bead / wire error factors that carry it into the analysis and the optimiser."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from ftrac_design.design.presets import PRESETS_DIR
from ftrac_design.features.model import Features, PointFeature
from ftrac_design.pose.camera import Camera
from ftrac_design.xray.localization import bead_sigma_mm, size_error_factors, wire_sigma_mm
from ftrac_design.xray.model import ImagingModel
from ftrac_design.xray.render import expected_transmission

MODELS = PRESETS_DIR
DEPTH = 667.0


def _features(points=(), lines=()) -> Features:
    return Features(
        name="probe",
        source=None,
        sha256="-",
        nominal_beam_direction=np.array([0.0, -1.0, 0.0]),
        points=tuple(points),
        lines=tuple(lines),
    )


def test_sigma_scales_as_one_over_root_dose():
    lo, hi = ImagingModel(photons_per_px=1e4), ImagingModel(photons_per_px=4e4)
    assert bead_sigma_mm(1.0, DEPTH, imaging=hi) == pytest.approx(bead_sigma_mm(1.0, DEPTH, imaging=lo) / 2, rel=1e-12)
    assert wire_sigma_mm(0.3, DEPTH, imaging=hi) == pytest.approx(wire_sigma_mm(0.3, DEPTH, imaging=lo) / 2, rel=1e-12)


def test_bigger_parts_are_read_more_precisely():
    beads = [bead_sigma_mm(d, DEPTH) for d in (0.5, 0.8, 1.0, 1.2, 1.5, 2.0)]
    wires = [wire_sigma_mm(d, DEPTH) for d in (0.2, 0.25, 0.3, 0.4, 0.5)]
    assert all(a > b for a, b in zip(beads, beads[1:]))
    assert all(a > b for a, b in zip(wires, wires[1:]))


def test_thin_wire_limit_sigma_goes_as_one_over_diameter_squared():
    # far below the blur a wire is a line of strength μ·(area) ∝ d²: the image's slope, and so
    # √information, grows as d² (weak attenuation: T ≈ 1 − μ·chord)
    s1, s2 = wire_sigma_mm(0.02, DEPTH), wire_sigma_mm(0.04, DEPTH)
    assert np.log(s2 / s1) / np.log(2.0) == pytest.approx(-2.0, abs=0.03)


def test_no_dose_or_bad_size_is_refused():
    with pytest.raises(ValueError):
        bead_sigma_mm(1.0, DEPTH, imaging=ImagingModel(photons_per_px=None))
    with pytest.raises(ValueError):
        wire_sigma_mm(-0.3, DEPTH)


def test_wire_information_matches_a_brute_force_shift():
    # the module differentiates a pixel mean by its edge values; here: shift the profile by ±h
    # on a finer grid and difference the pixel means (h spans a few fine cells: the chord's
    # slope is singular at the wire's edge, so a much smaller h only samples that singularity)
    from scipy.ndimage import gaussian_filter1d

    from ftrac_design.xray.render import blur_sigma_px

    cam, im, d = Camera(), ImagingModel(), 0.3
    M, pix = cam.focal_length_mm / DEPTH, cam.pixel_size_mm[0]
    blur = float(np.mean(blur_sigma_px(cam, im, DEPTH)))
    fine, half, h = 256, 12, 5e-3
    info = []
    for p in range(8):

        def lam(s):
            x = (np.arange(2 * half * fine) + 0.5) / fine * pix - half * pix - p / 8 * pix - s
            T = np.exp(-im.mu("steel") * 2 * np.sqrt(np.clip((d / 2) ** 2 - (x / M) ** 2, 0, None)))
            T = gaussian_filter1d(T, blur * fine, mode="constant", cval=1.0, truncate=6.0)
            return T.reshape(2 * half, fine).mean(1)

        dl = (lam(h) - lam(-h)) / (2 * h)
        info.append(im.photons_per_px * np.sum(dl**2 / lam(0.0)) / pix)
    assert wire_sigma_mm(d, DEPTH, cam, im) == pytest.approx(1 / np.sqrt(np.mean(info)), rel=0.01)


def test_bead_sigma_matches_finite_differences_of_the_renderer():
    # the renderer (float64, 8×8 sub-samples) moved by ±20 µm at six sub-pixel offsets
    cam = Camera()
    im = dataclasses.replace(ImagingModel(), single_precision=False, supersample=8)
    M = cam.focal_length_mm / DEPTH
    f = _features(points=[PointFeature("B1", np.zeros(3), 1.0)])
    R, h = np.eye(3), 0.02
    info = []
    for ox, oy in np.random.default_rng(0).uniform(0, cam.pixel_size_mm[0] / M, (6, 2)):
        t = np.array([ox, oy, DEPTH])
        e = np.array([h, 0.0, 0.0])
        I0 = expected_transmission(f, R, t, cam, im).astype(float)
        dI = (
            expected_transmission(f, R, t + e, cam, im).astype(float)
            - expected_transmission(f, R, t - e, cam, im).astype(float)
        ) / (2 * h)
        info.append(im.photons_per_px * np.sum(dI**2 / I0) / M**2)  # object mm → detector mm
    assert bead_sigma_mm(1.0, DEPTH, cam, im) == pytest.approx(1 / np.sqrt(np.mean(info)), rel=0.08)


def test_size_error_factors_are_ratios_to_the_reference():
    assert size_error_factors(1.0, 0.3, 1.0, 0.3, DEPTH) == (1.0, 1.0)
    assert size_error_factors(None, None, 1.0, 0.3, DEPTH) == (1.0, 1.0)
    kb, kw = size_error_factors(0.8, 0.4, 1.0, 0.3, DEPTH)
    assert kb == pytest.approx(bead_sigma_mm(0.8, DEPTH) / bead_sigma_mm(1.0, DEPTH), rel=1e-12)
    assert kw == pytest.approx(wire_sigma_mm(0.4, DEPTH) / wire_sigma_mm(0.3, DEPTH), rel=1e-12)
    assert kb > 1.0 > kw


def test_simulated_observation_noise_scales_with_the_factors(f2005):
    from ftrac_design.pose.simulate import simulate_observation

    features = f2005
    R, t = np.eye(3), np.array([0.0, 0.0, DEPTH])
    cam = Camera()
    clean = simulate_observation(features, cam, R, t, 0.0, np.random.default_rng(1))
    one = simulate_observation(features, cam, R, t, 0.25, np.random.default_rng(1))
    two = simulate_observation(features, cam, R, t, 0.25, np.random.default_rng(1), error_factors=(2.0, 0.5))
    for k in clean.points:
        np.testing.assert_allclose(
            two.points[k] - clean.points[k], 2.0 * (one.points[k] - clean.points[k]), rtol=1e-9, atol=1e-12
        )
    for k in clean.lines:
        np.testing.assert_allclose(
            two.lines[k].points - clean.lines[k].points,
            0.5 * (one.lines[k].points - clean.lines[k].points),
            rtol=1e-9,
            atol=1e-12,
        )


def test_optimiser_charges_a_stock_size_for_its_image():
    from ftrac_design.analysis.poses import analyse_poses
    from ftrac_design.analysis.sampling import workspace_poses
    from ftrac_design.analysis.score import AnalysisSettings
    from ftrac_design.design.loader import parse_design
    from ftrac_design.features import compute_features
    from ftrac_design.optimize.evaluate import EvalSettings, evaluate_candidate
    from ftrac_design.optimize.space import apply_values

    base = tomllib.loads((MODELS / "ftrac_mini.toml").read_text())
    data = apply_values(base, {"wire.diameter": 0.4})
    kb, kw = size_error_factors(1.0, 0.4, 1.0, 0.3, float(base["analysis"].get("depth", DEPTH)))
    assert "bead_error_factor" not in data["analysis"]
    assert data["analysis"]["wire_error_factor"] == pytest.approx(kw, rel=1e-12)
    # back to the start's size: no factor is written
    assert "wire_error_factor" not in apply_values(base, {"wire.diameter": 0.3})["analysis"]
    s = AnalysisSettings(poses=200, seed=3)
    got = evaluate_candidate(data, EvalSettings(analysis=s))
    assert got["feasible"]
    # the same as the analysis with the wire's σ scaled by hand
    design = parse_design(data)
    f = compute_features(design)
    R, t = workspace_poses(s.workspace, f.nominal_beam_direction, s.poses, s.seed)
    noise = s.noise.scaled(1.0, kw)
    m = analyse_poses(f, R, t, s.camera, noise, s.contour, detail=False).overall
    assert got["figures"]["translation_p95_mm"] == pytest.approx(
        float(np.percentile(m.translation_rms_mm, 95)), rel=1e-12
    )
    # and the design file it becomes carries the factor into `analyze`
    from ftrac_design.analysis.subject import Subject, settings_for

    settings, _ = settings_for(Subject(f, design.analysis, None))
    assert AnalysisSettings().for_parts(design.analysis).error_factors == settings.error_factors
    assert settings.error_factors == (1.0, pytest.approx(kw, rel=1e-12))
