"""Intensity path: the simulator's pose derivative, the pixel-level bound, the refinement."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ftrac_design.features.model import Features, PointFeature
from ftrac_design.intensity import RoiModel, perturb, pixel_information, refine_intensity, roi_around
from ftrac_design.pose import so3
from ftrac_design.pose.camera import Camera
from ftrac_design.xray import ImagingModel, render


def test_bead_jacobian_matches_the_closed_form():
    """Point-sampled, unblurred bead: L = μ 2√(r² − m²), m the ray's distance from the centre P;
    ∂L/∂P = −2μ P⊥ / √(r² − m²) (P⊥ the part of P across the ray); ∂P/∂δ = δ × (P − t), ∂P/∂t = I."""
    r = 1.0
    f = Features(
        "b", None, None, np.array([0, -1.0, 0]), points=(PointFeature("B", np.array([3.0, -2.0, 4.0]), 2 * r),)
    )
    cam = Camera(1000.0, (0.44, 0.44), (64.0, 64.0))
    im = ImagingModel(
        image_shape=(128, 128),
        photons_per_px=None,
        supersample=1,
        focal_spot_mm=0.0,
        detector_blur_px=0.0,
        single_precision=False,
    )
    R = so3.exp(np.array([[0.3, -0.2, 0.5]]))[0]
    t = np.array([1.0, -2.0, 660.0])
    P = R @ f.points[0].center + t
    roi = roi_around(f, R, t, cam, im.image_shape)
    model = RoiModel(f, cam, im, roi)
    L, J = model.jacobian(R, t)
    v0, u0, h, w = roi
    V, U = np.mgrid[v0 : v0 + h, u0 : u0 + w]
    D = np.stack([(U - 64.0) * 0.44, (V - 64.0) * 0.44, np.full(U.shape, 1000.0)], -1)
    Dh = D / np.linalg.norm(D, axis=-1, keepdims=True)
    Pp = P - (Dh @ P)[..., None] * Dh
    m2 = (Pp**2).sum(-1)
    inside = m2 < (0.8 * r) ** 2
    mu = im.mu("steel")
    np.testing.assert_allclose(L[inside], mu * 2 * np.sqrt(r * r - m2[inside]), rtol=1e-9)
    dLdP = -2 * mu * Pp / np.sqrt(np.maximum(r * r - m2, 1e-12))[..., None]
    for j in range(3):
        e = np.eye(3)[j]
        rot = dLdP @ np.cross(e, P - t)
        # O(h²) of the 0.15 px difference step
        np.testing.assert_allclose(J[j][inside], rot[inside], rtol=1e-2, atol=1e-5)
        np.testing.assert_allclose(J[3 + j][inside], dLdP[..., j][inside], rtol=1e-2, atol=1e-5)
    assert inside.sum() > 20


def test_jacobian_agrees_with_differences_along_any_direction(features_2005, pose_2005):
    """The full model (body, wires, beads, pixel integration, blur): J·x equals the central
    difference along a random pose direction x (so the six columns compose as the solver's
    so(3) perturbation does)."""
    R, t = pose_2005
    im = ImagingModel(photons_per_px=None, single_precision=False)
    roi = roi_around(features_2005, R, t, Camera(), im.image_shape)
    model = RoiModel(features_2005, Camera(), im, roi)
    L, J = model.jacobian(R, t)
    x = np.array([0.4, -0.7, 0.3, 0.5, -0.4, 0.6]) * model.steps(t)  # ~0.15 px motion, like the steps
    model.freeze(R, t)
    Lp = model.log_image(*perturb(R, t, x))
    Lm = model.log_image(*perturb(R, t, -x))
    fd = (Lp - Lm) / 2
    lin = np.tensordot(x, J, 1)
    # sub-samples that cross a silhouette within a step make single pixels depart (the
    # 4 × 4-sampled model has √-kinks there, ~4 % of the norm; a wrong column or sign would
    # give ≥ 30 %)
    err = np.abs(lin - fd)
    assert np.abs(fd).max() > 0.02
    assert np.percentile(err, 99) < 0.05 * np.abs(fd).max()
    assert np.linalg.norm(lin - fd) < 0.07 * np.linalg.norm(fd)


def test_bound_scales_as_one_over_root_dose(features_2005, pose_2005):
    R, t = pose_2005
    lo = pixel_information(features_2005, R, t, imaging=ImagingModel(photons_per_px=2500.0))
    hi = pixel_information(features_2005, R, t, imaging=ImagingModel(photons_per_px=10000.0))
    np.testing.assert_allclose(lo.std / hi.std, 2.0, rtol=1e-9)
    assert np.all(lo.std > 0) and lo.std[5] > lo.std[3]  # depth is the weak axis
    with_bg = pixel_information(
        features_2005,
        R,
        t,
        imaging=ImagingModel(photons_per_px=10000.0),
        background=np.full((1024, 1024), 1.0),
    )
    np.testing.assert_allclose(with_bg.std / hi.std, math.exp(0.5), rtol=1e-9)  # e^{-1} of the counts
    nuis = pixel_information(features_2005, R, t, imaging=ImagingModel(photons_per_px=10000.0), nuisance=True)
    assert np.all(nuis.std >= hi.std * (1 - 1e-9))  # unknown gain/background cost information
    with pytest.raises(ValueError):
        pixel_information(features_2005, R, t, imaging=ImagingModel(photons_per_px=None))


def test_noise_free_image_refines_to_the_exact_pose(features_2005, pose_2005):
    R, t = pose_2005
    img = render(features_2005, R, t, imaging=ImagingModel(photons_per_px=None))
    rng = np.random.default_rng(0)
    ax, d = rng.normal(size=3), rng.normal(size=3)
    x = np.concatenate([np.radians(1.0) * ax / np.linalg.norm(ax), 2.0 * d / np.linalg.norm(d)])
    R0, t0 = perturb(R, t, x)
    res = refine_intensity(
        features_2005,
        img.log_image,
        Camera(),
        R0,
        t0,
        ImagingModel(photons_per_px=None),
        scales=(4.0, 2.0, 0.0),
    )
    assert res.converged and res.cost_end < 1e-6 * res.cost_start
    assert np.degrees(so3.angle(res.rotation, R)) < 1e-3
    assert np.abs(res.translation_mm - t).max() < 2e-3
    assert res.gain == pytest.approx(1.0, abs=1e-4)


def test_refinement_never_ends_worse_than_its_start(features_2005, pose_2005):
    R, t = pose_2005
    im = ImagingModel()
    img = render(features_2005, R, t, imaging=im, rng=np.random.default_rng(3))
    # from the true pose on a noisy image: it may only lower the objective
    res = refine_intensity(features_2005, img.raw, Camera(), R, t, im, polarity="dense_dark", scales=(0.0,))
    assert res.cost_end <= res.cost_start
    assert np.abs(res.translation_mm - t)[:2].max() < 0.01 and res.covariance is not None
    # from far off (10 mm across the view), with no coarse scale: whatever it does, never worse
    R0, t0 = perturb(R, t, np.array([0, 0, 0, 10.0, -6.0, 0]))
    far = refine_intensity(
        features_2005, img.raw, Camera(), R0, t0, im, polarity="dense_dark", scales=(0.0,), max_iterations=3
    )
    assert far.cost_end <= far.cost_start


def test_refine_track_result_replaces_the_pose(features_2005, pose_2005):
    """The ``track --refine intensity`` call: a converged track result comes back with the
    refined pose and an ``intensity`` diagnostic; a failed one unchanged."""
    from dataclasses import dataclass, field

    from ftrac_design.intensity import refine_track_result
    from ftrac_design.pose import Diagnostics
    from ftrac_design.pose.solver import Pose

    @dataclass
    class Result:  # the fields of segment.pipeline.TrackResult it uses
        pose: Pose
        polarity: str
        diagnostics: Diagnostics = field(default_factory=Diagnostics)

    R, t = pose_2005
    img = render(features_2005, R, t, imaging=ImagingModel(), rng=np.random.default_rng(2))
    R0, t0 = perturb(R, t, np.array([2e-4, -1e-4, 1e-4, 0.02, -0.01, 0.3]))
    start = Result(Pose(R0, t0, True, 0.1, np.eye(6), {}, 3), "dense-dark")
    out = refine_track_result(img.raw, features_2005, Camera(), start)
    assert out.diagnostics.intensity.cost_end <= out.diagnostics.intensity.cost_start
    assert np.abs(out.pose.translation_mm - t).max() < 0.1 < np.abs(t0 - t).max()
    assert out.pose.covariance.shape == (6, 6) and out.pose.converged
    # the cluster-robust covariance given out: on white Poisson noise, the pixel-level bound's
    # (with the refinement's gain and spline background unknown) within the estimate's spread
    bound = pixel_information(features_2005, R, t, imaging=ImagingModel(), nuisance=True, background_spline_px=12)
    np.testing.assert_allclose(np.sqrt(np.diag(out.pose.covariance)) / bound.std, 1.0, atol=0.3)
    failed = Result(Pose(R0, t0, False, np.nan, None, {}, 0, "not found"), "dense-dark")
    assert refine_track_result(img.raw, features_2005, Camera(), failed) is failed


def test_refine_track_result_keeps_the_feature_pose_when_the_fit_leaves_its_covariance(
    features_2005, pose_2005, monkeypatch
):
    """A refinement is taken only where it converged and stayed inside the feature path's
    pose's covariance (χ²₆ ≤ MOVE_CHI2): the same fit moved by 2 σ of that covariance in depth
    (χ²₆ = 4) replaces the pose, moved by 6 σ (36) or left unconverged it does not — the
    feature pose comes back as it was, the diagnostic saying why; a record without ``taken``
    (written before it was kept) reads as taken."""
    from dataclasses import dataclass, field
    from types import SimpleNamespace

    import ftrac_design.intensity.refine as refine_mod
    from ftrac_design.pose import Diagnostics
    from ftrac_design.pose.record import IntensityFit
    from ftrac_design.pose.solver import Pose

    @dataclass
    class Result:
        pose: Pose
        polarity: str
        diagnostics: Diagnostics = field(default_factory=Diagnostics)

    R, t = pose_2005
    cov = np.diag([1e-6, 1e-6, 1e-6, 0.01, 0.01, 0.25])  # depth σ 0.5 mm
    start = Result(Pose(R, t, True, 0.1, cov, {}, 3), "dense-dark")

    def fit_moving(dz_mm: float, converged: bool = True):
        def fake(*args, **kwargs):
            return SimpleNamespace(
                rotation=R, translation_mm=t + np.array([0.0, 0.0, dz_mm]), covariance=cov, converged=converged,
                cost_start=10.0, cost_end=5.0, iterations=4, gain=1.0, roi=(0, 0, 10, 10), n_nuisance=7, message="",
                robust_covariance=None,
            )  # fmt: skip

        return fake

    img = np.zeros((16, 16))
    monkeypatch.setattr(refine_mod, "refine_intensity", fit_moving(1.0))
    near = refine_mod.refine_track_result(img, features_2005, Camera(), start)
    assert near.diagnostics.intensity.taken and near.pose.translation_mm[2] == pytest.approx(t[2] + 1.0)
    for fake, why in ((fit_moving(3.0), "χ²₆ = 36"), (fit_moving(1.0, converged=False), "did not converge")):
        monkeypatch.setattr(refine_mod, "refine_intensity", fake)
        out = refine_mod.refine_track_result(img, features_2005, Camera(), start)
        assert out.pose is start.pose and not out.diagnostics.intensity.taken
        assert why in out.diagnostics.intensity.message
    old = {k: v for k, v in near.diagnostics.intensity.to_dict().items() if k != "taken"}
    assert Diagnostics.from_dict({"intensity": old}).intensity == IntensityFit(**old, taken=True)


def test_bound_matches_the_spread_of_a_simple_estimator():
    """One bead, tx alone unknown: the linearised weighted least-squares estimate from the
    true pose, Σ w J (Y − L) / Σ w J², scatters as the bound 1/√F_tx,tx predicts (200 noise
    draws: the sample std is good to ±5 %)."""
    f = Features("b", None, None, np.array([0, -1.0, 0]), points=(PointFeature("B", np.zeros(3), 2.0),))
    cam = Camera(1000.0, (0.44, 0.44), (32.0, 32.0))
    im = ImagingModel(image_shape=(64, 64), photons_per_px=2000.0)
    R, t = np.eye(3), np.array([0.05, -0.03, 667.0])
    bound = pixel_information(f, R, t, cam, im)
    sd_tx = 1 / math.sqrt(bound.information[3, 3])
    v0, u0, h, w = bound.roi
    L, J = RoiModel(f, cam, im, bound.roi).jacobian(R, t)
    wts = im.photons_per_px * np.exp(-L)
    est = []
    for k in range(200):
        Y = render(f, R, t, cam, im, rng=np.random.default_rng(100 + k)).log_image[v0 : v0 + h, u0 : u0 + w]
        est.append(float(np.sum(wts * J[3] * (Y - L)) / np.sum(wts * J[3] ** 2)))
    assert abs(np.mean(est)) < 3 * sd_tx / math.sqrt(200)
    assert np.std(est, ddof=1) == pytest.approx(sd_tx, rel=0.2)


def test_track_cli_call_form_is_forwarded(features_2005, pose_2005, monkeypatch):
    """cli/track.py calls refine_intensity(image, features, camera, track_result)."""
    import ftrac_design.intensity.refine as refine_mod

    seen = {}
    monkeypatch.setattr(refine_mod, "refine_track_result", lambda *a: seen.setdefault("args", a))

    class Res:
        pose = None

    image = np.zeros((8, 8))
    res = Res()
    refine_mod.refine_intensity(image, features_2005, Camera(), res)
    assert seen["args"][0] is image and seen["args"][1] is features_2005 and seen["args"][3] is res


def test_workspace_imaging_block_scales_as_one_over_root_dose(features_2005):
    """analyze --imaging's figures: the image-level σ at 4× the dose is exactly half (Poisson
    information ∝ dose), the feature-level σ does not change, so their ratio doubles; the
    feature-level σ equals the existing analysis's Cramér–Rao bound at the same poses."""
    from ftrac_design.analysis.information import feature_layout, total_information
    from ftrac_design.intensity.workspace import imaging_analysis
    from ftrac_design.pose.problem import NoiseModel

    a = imaging_analysis(features_2005, poses=2, seed=3, imaging=ImagingModel(photons_per_px=1e4))
    b = imaging_analysis(features_2005, poses=2, seed=3, imaging=ImagingModel(photons_per_px=4e4))
    np.testing.assert_allclose(b.image_std, a.image_std / 2, rtol=1e-9)
    np.testing.assert_allclose(b.feature_std, a.feature_std, rtol=1e-12)
    da, db = a.to_dict(), b.to_dict()
    for q in ("p50", "p95"):
        for ax in ("rx", "tz"):
            assert db["ratio_feature_to_image"][q][ax] == pytest.approx(2 * da["ratio_feature_to_image"][q][ax])
    F = total_information(feature_layout(features_2005), Camera(), a.R, a.t, NoiseModel.from_segmentation_error(0.25))
    std = np.sqrt(np.diagonal(np.linalg.inv(F), axis1=1, axis2=2))
    np.testing.assert_allclose(a.feature_std[:, 3:], std[:, 3:], rtol=1e-12)
    np.testing.assert_allclose(a.feature_std[:, :3], np.degrees(std[:, :3]), rtol=1e-12)
    assert np.all(da["image_std"]["p50"]["tz"] <= da["image_std"]["p95"]["tz"])


