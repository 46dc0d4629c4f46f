"""Balls a pose does not use but that the image shows a few pixels from where it puts them:
:func:`ftrac_design.segment.acceptance.displaced_balls` refuses such a pose (it is turned
about the balls it uses), and not a right one whose unused balls sit on their blobs.

The scene is the blob detector's response alone: a Gaussian blob (σ one ball radius, peak 10
noise units) at each ball's image, over a flat background; where the image side is tested, the
blobs are also the detector's fitted balls (all shaped like a ball, all equally strong) and the
learned detector reads each as a ball."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest
from test_fuzz_observation import FEATURES

from ftrac_design.pose import Camera, Pose
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import TrackOptions, acceptance, identify
from ftrac_design.segment.beads import Beads
from ftrac_design.segment.detection import Scene, scales

F = FEATURES["ftrac_2005"]
CAM = Camera()
#: the image the default camera sees: its principal point at the centre
SHAPE = (int(2 * CAM.principal_point_px[1] + 1), int(2 * CAM.principal_point_px[0] + 1))
OPTS = TrackOptions()
UNUSED = ("B5", "B6", "B7")


@pytest.fixture(scope="module")
def view():
    """A pose whose nine balls are all clear of one another (their blurred discs touch none)."""
    sc = scales(F, CAM, OPTS.finding)
    rng = np.random.default_rng(11)
    for _ in range(50):
        R, t = Workspace().sample(1, F.nominal_beam_direction, rng)
        uv = identify.project(CAM, R[0], t[0], F.point_centers())[0]
        dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9
        if dd.min() > 4 * sc.bead_radius_px:
            return R[0], t[0], uv, sc
    raise AssertionError("no view with every ball clear of the others")


def _scene(uv_blobs: np.ndarray, sc, fitted: bool = False, learned: bool = True) -> Scene:
    H, W = SHAPE
    yy, xx = np.mgrid[0:H, 0:W]
    snr = np.zeros((H, W), np.float32)
    for u, v in uv_blobs:
        snr += 10.0 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * sc.bead_radius_px**2)).astype(np.float32)
    z = np.zeros((H, W), np.float32)
    n = len(uv_blobs)
    beads = None
    if fitted:
        one = np.ones(n)
        rb = one * sc.bead_radius_px
        beads = Beads(np.asarray(uv_blobs, float), rb, one, one, 0.1 * one, one, 10 * one, 10 * one)
    ball = SimpleNamespace(ball_probability=lambda uv: np.ones(len(uv))) if learned else None
    return Scene(F, CAM, sc, z, np.ones_like(z), beads, None, blob_snr=snr, learned=ball)


def _labelling(R, t):
    """The pose (R, t) using every ball but ``UNUSED``, each matched to the blob of its own
    index (the scenes list one blob per ball, in the design's order)."""
    used = {p.id: np.zeros(2) for p in F.points if p.id not in UNUSED}
    match = {p.id: k for k, p in enumerate(F.points)}
    return SimpleNamespace(obs=SimpleNamespace(points=used), pose=Pose(R, t, True, 1.0, None, {}, 0), match=match)


def _moved(uv, shift_px, direction=(0.6, 0.8)):
    out = uv.copy()
    for k, p in enumerate(F.points):
        if p.id in UNUSED:
            out[k] = out[k] + shift_px * np.asarray(direction)
    return out


def test_unused_balls_on_their_blobs_refuse_nothing(view):
    R, t, uv, sc = view
    assert acceptance.displaced_balls(_scene(_moved(uv, 0.5), sc), _labelling(R, t), OPTS.acceptance) is None


def test_unused_balls_shown_four_pixels_off_refuse_the_pose(view):
    R, t, uv, sc = view
    why = acceptance.displaced_balls(_scene(_moved(uv, 4.0), sc), _labelling(R, t), OPTS.acceptance)
    assert why is not None and why.startswith("identification not confirmed: 3 balls")
    # the distance to the strongest pixel: within half a pixel of the 4 px shift
    found = dict(re.findall(r"(B\d) ([\d.]+) px", why))
    assert set(found) == set(UNUSED)
    assert all(abs(float(d) - 4.0) <= 0.5 for d in found.values())


def test_a_ball_that_shows_nowhere_near_is_not_displaced(view):
    """A ball the image does not show at all (hidden, or too faint) is for the unexplained-ball
    count, not this test: only blobs within two radii count."""
    R, t, uv, sc = view
    gone = [q for q, p in zip(uv, F.points) if p.id not in UNUSED]
    assert acceptance.displaced_balls(_scene(np.array(gone), sc), _labelling(R, t), OPTS.acceptance) is None


def test_one_displaced_ball_is_allowed(view):
    R, t, uv, sc = view
    one = uv.copy()
    k = [p.id for p in F.points].index("B5")
    one[k] += (2.4, 3.2)
    assert acceptance.displaced_balls(_scene(one, sc), _labelling(R, t), OPTS.acceptance) is None


def test_balls_shown_beside_where_the_pose_puts_them_refuse_it(view):
    """Blobs 2.2 radii off the unused balls: past the two radii the pose's side looks within,
    yet near enough that the discs would touch — seen from the image's side."""
    R, t, uv, sc = view
    off = _moved(uv, 2.2 * sc.bead_radius_px)
    assert acceptance.displaced_balls(_scene(off, sc), _labelling(R, t), OPTS.acceptance) is None
    why = acceptance.displaced_balls(_scene(off, sc, fitted=True), _labelling(R, t), OPTS.acceptance)
    assert why is not None and why.startswith("identification not confirmed: 3 balls")
    d = [float(x) for x in re.findall(r"blob ([\d.]+) px", why)]
    assert len(d) == 3 and all(abs(x - 2.2 * sc.bead_radius_px) < 1e-6 for x in d)


def test_blobs_beside_count_only_where_the_network_reads_balls(view):
    """Without the learned detector (the classical path) the blob detector alone cannot tell a
    ball from a seed's end: the image's side is not read, the pose's side still is."""
    R, t, uv, sc = view
    off = _moved(uv, 2.2 * sc.bead_radius_px)
    scene = _scene(off, sc, fitted=True, learned=False)
    assert acceptance.displaced_balls(scene, _labelling(R, t), OPTS.acceptance) is None


def test_blobs_on_their_balls_or_past_touching_refuse_nothing(view):
    R, t, uv, sc = view
    for shift in (0.5, sc.touching_px + 0.5):
        scene = _scene(_moved(uv, shift), sc, fitted=True)
        assert acceptance.displaced_balls(scene, _labelling(R, t), OPTS.acceptance) is None, shift


def test_a_blob_between_two_balls_whose_discs_touch_is_theirs(view):
    """Two balls the pose puts 1.6 radii apart blend into one blob between them: a blob there,
    farther than the displaced distance from each, is explained by the pair."""
    R, t, uv, sc = view
    rb = sc.bead_radius_px
    ids = [p.id for p in F.points]
    a, b = ids.index("B5"), ids.index("B6")
    moved = uv.copy()
    moved[b] = moved[a] + (1.6 * rb, 0.0)
    blobs = uv.copy()
    blobs[a] = blobs[b] = moved[a] + (0.8 * rb, 0.0)
    k = ids.index("B7")
    blobs[k] = uv[k] + (2.2 * rb, 0.0)
    scene = _scene(blobs, sc, fitted=True)
    pose = _labelling(R, t)
    with_pair = acceptance.blobs_beside(scene, pose, moved, OPTS.acceptance)
    assert [round(d / rb, 3) for _, d in with_pair] == [2.2]
    apart = moved.copy()
    apart[b] = moved[a] + (2 * sc.touching_px, 0.0)
    assert len(acceptance.blobs_beside(scene, pose, apart, OPTS.acceptance)) >= 2
