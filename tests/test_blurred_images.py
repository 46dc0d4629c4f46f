"""Blurred images: the blur as the balls show it, the blob detector's scale under that blur,
and wires too faint to measure point by point.

A ball's fit pins its image's second moment (r²/5 + σ² per axis), not the radius and the blur
apart; the image's blur is read from that moment at the expected radius. The Laplacian that
finds the balls widens with the blur beyond the default, as a blurred blob's scale does, so
that a blurred ball reads close to what a matched filter would read. A wire whose curvature
across it is under 3 noise σ at most of its points is measured on runs of it, each run moved
to the ridge as one."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import TrackOptions, identify
from ftrac_design.segment.beads import blob_response, blob_sigma
from ftrac_design.segment.detection import detect, fitted_blur, scales
from ftrac_design.segment.guided import guided_contours
from ftrac_design.segment.image import to_density
from ftrac_design.xray import ImagingModel, blur_sigma_px, render

OPTS = TrackOptions()


def _ball(radius_px: float, blur_px: float, n: int = 81) -> np.ndarray:
    """A sphere's projected chord (unit peak) of radius ``radius_px``, centred in an n × n
    image, blurred by a Gaussian of σ ``blur_px``."""
    y, x = np.mgrid[:n, :n] - n // 2
    rho2 = x * x + y * y
    chord = np.sqrt(np.maximum(radius_px**2 - rho2, 0.0)) / radius_px
    return gaussian_filter(chord, blur_px).astype(np.float32)


def _snr_at_centre(img: np.ndarray, radius_px: float, sigma_px: float) -> float:
    """The blob detector's response over its white-noise response (unit pixel σ) at the centre."""
    resp, _, _, nr = blob_response(img, radius_px, 1.0, sigma_px)
    c = img.shape[0] // 2
    return float(resp[c, c] / nr)


def test_the_blob_scale_is_the_default_at_the_default_blur_and_adds_the_extra_in_quadrature():
    """r/√2 (at least 0.8 px) with no extra blur; √(r²/2 + b²) with an extra blur b."""
    assert blob_sigma(3.4) == pytest.approx(3.4 / math.sqrt(2))
    assert blob_sigma(0.5) == pytest.approx(0.8)
    assert blob_sigma(3.4, 1.83) == pytest.approx(math.sqrt(3.4**2 / 2 + 1.83**2))


def test_the_scales_widen_the_blob_scale_only_beyond_the_default_blur(f2005):
    """At the default blur the detector keeps r/√2; at a 2 px blur it adds √(2² − 0.8²)."""
    sc = scales(f2005, Camera(), OPTS.finding)
    assert sc.blob_sigma_px == pytest.approx(blob_sigma(sc.bead_radius_px))
    wide = scales(f2005, Camera(), replace(OPTS.finding, blur_px=2.0))
    extra = math.sqrt(2.0**2 - OPTS.finding.blur_px**2)
    assert wide.blob_sigma_px == pytest.approx(blob_sigma(sc.bead_radius_px, extra))


@pytest.mark.parametrize("blur_px, gain", [(1.6, 1.10), (2.0, 1.20)])
def test_a_blurred_ball_reads_more_at_its_own_scale(blur_px, gain):
    """A 3.4 px ball under a 1.6 / 2 px blur, in white noise: at the blob scale widened by the
    blur beyond the default 0.8 px its SNR is ≥ 10 / 20 % above the default scale's, and at least 80 %
    of the matched filter's √Σs² (the bound no linear detector of it exceeds)."""
    r = 3.4
    img = _ball(r, blur_px)
    extra = math.sqrt(blur_px**2 - OPTS.finding.blur_px**2)
    at_default = _snr_at_centre(img, r, blob_sigma(r))
    at_own = _snr_at_centre(img, r, blob_sigma(r, extra))
    matched = float(np.sqrt((img.astype(float) ** 2).sum()))
    assert at_own >= gain * at_default
    assert 0.8 * matched <= at_own <= matched