def test_analyze_imaging_cli_writes_the_block(tmp_path):
    """``analyze --imaging``: analysis.json gains the imaging block with the stated settings,
    the summary prints it, imaging.png is written; a bad dose is exit 2."""
    import json

    from click.testing import CliRunner

    from ftrac_design.cli.main import cli

    out = tmp_path / "an"
    r = CliRunner().invoke(
        cli,
        [
            "analyze",
            "ftrac_2005",
            "--poses",
            "100",
            "--atlas-step-deg",
            "15",
            "--score-images",
            "0",
            "--image-atlas-step-deg",
            "0",
            "--imaging",
            "--imaging-poses",
            "2",
            "--dose",
            "2e4",
            "-o",
            str(out),
        ],
    )
    assert r.exit_code in (0, 1), r.output
    doc = json.loads((out / "analysis.json").read_text())
    im = doc["imaging"]
    assert im["settings"]["poses"] == 2 and im["settings"]["photons_per_px"] == 2e4
    assert set(im["image_std"]["p50"]) == {"rx", "ry", "rz", "tx", "ty", "tz"}
    assert all(im["ratio_feature_to_image"]["p50"][a] > 1 for a in im["units"])
    assert "imaging.png" in doc["files"] and (out / "imaging.png").stat().st_size > 0
    assert "features/image p50" in r.output
    bad = CliRunner().invoke(cli, ["analyze", "ftrac_2005", "--imaging", "--dose", "-1", "-o", str(tmp_path / "b")])
    assert bad.exit_code == 2


