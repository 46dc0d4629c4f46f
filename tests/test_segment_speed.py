"""The segmentation's shortcuts give what the plain computation gives:
the blob peaks tested only at strong pixels equal those of a whole-image dilation, and the
remembered contour fits and residuals equal fresh ones."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ftrac_design.pose.fitting import fit_conic, fit_line
from ftrac_design.segment.beads import blob_candidates
from ftrac_design.segment.image import gaussian_kernels
from ftrac_design.segment.noise import cached_fit


def _blob_candidates_dense(img, radius_px, noise, max_count, min_snr):
    """The peak search with cv2.dilate over the whole image (the former implementation)."""
    sb = max(radius_px / np.sqrt(2.0), 0.8)
    g0, _, g2 = gaussian_kernels(sb)
    xx = cv2.sepFilter2D(img, cv2.CV_32F, g2, g0, borderType=cv2.BORDER_REPLICATE)
    yy = cv2.sepFilter2D(img, cv2.CV_32F, g0, g2, borderType=cv2.BORDER_REPLICATE)
    resp = -(xx + yy) * (sb * sb)
    nr = noise * sb * sb * float(np.sqrt(2 * (g2.astype(float) ** 2).sum() * (g0.astype(float) ** 2).sum()))
    k = max(int(round(radius_px)), 1)
    dil = cv2.dilate(resp, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1)))
    j, i = np.nonzero((resp >= dil) & (resp > min_snr * nr) & (xx < 0) & (yy < 0))
    val = resp[j, i]
    o = np.argsort(-val)[:max_count]
    return np.stack([i[o], j[o]], -1).astype(float), val[o] / nr


@pytest.mark.parametrize("seed", range(12))
def test_blob_peaks_equal_whole_image_dilation(seed):
    rng = np.random.default_rng(seed)
    img = rng.normal(size=(120, 150)).astype(np.float32)
    for _ in range(8):  # blobs, some at the border, some touching
        y, x = rng.integers(0, 120), rng.integers(0, 150)
        img[max(y - 3, 0) : y + 3, max(x - 3, 0) : x + 3] += rng.uniform(3, 20)
    r = float(rng.uniform(1.5, 6))
    snr = float(rng.choice([0.1, 2.0, 8.0]))  # 0.1: most pixels strong, the dilation path
    a = blob_candidates(img, r, 1.0, 40, snr, min_isotropy=0.0)
    b = _blob_candidates_dense(img, r, 1.0, 40, snr)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_remembered_fits_equal_fresh_ones():
    rng = np.random.default_rng(1)
    s = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    pts = np.stack([30 * np.cos(s) + 5, 18 * np.sin(s) - 2], -1) + rng.normal(0, 0.1, (40, 2))
    for fitter in (fit_conic, fit_line):
        f1, f2 = cached_fit(fitter, pts), cached_fit(fitter, pts.copy())
        assert f1 is f2  # same points: remembered
        g = fitter(pts)
        assert float(f1.rss) == float(g.rss) and int(f1.dof) == int(g.dof)
    moved = pts + 0.5
    assert float(cached_fit(fit_conic, moved).rss) == float(fit_conic(moved).rss)


def _problem_arrays(prob) -> dict:
    """The arrays of a compiled problem, by field."""
    from dataclasses import fields

    return {f.name: getattr(prob, f.name) for f in fields(prob) if isinstance(getattr(prob, f.name), np.ndarray)}


def test_a_remembered_compilation_equals_a_fresh_one(features_2005):
    """:func:`~ftrac_design.pose.compile_problem` remembers its last compilations by the
    observations' contents: an equal copy gets the same problem, and it equals a compilation
    made afresh (another noise object, equal in value, is not remembered); a contour moved
    by 1e-9 px, another noise model or another ellipse sampling compile anew."""
    from ftrac_design.pose import Camera, NoiseModel, compile_problem
    from ftrac_design.pose.observation import CurveObservation, Observation
    from ftrac_design.pose.simulate import Workspace, simulate_observation

    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(5))
    obs = simulate_observation(features_2005, Camera(), R[0], t[0], 0.2, np.random.default_rng(6))
    noise = NoiseModel()
    first = compile_problem(features_2005, [obs], noise)
    copy = Observation(
        obs.camera,
        {k: v.copy() for k, v in obs.points.items()},
        {k: CurveObservation(points=c.points.copy()) for k, c in obs.lines.items()},
        {k: CurveObservation(points=c.points.copy()) for k, c in obs.ellipses.items()},
        obs.origin,
    )
    assert compile_problem(features_2005, [copy], noise) is first
    fresh = compile_problem(features_2005, [obs], NoiseModel())
    assert fresh is not first
    a, b = _problem_arrays(first), _problem_arrays(fresh)
    assert a.keys() == b.keys() and len(a) > 10
    for k in a:
        assert np.array_equal(a[k], b[k], equal_nan=True), k
    eid = sorted(obs.ellipses)[0]
    copy.ellipses[eid] = CurveObservation(points=copy.ellipses[eid].points + 1e-9)
    moved = compile_problem(features_2005, [copy], noise)
    assert moved is not first and not np.array_equal(moved.e_theta, first.e_theta)
    assert compile_problem(features_2005, [obs], NoiseModel(ellipse_mm=0.2)) is not first
    assert compile_problem(features_2005, [obs], noise, ellipse_model_points=32) is not first


def test_the_unmodelled_terms_from_one_batch_equal_each_alone(f2005):
    """:func:`.noise.unmodelled_covariance` shifts the pose for the ellipses' offset and the
    four distortion modes in one batch: each term equals its own function's, and a zero σ
    leaves that term out."""
    from ftrac_design.pose import Camera
    from ftrac_design.pose.simulate import Workspace
    from ftrac_design.segment import track_image
    from ftrac_design.segment.noise import contour_offset_covariance, distortion_covariance, unmodelled_covariance
    from ftrac_design.xray import render

    R, t = Workspace().sample(1, f2005.nominal_beam_direction, np.random.default_rng(11))
    res = track_image(render(f2005, R[0], t[0], Camera(), rng=np.random.default_rng(11)).raw, f2005, Camera())
    assert res.pose.converged and res.observation.ellipses and res.observation.lines
    obs, pose, noise = res.observation, res.pose, res.noise
    offset, distortion = unmodelled_covariance(f2005, obs, pose, noise, 0.3, 1.5)
    np.testing.assert_allclose(offset, contour_offset_covariance(f2005, obs, pose, noise, 0.3), rtol=1e-12, atol=0)
    np.testing.assert_allclose(distortion, distortion_covariance(f2005, obs, pose, noise, 1.5), rtol=1e-12, atol=0)
    assert np.all(np.linalg.eigvalsh(offset) > -1e-15) and np.trace(distortion) > 0
    assert unmodelled_covariance(f2005, obs, pose, noise, 0.0, 1.5)[0] is None
    assert unmodelled_covariance(f2005, obs, pose, noise, 0.3, 0.0)[1] is None


def test_gaussian_kernels_are_made_once_and_cannot_be_changed():
    """The sampled Gaussian and its derivatives are remembered per scale and read-only (a
    caller that changed them would change every later filter)."""
    a, b = gaussian_kernels(1.35), gaussian_kernels(np.float64(1.35))
    assert all(x is y for x, y in zip(a, b))
    for k in a:
        with pytest.raises(ValueError):
            k[0] = 1.0
    g0, g1, g2 = a
    x = np.arange(-(len(g0) // 2), len(g0) // 2 + 1)
    assert float(g0.sum()) == pytest.approx(1.0, abs=1e-6)
    assert float((g1 * x).sum()) == pytest.approx(-1.0, abs=1e-5)
    assert float((g2 * x * x).sum()) == pytest.approx(2.0, abs=1e-5)
