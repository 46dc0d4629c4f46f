"""Segmentation of rendered radiographs: beads, wire centre-lines, polarity, blur bias."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftrac_design.pose import Camera
from ftrac_design.pose.fitting import conic_matrix
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment.beads import fit_beads, sphere_profile
from ftrac_design.segment.image import detect_polarity, noise_sigma, to_density, top_hat
from ftrac_design.segment.pipeline import track_image
from ftrac_design.segment.ridges import ridge_points
from ftrac_design.xray import render


@pytest.fixture(scope="module")
def rendered(f2005):
    features = f2005
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(11))
    rad = render(features, R[0], t[0], Camera(), rng=np.random.default_rng(11))
    return features, rad


def test_sphere_profile_closed_forms():
    """The Hankel-form profile equals a brute-force 2-D convolution of the chord
    2√(r² − ρ²) with the Gaussian, and its integral is the ball's volume (4/3)π r³ (blur
    preserves the integral)."""
    from scipy.ndimage import gaussian_filter

    r, s, h = 3.0, 0.8, 0.02
    ax = np.arange(-8, 8 + h / 2, h)
    X, Y = np.meshgrid(ax, ax)
    chord = 2 * np.sqrt(np.maximum(r * r - X * X - Y * Y, 0))
    brute = gaussian_filter(chord, s / h, mode="constant")
    i0 = len(ax) // 2
    rho = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    idx = np.round(rho / h).astype(int) + i0
    assert np.allclose(sphere_profile(rho, np.array(r), np.array(s)), brute[i0, idx], atol=2e-3 * 2 * r)
    x = np.linspace(0, 12, 4000)
    S = sphere_profile(x, np.array(r), np.array(1.0))
    area = np.trapezoid(S * 2 * np.pi * x, x)
    assert area == pytest.approx(4 / 3 * np.pi * r**3, rel=2e-3)


def test_bead_fit_recovers_a_synthetic_ball_off_grid():
    """A blurred ball drawn from the model at a sub-pixel centre with a wire butting
    against it: the robust fit finds the centre to < 0.02 px (the wire is an outlier)."""
    H = W = 41
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    c = np.array([20.37, 19.81])
    img = 0.27 * sphere_profile(np.hypot(xx - c[0], yy - c[1]), np.array(3.4), np.array(0.8))
    wire = (np.abs(yy - c[1]) < 0.8) & (xx > c[0] + 3.4)
    img = img + 0.35 * wire
    rng = np.random.default_rng(0)
    img = (img + rng.normal(0, 0.005, img.shape)).astype(np.float32)
    b = fit_beads(img, np.array([[20.0, 20.0]]), 3.4, 0.8, 0.005)
    assert np.linalg.norm(b.uv[0] - c) < 0.02
    assert b.radius[0] == pytest.approx(3.4, abs=0.1)


def test_polarity_detected_for_raw_and_log(rendered):
    _, rad = rendered
    assert detect_polarity(rad.raw.astype(float), 7) == "dense-dark"
    assert detect_polarity(rad.log_image, 7) == "dense-bright"


def test_ridge_points_lie_on_the_projected_lines(rendered):
    """Steger points near each projected line (wires and beads only, no body), away from
    beads and other features, scatter ≤ 0.1 px about it with a bias ≤ 0.05 px."""
    features, rad0 = rendered
    bare = replace(features, body=None)
    rad = render(bare, rad0.rotation, rad0.translation_mm, Camera(), rng=np.random.default_rng(3))
    g = to_density(rad.raw.astype(float), "dense-dark")
    T = top_hat(g, 8)
    rp = ridge_points(T, 1.35, noise_sigma(T))
    beads = np.array(list(rad.truth["projected"]["points"].values()))
    far = np.min(np.linalg.norm(rp.uv[:, None] - beads[None], axis=-1), 1) > 7
    for lid, ln in rad.truth["projected"]["lines"].items():
        a, b = np.array(ln["start"]), np.array(ln["end"])
        d = (b - a) / np.linalg.norm(b - a)
        n = np.array([-d[1], d[0]])
        off = (rp.uv - a) @ n
        along = (rp.uv - a) @ d
        near = (np.abs(off) < 1.0) & (along > 5) & (along < np.linalg.norm(b - a) - 5) & far
        if near.sum() < 10:
            continue
        assert abs(np.median(off[near])) < 0.05, lid
        assert 1.4826 * np.median(np.abs(off[near] - np.median(off[near]))) < 0.1, lid


def _conic_distance(C: np.ndarray, uv: np.ndarray) -> np.ndarray:
    x = np.c_[uv, np.ones(len(uv))]
    Q = np.einsum("ni,ij,nj->n", x, C, x)
    return Q / np.linalg.norm(2 * (x @ C)[:, :2], axis=1)


def test_track_observation_matches_the_projection(rendered):
    """The observation that track segments: bead centres within 0.15 px of the projected
    centres, contour points within 0.1 px (RMS) of the projected lines and ellipses, and no
    shrinkage of the ellipses (mean signed distance |·| ≤ 0.05 px) — the body-edge blur bias
    is removed."""
    features, rad = rendered
    res = track_image(rad.raw, features, Camera())
    assert res.pose.converged, res.pose.error
    obs = res.observation
    truth = rad.truth["projected"]
    assert len(obs.points) >= 7
    for fid, uv in obs.points.items():
        assert np.linalg.norm(uv - np.array(truth["points"][fid])) < 0.15, fid
    for fid, c in obs.ellipses.items():
        C = conic_matrix(np.array(truth["ellipses"][fid]["conic"]))
        d = _conic_distance(C, c.points)
        cen = np.array([*truth["ellipses"][fid]["center"], 1.0])
        d *= np.sign(cen @ C @ cen)  # + inside
        assert np.sqrt(np.mean(d**2)) < 0.1, fid
        assert abs(np.mean(d)) < 0.05, fid
    for fid, c in obs.lines.items():
        a, b = np.array(truth["lines"][fid]["start"]), np.array(truth["lines"][fid]["end"])
        dvec = (b - a) / np.linalg.norm(b - a)
        off = (c.points - a) @ np.array([-dvec[1], dvec[0]])
        assert np.sqrt(np.mean(off**2)) < 0.1, fid
    # per-point quality is reported for every observed feature
    assert set(res.quality["points"]) == set(obs.points)
    assert set(res.quality["ellipses"]) == set(obs.ellipses)


def test_same_input_same_result(rendered):
    features, rad = rendered
    a = track_image(rad.raw, features, Camera())
    b = track_image(rad.raw, features, Camera())
    assert np.array_equal(a.pose.rotation, b.pose.rotation)
    assert np.array_equal(a.pose.translation_mm, b.pose.translation_mm)


def test_fast_selections_equal_numpy():
    """The noise MAD's binned median and the polarity's block-maxima k-th largest are
    shortcuts: they must give numpy's numbers exactly (ties, zeros, skew, tiny arrays)."""
    from ftrac_design.pose import so3
    from ftrac_design.segment.image import _kth_largest, _median

    rng = np.random.default_rng(5)
    for t in range(60):
        n = int(rng.integers(1, 60000))
        v = rng.normal(size=n).astype(np.float32)
        if t % 3 == 1:
            v = np.round(3 * v).astype(np.float32)  # many ties
        if t % 3 == 2:
            v[: n // 2] = 0
            v = np.abs(v) ** 3
        m = _median(v)
        assert m == np.median(v) and m.dtype == np.median(v).dtype
        a = np.maximum(v[: (n // 97) * 97].reshape(-1, 97) if n >= 97 else v[None], 0)
        ref = np.sort(a[a > 0])[::-1]
        assert _kth_largest(a, 16) == (float(ref[15]) if len(ref) >= 16 else 0.0)
    r = rng.normal(size=(50, 3))
    r[0] = 0
    import cv2

    assert np.allclose(so3.exp(r), np.array([cv2.Rodrigues(x)[0] for x in r]), atol=1e-14)


def test_bead_fit_models_a_blurred_wire_beside_the_ball():
    """A ball under 2 px of blur with a blurred wire passing 4.5 px from its centre (a broad
    band the plane cannot take up): the plain fit is pulled toward the wire; given the wire's
    shape (unit amplitude, its amplitude fitted) the centre comes out within 0.02 px."""
    H = W = 61
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    c = np.array([30.37, 29.81])
    s = 2.0
    img = 0.27 * sphere_profile(np.hypot(xx - c[0], yy - c[1]), np.array(3.4), np.array(s))
    # a straight wire along 15° through a point 4.5 px from the centre, its profile Gaussian
    n = np.array([np.sin(np.radians(15)), -np.cos(np.radians(15))])
    d = (xx - c[0]) * n[0] + (yy - c[1]) * n[1] - 4.5
    band = np.exp(-0.5 * (d / s) ** 2)
    img = img + 0.6 * band
    rng = np.random.default_rng(1)
    img = (img + rng.normal(0, 0.005, img.shape)).astype(np.float32)
    start = np.array([[30.0, 30.0]])
    plain = fit_beads(img, start, 3.4, s, 0.005, prior_scale=1000.0)
    modelled = fit_beads(img, start, 3.4, s, 0.005, prior_scale=1000.0, background=band)
    assert np.linalg.norm(plain.uv[0] - c) > 0.5  # 1.7 px
    assert np.linalg.norm(modelled.uv[0] - c) < 0.02  # 0.004 px
    assert modelled.sigma_px[0] < 0.01


def test_wire_profile_is_the_blurred_line_about_each_wire(f2005):
    """:func:`.body.wire_profile` beside a straight wire piece, away from the other wires:
    exp(−d²/2σ²) of the distance d to the projected piece, half that at a piece's end; 0
    beyond the patches asked for; and the balls' projected radius is f · r / Z (px)."""
    from ftrac_design.pose import Pose
    from ftrac_design.segment import identify
    from ftrac_design.segment.body import pose_bead_radius_px, wire_profile

    features, cam = f2005, Camera()
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(5))
    R, t = R[0], t[0]
    curves = identify.curve_samples(features, cam, R, t)
    others = {fid: pts for fid, (_, pts) in curves.items()}
    fid, (_, pts) = next((f, c) for f, c in curves.items() if c[0] == "line" and len(c[1]) > 40)
    from ftrac_design.segment.identify import project

    ends = project(cam, R, t, np.array([p for _, a, b in features.wire_pieces for p in (a, b)]))[0]
    rest = np.concatenate([p for f, p in others.items() if f != fid] + [ends])
    far = np.array([np.min(np.linalg.norm(rest - p, axis=1)) for p in pts])
    i = int(np.argmax(far[5:-5])) + 5
    assert far[i] > 12
    d_hat = (pts[i + 1] - pts[i - 1]) / np.linalg.norm(pts[i + 1] - pts[i - 1])
    normal = np.array([-d_hat[1], d_hat[0]])
    sigma = 1.3
    prof = wire_profile(features, cam, R, t, (1024, 1024), sigma, pts[i : i + 1], 4)
    row, col = np.nonzero(prof)
    q = np.stack([col, row], 1).astype(float)
    dist = np.abs((q - pts[i]) @ normal)
    near = np.abs((q - pts[i]) @ d_hat) < 3  # the piece runs on past the patch's corners
    assert np.allclose(prof[row, col][near], np.exp(-0.5 * (dist[near] / sigma) ** 2), atol=0.02)
    assert np.all(np.abs(q - np.round(pts[i])) <= 4)
    # a piece's end (where it butts against a ball) reads half the line's peak on its centre-line
    ellipses = np.concatenate([p for f, (kind, p) in curves.items() if kind == "ellipse"])
    e = next(e for e in ends if np.min(np.linalg.norm(ellipses - e, axis=1)) > 8 * sigma)
    at_end = wire_profile(features, cam, R, t, (1024, 1024), sigma, e[None], 6)
    u, v = np.round(e).astype(int)
    cells = np.array([[u, v], [u + 1, v], [u, v + 1], [u + 1, v + 1]])
    values = at_end[cells[:, 1], cells[:, 0]]
    # bilinear from the four pixels about it: the profile is smooth on the scale of a pixel
    fu, fv = e - np.floor(e)
    uu, vv = np.floor(e).astype(int)
    corner = at_end[vv : vv + 2, uu : uu + 2]
    mid = (corner[0, 0] * (1 - fu) + corner[0, 1] * fu) * (1 - fv) + (corner[1, 0] * (1 - fu) + corner[1, 1] * fu) * fv
    assert values.max() < 0.75
    assert mid == pytest.approx(0.5, abs=0.06)
    Z = features.point_centers() @ R[2] + t[2]
    r = np.array([p.diameter for p in features.points]) / 2
    assert pose_bead_radius_px(features, cam, Pose(R, t, True, 1.0, None, {}, 0)) == pytest.approx(
        float(np.mean(cam.fx * r / Z))
    )


def test_contour_offset_covariance_is_the_pose_shift_of_moved_ellipses(rendered):
    """:func:`.noise.contour_offset_covariance` is σ² Δθ Δθᵀ with Δθ the pose's shift per px of
    an outward offset of the ellipse contours: its translation part equals a full re-solve of
    the observation with the contours moved 0.05 px (finite difference) within 5 %, the moved
    points lie 0.05 px outside the projected ellipses' own, and the term scales with σ²."""
    from ftrac_design.pose import SolverOptions, refine_pose
    from ftrac_design.segment.noise import contour_offset_covariance, ellipses_moved_out

    features, rad = rendered
    res = track_image(rad.raw, features, Camera())
    assert res.pose.converged and res.observation.ellipses
    obs, pose = res.observation, res.pose
    C = contour_offset_covariance(features, obs, pose, res.noise, 1.0)
    lam, vec = np.linalg.eigh(C)
    assert lam[:-1].max() < 1e-9 * lam[-1]
    d_cov = vec[:, -1] * np.sqrt(lam[-1])
    np.testing.assert_allclose(contour_offset_covariance(features, obs, pose, res.noise, 0.02), 4e-4 * C, rtol=1e-9)
    moved = ellipses_moved_out(features, obs, pose, 0.05)
    for fid, c in obs.ellipses.items():
        step = np.linalg.norm(moved.ellipses[fid].points - c.points, axis=1)
        np.testing.assert_allclose(step, 0.05, rtol=1e-9)
    opts = SolverOptions(noise=res.noise)
    p0 = refine_pose(features, obs, pose.rotation, pose.translation_mm, opts)
    p1 = refine_pose(features, moved, pose.rotation, pose.translation_mm, opts)
    d_fd = (p1.translation_mm - p0.translation_mm) / 0.05
    d_fd_sign = np.sign(d_fd @ d_cov[3:])
    np.testing.assert_allclose(d_fd_sign * d_cov[3:], d_fd, rtol=0.05, atol=0.05 * np.abs(d_fd).max())
    # moved outward, the ellipses grow: the fiducial comes nearer the source
    assert d_fd[2] < 0


def test_the_labelling_found_with_the_body_subtracted_is_kept_even_where_it_fits_worse(rendered, monkeypatch):
    """At the best labelling's pose the body's projection is subtracted and the balls fitted
    again with the predicted wires modelled under them; that labelling replaces the first
    whenever it converged — also where it explains the same features at a worse misfit, since
    its balls are the truer evidence."""
    from ftrac_design.segment import pipeline

    features, rad = rendered
    real = pipeline._with_body_subtracted
    asked = []

    def fitting_worse(g, scene, best, *args):
        lab, sc = real(g, scene, best, *args)
        asked.append((len(best.obs.points), len(lab.obs.points)))
        return replace(lab, score=best.score + 100.0), sc

    monkeypatch.setattr(pipeline, "_with_body_subtracted", fitting_worse)
    res = track_image(rad.raw, features, Camera())
    assert asked and asked[0][0] == asked[0][1] == 9
    assert res.pose.converged and res.diagnostics.body_subtracted