def test_central_differences_from_forward_ones_equal_the_direct_central_ones(features_2005, pose_2005):
    """The polishing step's Jacobian: six backward renders added to the forward differences
    give the same central differences as twelve fresh renders (same frozen body pixels)."""
    R, t = pose_2005
    im = ImagingModel()
    model = RoiModel(features_2005, Camera(), im, roi_around(features_2005, R, t, Camera(), im.image_shape))
    L0 = model.log_image(R, t)
    _, Jf = model._differences(R, t, "log", central=False, value=L0)
    _, Jc = model._differences(R, t, "log", central=True, value=L0)
    Jr = model.central_from_forward(R, t, L0, Jf)
    np.testing.assert_allclose(Jr, Jc, rtol=0, atol=1e-9 * np.abs(Jc).max())
    assert model.body_flags is None  # the frozen flags are given back


def test_auto_schedule_smooths_only_from_a_far_start(features_2005, pose_2005):
    """``scales="auto"``: full resolution from a start a fraction of a pixel off (the feature
    path's), the coarse scales first from a start ~0.5° / 1 mm off; both reach the pose."""
    R, t = pose_2005
    im = ImagingModel(photons_per_px=None)
    img = render(features_2005, R, t, imaging=im)
    near = refine_intensity(
        features_2005,
        img.log_image,
        Camera(),
        *perturb(R, t, np.r_[np.radians([0.005] * 3), 0.005, -0.005, 0.05]),
        im,
    )
    assert {h[0] for h in near.history} == {0.0}
    far = refine_intensity(
        features_2005,
        img.log_image,
        Camera(),
        *perturb(R, t, np.r_[np.radians([0.3, -0.3, 0.25]), 0.6, -0.6, 0.5]),
        im,
        coarse_scales=(4.0, 2.0),
    )
    assert far.history[0][0] == 4.0 and far.history[-1][0] == 0.0
    for res in (near, far):
        assert np.degrees(so3.angle(res.rotation, R)) < 2e-3 and np.abs(res.translation_mm - t).max() < 5e-3
    with pytest.raises(ValueError):
        refine_intensity(features_2005, img.log_image, Camera(), R, t, im, scales="fast")