@pytest.fixture(scope="module", params=[0.7, 1.8])
def blurred_scene(request, f2005):
    """A raw radiograph of ftrac_2005 with the detector's line spread σ = param px (a small
    focal spot), detected at the default blur; with the total blur at the fiducial."""
    R, t = Workspace().sample(1, f2005.nominal_beam_direction, np.random.default_rng(5))
    imaging = ImagingModel(focal_spot_mm=0.3, detector_blur_px=request.param, photons_per_px=3.0e4)
    rad = render(f2005, R[0], t[0], Camera(), imaging, rng=np.random.default_rng(5))
    g = to_density(rad.raw.astype(float), "dense-dark")
    su, sv = blur_sigma_px(Camera(), imaging, float(t[0][2]))
    return detect(g, f2005, Camera(), OPTS.finding), math.hypot(su, sv) / math.sqrt(2)


def test_the_image_blur_is_read_from_the_balls_second_moment(blurred_scene):
    """The blur read off the balls is within 0.3 px of the blur drawn, at the default blur and
    under a 1.8 px one; only the blurred image asks to be detected again at its own blur."""
    scene, truth = blurred_scene
    got = fitted_blur(scene)
    assert got is not None
    assert got == pytest.approx(truth, abs=0.3)
    again = got > max(OPTS.finding.blur_px * OPTS.finding.blur_redetect, 1.1)
    assert again == (truth > 1.5)


def _contours(scene, R, t, pool: float, tol_px: float = 1.0):
    """The guided contours at pose (R, t) with the default settings, pooling ``pool``
    correlation lengths per run (0: point by point only)."""
    c, sc = OPTS.labelling.contour, scene.scales
    corr = c.thin_factor * sc.ridge_sigma_px
    excl = np.full(len(scene.features.points), sc.bead_radius_px + 3 * sc.blur_px + 1.5)
    return guided_contours(
        scene, R, t, excl, tol_px, c.separation_px, c.guided_min_snr,
        pool_px=pool * corr, corr_px=corr, pool_min_snr=c.guided_pool_min_snr,
    )  # fmt: skip


@pytest.fixture(scope="module")
def faint_wires(f2005):
    """ftrac_2005 at 40 quanta a pixel under a 1.8 px detector blur, detected again at the
    blur its balls show (as the tracker does); with its pose."""
    R, t = Workspace().sample(1, f2005.nominal_beam_direction, np.random.default_rng(8))
    imaging = ImagingModel(focal_spot_mm=0.3, detector_blur_px=1.8, photons_per_px=40.0)
    rad = render(f2005, R[0], t[0], Camera(), imaging, rng=np.random.default_rng(8))
    g = to_density(rad.raw.astype(float), "dense-dark")
    blur = fitted_blur(detect(g, f2005, Camera(), OPTS.finding))
    return detect(g, f2005, Camera(), replace(OPTS.finding, blur_px=blur)), R[0], t[0]


def test_a_wire_too_faint_point_by_point_is_measured_on_runs(faint_wires):
    """An ellipse with too few points at 3 σ is measured on runs of it: at least six points,
    their median distance to the ellipse the true pose projects under 0.6 px; the ellipse
    measured point by point keeps its points."""
    scene, R, t = faint_wires
    alone = _contours(scene, R, t, pool=0.0)
    pooled = _contours(scene, R, t, pool=OPTS.labelling.contour.guided_pool)
    gained = set(pooled.ellipses) - set(alone.ellipses)
    assert gained
    truth = identify.curve_samples(scene.features, scene.camera, R, t)
    for fid in gained:
        q = pooled.ellipses[fid]
        d = np.linalg.norm(q[:, None] - truth[fid][1][None], axis=-1).min(1)
        assert len(q) >= 6
        assert float(np.median(d)) < 0.6
    for fid, q in alone.ellipses.items():
        np.testing.assert_array_equal(pooled.ellipses[fid], q)


@pytest.mark.parametrize("shift_mm", [(60.0, 0.0, 0.0), (0.0, -60.0, 0.0)])
def test_runs_on_bare_background_measure_no_wire(faint_wires, shift_mm):
    """The pose moved 60 mm across the view, its wires on the noise of bare background: no
    line or ellipse is measured, with the wide first-stage tolerance."""
    scene, R, t = faint_wires
    c = _contours(scene, R, t + np.array(shift_mm), pool=OPTS.labelling.contour.guided_pool, tol_px=2.0)
    assert not c.lines and not c.ellipses
