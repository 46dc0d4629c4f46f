"""Each ball its own σ: the noise model gives a named bead its own standard deviation, the
solver weights it by that, and the image path derives it from the ball's own fit (its
reported σ, how far its fitted radius is from its fellows' and its apparent size from the
sharper ones'), so that a ball overlapped by a needle or an edge, or shown blurrier than the
rest, does not pull the pose."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_fuzz_observation import FEATURES

from ftrac_design.pose import Camera, NoiseModel, SolverOptions, refine_pose
from ftrac_design.pose.observation import Observation
from ftrac_design.pose.problem import compile_problem
from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation
from ftrac_design.segment import TrackOptions
from ftrac_design.segment.beads import Beads
from ftrac_design.segment.noise import measured_noise

OPTS = TrackOptions().labelling.noise
PIX = 0.3


@pytest.fixture(scope="module")
def view():
    features = FEATURES["nine_bead"]
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(5))
    cam = Camera()
    return features, cam, R[0], t[0], simulate_observation(features, cam, R[0], t[0])


def _without(obs: Observation, fid: str) -> Observation:
    return Observation(obs.camera, {k: v for k, v in obs.points.items() if k != fid}, obs.lines, obs.ellipses)


def _shifted(obs: Observation, fid: str, d_px) -> Observation:
    pts = dict(obs.points)
    pts[fid] = np.asarray(pts[fid], float) + np.asarray(d_px, float)
    return Observation(obs.camera, pts, obs.lines, obs.ellipses)


def test_a_bead_of_its_own_sigma_is_whitened_by_it(view):
    features, cam, *_, obs = view
    pix = float(np.mean(cam.pixel_size_mm))
    noise = NoiseModel(point_mm=0.05, points=(("B3", 0.2),))
    prob = compile_problem(features, [obs], noise)
    w = dict(zip(prob.point_ids, prob.p_w[0]))
    assert w["B3"] == pytest.approx(pix / 0.2)
    assert all(v == pytest.approx(pix / 0.05) for k, v in w.items() if k != "B3")
    assert noise.scaled(bead=2.0).point_sigma_mm("B3") == pytest.approx(0.4)
    assert noise.scaled(bead=2.0).point_sigma_mm("B1") == pytest.approx(0.1)


def test_a_bead_of_unbounded_sigma_is_the_pose_without_it(view):
    """Weighted least squares: a bead whose σ grows without bound leaves the pose it would
    have without that bead, however far it is moved."""
    features, _, R, t, obs = view
    moved = _shifted(obs, "B5", (3.0, -2.0))
    loose = refine_pose(features, moved, R, t, SolverOptions(noise=NoiseModel(0.05, points=(("B5", 5e4),))))
    gone = refine_pose(features, _without(obs, "B5"), R, t, SolverOptions(noise=NoiseModel(0.05)))
    assert loose.converged and gone.converged
    dr, dt = pose_errors(loose.rotation, loose.translation_mm, gone.rotation, gone.translation_mm)
    assert np.degrees(np.linalg.norm(dr)) < 1e-5 and np.linalg.norm(dt) < 1e-5


def _beads(
    obs: Observation, radius: dict[str, float], sigma: dict[str, float], blur: dict[str, float] | None = None
) -> tuple[Beads, dict[str, int]]:
    ids = sorted(obs.points)
    n = len(ids)
    beads = Beads(
        uv=np.array([obs.points[k] for k in ids], float),
        radius=np.array([radius.get(k, 3.4) for k in ids]),
        blur=np.array([(blur or {}).get(k, 0.8) for k in ids]),
        amplitude=np.ones(n),
        sigma_px=np.array([sigma.get(k, 0.05) for k in ids]),
        rms=np.ones(n),
        response=np.ones(n),
        contrast=np.full(n, 20.0),
    )
    return beads, {k: i for i, k in enumerate(ids)}


def test_each_ball_s_sigma_is_its_fit_s_and_its_radius_s_and_size_s_departure(view):
    """σᵢ² = (a sᵢ)² + (b Δrᵢ)² + (c Δmᵢ)² + σ_sys² (px), m = √(r² / 5 + blur²), times the
    pixel pitch; the median is the type's σ, and no ball is given more than
    ``point_max_ratio`` times it."""
    *_, obs = view
    beads, match = _beads(obs, radius={"B2": 3.9}, sigma={"B7": 0.12, "B9": 5.0}, blur={"B4": 1.0})
    nm = measured_noise(obs, beads, match, PIX, 0.8, OPTS)
    a, b, c, sys = OPTS.point_fit_scale, OPTS.point_radius_scale, OPTS.point_size_scale, OPTS.sys_point_px
    plain = np.sqrt((a * 0.05) ** 2 + sys**2) * PIX
    assert c > 0 and nm.point_sigma_mm("B1") == pytest.approx(plain)
    assert nm.point_mm == pytest.approx(plain)
    m0 = np.sqrt(3.4**2 / 5 + 0.8**2)
    dm2 = np.sqrt(3.9**2 / 5 + 0.8**2) - m0
    assert nm.point_sigma_mm("B2") == pytest.approx(
        np.sqrt((a * 0.05) ** 2 + (b * 0.5) ** 2 + (c * dm2) ** 2 + sys**2) * PIX
    )
    # a ball of the right radius shown more blurred than its fellows: its size alone departs
    dm4 = np.sqrt(3.4**2 / 5 + 1.0**2) - m0
    assert nm.point_sigma_mm("B4") == pytest.approx(np.sqrt((a * 0.05) ** 2 + (c * dm4) ** 2 + sys**2) * PIX)
    assert nm.point_sigma_mm("B7") == pytest.approx(np.sqrt((a * 0.12) ** 2 + sys**2) * PIX)
    assert nm.point_sigma_mm("B9") == pytest.approx(OPTS.point_max_ratio * plain)


def test_the_size_s_reference_is_the_sharper_balls_not_the_median(view):
    """Five of nine balls shown blurrier (on a structure): the median size is one of theirs,
    so the reference is the sizes' lower third — the four sharp balls keep the plain σ and
    the blurred five carry their departure from it."""
    *_, obs = view
    blurred = {f"B{i}": 1.6 for i in range(5, 10)}
    beads, match = _beads(obs, radius={}, sigma={}, blur=blurred)
    nm = measured_noise(obs, beads, match, PIX, 0.8, OPTS)
    a, c, sys = OPTS.point_fit_scale, OPTS.point_size_scale, OPTS.sys_point_px
    plain = np.sqrt((a * 0.05) ** 2 + sys**2) * PIX
    dm = np.sqrt(3.4**2 / 5 + 1.6**2) - np.sqrt(3.4**2 / 5 + 0.8**2)
    assert all(nm.point_sigma_mm(f"B{i}") == pytest.approx(plain) for i in range(1, 5))
    assert nm.point_sigma_mm("B7") == pytest.approx(np.sqrt((a * 0.05) ** 2 + (c * dm) ** 2 + sys**2) * PIX)
    by_median = measured_noise(obs, beads, match, PIX, 0.8, replace(OPTS, point_size_quantile=0.5))
    assert by_median.point_sigma_mm("B7") == pytest.approx(plain)
    assert by_median.point_sigma_mm("B1") > 2 * plain


def test_balls_pulled_along_a_structure_they_share_no_longer_carry_the_pose(view):
    """Three balls pulled 1.5 px the same way and two more unmoved, all five shown blurrier
    than the other four (a tube's walls under them): sized against the sharper balls, the
    pose moves a fraction of what the median size as the reference lets it (2.9 against
    10 mm here)."""
    features, cam, R, t, obs = view
    moved = obs
    for fid in ("B5", "B6", "B7"):
        moved = _shifted(moved, fid, (-1.5, 0.3))
    pix = float(np.mean(cam.pixel_size_mm))
    beads, match = _beads(moved, radius={}, sigma={}, blur={f"B{i}": 1.6 for i in range(5, 10)})
    err = {}
    for q in (OPTS.point_size_quantile, 0.5):
        noise = measured_noise(moved, beads, match, pix, 0.8, replace(OPTS, point_size_quantile=q))
        p = refine_pose(features, moved, R, t, SolverOptions(noise=noise))
        assert np.all(np.isfinite(p.translation_mm))
        dr, dt = pose_errors(p.rotation, p.translation_mm, R, t)
        err[q] = np.linalg.norm(dt)
    assert err[OPTS.point_size_quantile] < 0.5 * err[0.5]


def test_a_ball_that_looks_larger_than_its_fellows_no_longer_pulls_the_pose(view):
    """A ball merged with a needle is fitted 1.5 px off and 1.3 px larger than the others:
    with its own σ the pose moves a fraction of what the median ball's σ lets it move."""
    features, cam, R, t, obs = view
    moved = _shifted(obs, "B6", (1.2, -0.9))
    pix = float(np.mean(cam.pixel_size_mm))
    beads, match = _beads(moved, radius={"B6": 4.7}, sigma={})
    own = measured_noise(moved, beads, match, pix, 0.8, OPTS)
    one = NoiseModel(own.point_mm, own.line_mm, own.ellipse_mm)
    err = {}
    for name, noise in (("own", own), ("one", one)):
        # the shifted ball makes the residuals improbable under either model: only the estimate counts
        p = refine_pose(features, moved, R, t, SolverOptions(noise=noise))
        assert np.all(np.isfinite(p.translation_mm))
        dr, dt = pose_errors(p.rotation, p.translation_mm, R, t)
        err[name] = np.linalg.norm(dt)
    assert err["own"] < 0.25 * err["one"]


def test_each_ball_s_sigma_is_written_with_the_pose_and_read_back():
    from ftrac_design.pose import Diagnostics

    nm = NoiseModel(0.03, 0.01, 0.02, (("B1", 0.03), ("B4", 0.07)))
    d = Diagnostics(polarity="dense-dark", noise_model_mm=nm).to_dict()
    assert d["noise_model_mm"] == {"point": 0.03, "line": 0.01, "ellipse": 0.02, "points": {"B1": 0.03, "B4": 0.07}}
    assert Diagnostics.from_dict(d).noise_model_mm == nm
    plain = Diagnostics(polarity="dense-dark", noise_model_mm=NoiseModel(0.03, 0.01, 0.02)).to_dict()
    assert "points" not in plain["noise_model_mm"]