def test_refine_options_by_object_or_keyword_give_the_same_result(features_2005, pose_2005):
    import dataclasses

    from ftrac_design.intensity import RefineOptions

    R, t = pose_2005
    im = ImagingModel(photons_per_px=1e4)
    img = render(features_2005, R, t, Camera(), im, rng=np.random.default_rng(5))
    R0, t0 = perturb(R, t, np.r_[np.radians([0.02, -0.02, 0.01]), 0.05, -0.05, 0.2])
    opts = RefineOptions(polarity="dense_dark", scales=(0.0,), max_iterations=6)
    a = refine_intensity(features_2005, img.raw, Camera(), R0, t0, im, options=opts)
    b = refine_intensity(
        features_2005, img.raw, Camera(), R0, t0, im, polarity="dense_dark", scales=(0.0,), max_iterations=6
    )
    c = refine_intensity(
        features_2005,
        img.raw,
        Camera(),
        R0,
        t0,
        im,
        options=dataclasses.replace(opts, max_iterations=99),
        max_iterations=6,
    )
    for x in (b, c):
        assert np.array_equal(a.rotation, x.rotation) and np.array_equal(a.translation_mm, x.translation_mm)
    with pytest.raises(TypeError):
        refine_intensity(features_2005, img.raw, Camera(), R0, t0, im, sigma_step=0.1)


