"""Intensity path: the smooth-background nuisance parameters (B-spline and polynomial), the
bound with them unknown (Schur complement), and the refinement's choice of background model."""

from __future__ import annotations

import numpy as np
import pytest

from ftrac_design.intensity import perturb, pixel_information, refine_intensity
from ftrac_design.intensity.background import Nuisance, TensorSpline, polynomial_basis, schur_information
from ftrac_design.pose import so3
from ftrac_design.pose.camera import Camera
from ftrac_design.xray import ImagingModel, anatomy, render


def test_tensor_spline_products_match_its_explicit_basis():
    """The separable products (N X, Nᵀ b, the banded Gram N W Nᵀ) equal the explicit basis's;
    the basis is a partition of unity and spans a cubic in each coordinate."""
    S = TensorSpline((37, 29), 8.0)
    D = S.dense()
    assert D.shape == (S.k, 37 * 29) and S.k == (5 + 3) * (4 + 3)
    np.testing.assert_allclose(D.sum(0), 1.0, atol=1e-12)
    rng = np.random.default_rng(0)
    X, b, w = rng.normal(size=(3, D.shape[1])), rng.normal(size=(2, S.k)), rng.uniform(0.1, 2.0, D.shape[1])
    np.testing.assert_allclose(S.apply(X), X @ D.T, atol=1e-12)
    np.testing.assert_allclose(S.synthesize(b), b @ D, atol=1e-12)
    ab, C = S.gram_banded(w), (D * w) @ D.T
    band = ab.shape[0] - 1
    for off in range(band + 1):  # every stored diagonal, and nothing beyond the band
        np.testing.assert_allclose(ab[band - off, off:], np.diagonal(C, off), atol=1e-12)
    assert np.abs(np.triu(C, band + 1)).max() == 0
    v, u = np.mgrid[0:37, 0:29] / 10.0
    cubic = (u**3 * v**2 - 2 * u * v**3 + v).ravel()
    assert np.abs(Nuisance(S, w).project(cubic)).max() < 1e-8 * np.abs(cubic).max()


@pytest.mark.parametrize("kind", ["spline", "polynomial"])
def test_schur_complement_equals_the_block_of_the_full_inverse(kind):
    """The pose information with gain and background unknown, (P J) W (P J)ᵀ, is the inverse
    of the pose block of the inverse of the joint information of (pose, gain, background)."""
    rng = np.random.default_rng(1)
    shape = (23, 31)
    n = shape[0] * shape[1]
    N = TensorSpline(shape, 9.0) if kind == "spline" else polynomial_basis(shape, 2).reshape(-1, n)
    Nd = N.dense() if kind == "spline" else N
    J, gain, w = rng.normal(size=(6, n)), rng.normal(size=(1, n)), rng.uniform(0.2, 3.0, n)
    A = np.concatenate([J, gain, Nd])
    joint = (A * w) @ A.T
    brute = np.linalg.inv(np.linalg.inv(joint)[:6, :6])
    F = schur_information(J, N, w, extra=gain)
    np.testing.assert_allclose(F, brute, rtol=1e-7, atol=1e-9 * np.abs(brute).max())
    # nuisance parameters can only cost information
    assert np.all(np.linalg.eigvalsh((J * w) @ J.T - F) > -1e-9 * np.abs(F).max())


def test_bound_grows_with_the_nuisance_space(features_2005, pose_2005):
    """Known background ≤ gain + quadratic ≤ gain + 12 px spline (it contains the quadratic)
    ≤ gain + 8 px spline (not nested in 12 px, but finer); the spline costs the fiducial
    some information, a few % on ftrac_2005."""
    R, t = pose_2005
    kw = dict(imaging=ImagingModel())
    known = pixel_information(features_2005, R, t, **kw)
    quad = pixel_information(features_2005, R, t, nuisance=True, **kw)
    s12 = pixel_information(features_2005, R, t, nuisance=True, background_spline_px=12.0, **kw)
    s8 = pixel_information(features_2005, R, t, nuisance=True, background_spline_px=8.0, **kw)
    assert np.all(known.std <= quad.std * (1 + 1e-9)) and np.all(quad.std <= s12.std * (1 + 1e-9))
    assert np.all(s12.std < s8.std) and np.all(s12.std < 1.2 * quad.std)


def test_spline_background_recovers_the_pose_under_a_smooth_background(features_2005, pose_2005):
    """Noise-free image over a smooth non-polynomial background (a broad Gaussian bump and a
    tilt): the spline model refines to the exact pose from 0.05° / 0.4 mm off, where the
    quadratic model is biased."""
    R, t = pose_2005
    im = ImagingModel(photons_per_px=None)
    V, U = np.mgrid[0:1024, 0:1024]
    uv = Camera().project((R @ features_2005.point_centers().T).T + t).mean(0)
    bg = 0.8 * np.exp(-((U - uv[0] - 40) ** 2 + (V - uv[1] + 30) ** 2) / (2 * 70.0**2)) + 1e-3 * (U - 512)
    img = render(features_2005, R, t, imaging=im, background=bg)
    R0, t0 = perturb(R, t, np.array([np.radians(0.05), -np.radians(0.05), np.radians(0.03), 0.02, -0.02, 0.4]))
    kw = dict(scales=(0.0,))
    spl = refine_intensity(features_2005, img.log_image, Camera(), R0, t0, im, background="spline", **kw)
    quad = refine_intensity(features_2005, img.log_image, Camera(), R0, t0, im, background="polynomial", **kw)
    err_s = np.r_[so3.angle(spl.rotation, R), np.abs(spl.translation_mm - t)]
    err_q = np.r_[so3.angle(quad.rotation, R), np.abs(quad.translation_mm - t)]
    assert spl.background_model == "spline" and spl.converged
    assert np.degrees(err_s[0]) < 2e-4 and err_s[1:3].max() < 2e-4 and err_s[3] < 5e-3
    assert err_q[3] > 3 * err_s[3]


def test_auto_background_takes_the_spline_on_a_clean_image_and_the_high_pass_over_clutter(features_2005, pose_2005):
    """``background="auto"``: clean noisy image → spline (the χ²/dof of its fit is ~1); over an
    anatomy-like background (bone edges, texture) → high-pass; both never worse than the start."""
    R, t = pose_2005
    im = ImagingModel()
    R0, t0 = perturb(R, t, np.array([0, 0, 0, 0.01, -0.01, 0.2]))
    kw = dict(polarity="dense_dark", scales=(0.0,), max_iterations=2)
    clean = render(features_2005, R, t, imaging=im, rng=np.random.default_rng(5))
    a = refine_intensity(features_2005, clean.raw, Camera(), R0, t0, im, **kw)
    assert a.background_model == "spline" and a.cost_end <= a.cost_start
    assert a.n_nuisance == 1 + len(a.background) and a.to_dict()["intensity"]["background"] == "spline"
    cluttered = render(features_2005, R, t, imaging=im, rng=np.random.default_rng(5), background=anatomy(seed=0))
    b = refine_intensity(features_2005, cluttered.raw, Camera(), R0, t0, im, **kw)
    assert b.background_model == "highpass" and b.cost_end <= b.cost_start
    with pytest.raises(ValueError):
        refine_intensity(features_2005, clean.raw, Camera(), R0, t0, im, background="wavelet", **kw)