def test_a_step_that_carries_the_fiducial_onto_the_source_is_damped_not_fatal():
    """Where the pixels hardly tell depth, the undamped Levenberg–Marquardt step can be metres
    long: a trial pose with the fiducial at or behind the source lowers nothing, and the damping
    is raised until a step does (here the sixth try: 1 m → 196 mm towards the minimum at 500 mm)."""
    from types import SimpleNamespace

    import ftrac_design.intensity.refine as refine_mod
    from ftrac_design.xray.rays import BehindSourceError

    def cost(R, t):
        if t[2] <= 1.0:
            raise BehindSourceError("the pose puts part of the fiducial behind the source")
        return (t[2] - 500.0) ** 2, None, None, None, None

    state = SimpleNamespace(R=np.eye(3), t=np.array([0.0, 0.0, 600.0]), cst=100.0**2, prob=SimpleNamespace(cost=cost))
    H = np.eye(6)
    grad = np.array([0.0, 0.0, 0.0, 0.0, 0.0, -1000.0])
    taken, lam, dx = refine_mod._Refinement._damped_step(state, H, np.diag(H).copy(), grad, 1e-3)
    assert taken and 1.0 < state.t[2] < 600.0 and state.cst < 100.0**2
    assert lam == pytest.approx(1e-3 * 4**6 / 3) and dx[5] == pytest.approx(-1000.0 / (1 + 1e-3 * 4**6))


def test_a_fit_is_stopped_at_the_first_step_that_leaves_where_its_answer_could_be_used(features_2005, pose_2005):
    """``within``: the fit stops, not converged, at the first step outside it; a region that
    holds every step changes nothing. ``refine_track_result`` passes the feature pose's own
    covariance, so a fit that leaves it is stopped there and the feature pose given out."""
    from dataclasses import dataclass, field

    from ftrac_design.intensity import refine_track_result
    from ftrac_design.pose import Diagnostics
    from ftrac_design.pose.solver import Pose

    R, t = pose_2005
    im = ImagingModel()
    img = render(features_2005, R, t, imaging=im, rng=np.random.default_rng(2))
    R0, t0 = perturb(R, t, np.array([2e-4, -1e-4, 1e-4, 0.02, -0.01, 0.3]))
    args = (features_2005, img.raw, Camera(), R0, t0, im)
    free = refine_intensity(*args, polarity="dense_dark", scales=(0.0,))
    held = refine_intensity(*args, polarity="dense_dark", scales=(0.0,), within=lambda R_, t_: True)
    assert free.converged and held.converged and held.message == free.message
    assert np.array_equal(held.translation_mm, free.translation_mm) and np.array_equal(held.rotation, free.rotation)
    calls = []
    stopped = refine_intensity(
        *args, polarity="dense_dark", scales=(0.0,), within=lambda R_, t_: calls.append(t_.copy()) or False
    )
    assert not stopped.converged and len(calls) == 1 and "left the region" in stopped.message
    assert stopped.iterations == 1 < free.iterations

    @dataclass
    class Result:
        pose: Pose
        polarity: str
        diagnostics: Diagnostics = field(default_factory=Diagnostics)

    tight = Result(Pose(R0, t0, True, 0.1, np.eye(6) * 1e-12, {}, 3), "dense-dark")
    out = refine_track_result(img.raw, features_2005, Camera(), tight)
    assert out.pose is tight.pose and not out.diagnostics.intensity.taken
    assert "left that pose's own covariance" in out.diagnostics.intensity.message


def test_robust_covariance_is_the_sandwich_and_the_model_covariance_where_the_noise_is_white():
    """One pixel a cluster: exactly H⁻¹ (Σ J_i J_iᵀ w_i² r_i²) H⁻¹ (the Huber–White form). Tiles
    of 8 px over white noise: the model's σ² H⁻¹ within the estimate's own spread. Over a
    residual correlated over a few pixels, as a model's missing blur or clutter leaves it, with
    a Jacobian as smooth as a rendered fiducial's: several times the white-noise figure."""
    from scipy.ndimage import gaussian_filter

    from ftrac_design.intensity.refine import robust_covariance

    rng = np.random.default_rng(5)
    h, w = 160, 200
    J = rng.normal(size=(6, h * w))
    wt = rng.uniform(0.5, 2.0, h * w)
    r = rng.normal(size=h * w) / np.sqrt(wt)
    H = (J * wt) @ J.T
    Hi = np.linalg.inv(H)
    hc0 = Hi @ ((J * (wt * r) ** 2) @ J.T) @ Hi
    assert np.allclose(robust_covariance(J, wt, r, (h, w), tile_px=1), hc0, rtol=1e-9, atol=0)
    white = robust_covariance(J, wt, r, (h, w))
    assert np.allclose(np.diag(white) / np.diag(Hi), 1.0, atol=0.2)

    def smooth_field():
        return gaussian_filter(rng.normal(size=(h, w)), 3.0).ravel()

    Js = np.stack([smooth_field() for _ in range(6)])
    rc = smooth_field()
    Hs = np.linalg.inv(Js @ Js.T)
    ones = np.ones(h * w)
    model = Hs * float(rc @ rc) / (h * w)  # the white-noise model's σ² H⁻¹
    assert np.all(np.diag(robust_covariance(Js, ones, rc, (h, w))) > 3 * np.diag(model))
