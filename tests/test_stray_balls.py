"""The acceptance test that refuses a pose with blobs as strong as its balls among them that
it does not explain (:func:`ftrac_design.segment.acceptance.stray_balls`): another phantom's
balls, a lattice of them, where the fiducial's own balls would be the strongest blobs; a blob
where two of the pose's own wires cross is not one of them."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from test_fuzz_observation import FEATURES

from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import TrackOptions, acceptance, identify

F = FEATURES["nine_bead"]
F2005 = FEATURES["ftrac_2005"]
CAMERA = Camera()
OPTS = TrackOptions().acceptance
RB = 3.4  # px: a 2 mm ball at the default magnification and pixel


def _pose(features, seed: int):
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(seed))
    return R[0], t[0]


def _scene_and_labelling(strays: np.ndarray, stray_response: float, features=F, seed: int = 3):
    """The design's balls (nine_bead's by default) where a pose puts them (blob response 20
    each) and ``strays`` (k, 2) px at ``stray_response``; the labelling uses every ball. Scales
    of a 2 mm ball and a 0.5 mm wire."""
    R, t = _pose(features, seed)
    uv = identify.project(CAMERA, R, t, features.point_centers())[0]
    allu = np.vstack([uv, strays.reshape(-1, 2)])
    response = np.r_[np.full(len(uv), 20.0), np.full(len(strays), stray_response)]
    scene = SimpleNamespace(
        beads=SimpleNamespace(uv=allu, response=response),
        features=features,
        camera=CAMERA,
        scales=SimpleNamespace(bead_radius_px=RB, wire_px=1.7, blur_px=0.8),
        learned=None,
        blob_snr=None,
    )
    ids = [p.id for p in features.points]
    lab = SimpleNamespace(
        match={fid: k for k, fid in enumerate(ids)},
        obs=SimpleNamespace(points={fid: uv[k] for k, fid in enumerate(ids)}),
        pose=SimpleNamespace(rotation=R, translation_mm=t),
    )
    return scene, lab, uv


def _inside(uv: np.ndarray, k: int) -> np.ndarray:
    """``k`` points inside the balls' hull, more than two radii from every ball: on the segments
    from the balls' centroid towards each ball, kept where clear of all of them."""
    c = uv.mean(0)
    pts = [c + f * (u - c) for u in uv for f in (0.3, 0.5, 0.7)]
    pts = [p for p in pts if np.linalg.norm(uv - p, axis=1).min() > 2 * RB + 1]
    assert len(pts) >= k
    return np.array(pts[:k])


@pytest.mark.parametrize("k,refused", [(0, False), (3, False), (4, True), (8, True)])
def test_strong_blobs_among_the_balls_refuse_the_pose_above_the_limit(k, refused):
    _, _, uv = _scene_and_labelling(np.zeros((0, 2)), 0.0)
    scene, lab, _ = _scene_and_labelling(_inside(uv, k), 15.0)  # 75 % of the balls' response
    why = acceptance.stray_balls(scene, lab, OPTS)
    assert (why is not None) == refused
    if refused:
        assert f"{k} blobs as strong as the fiducial's balls" in why


def test_weaker_far_or_coincident_blobs_do_not_count():
    _, _, uv = _scene_and_labelling(np.zeros((0, 2)), 0.0)
    inside = _inside(uv, 6)
    # weaker than 70 % of the balls' median response: clutter over the patient
    scene, lab, _ = _scene_and_labelling(inside, 13.0)
    assert acceptance.stray_balls(scene, lab, OPTS) is None
    # as strong, but outside the hull grown by a radius and 2 px
    c = uv.mean(0)
    span = np.ptp(uv, axis=0).max()
    outside = c + np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [-1, -1]]) * (span + 4 * RB)
    scene, lab, _ = _scene_and_labelling(outside, 20.0)
    assert acceptance.stray_balls(scene, lab, OPTS) is None
    # as strong, but within two radii of a ball the pose puts there (a ball's second blob)
    scene, lab, _ = _scene_and_labelling(uv[:6] + np.array([RB, 0.0]), 20.0)
    assert acceptance.stray_balls(scene, lab, OPTS) is None


def test_the_limit_is_a_setting():
    _, _, uv = _scene_and_labelling(np.zeros((0, 2)), 0.0)
    scene, lab, _ = _scene_and_labelling(_inside(uv, 4), 15.0)
    loose = TrackOptions(max_stray_balls=4).acceptance
    assert acceptance.stray_balls(scene, lab, loose) is None
    strict = TrackOptions(stray_ball_fraction=0.8).acceptance  # 16 > 15
    assert acceptance.stray_balls(scene, lab, strict) is None


def _curves(R, t) -> list[np.ndarray]:
    """ftrac_2005's predicted centre-lines at pose (R, t): each curve's finite samples (px)."""
    return [p[np.isfinite(p).all(1)] for _, p in identify.curve_samples(F2005, CAMERA, R, t).values()]


def _crossings(curves: list[np.ndarray]) -> np.ndarray:
    """Where two of the ``curves`` cross (px): the closest pairs of samples of two different
    curves within 0.5 px, one per crossing."""
    found: list[np.ndarray] = []
    for i, a in enumerate(curves):
        for b in curves[i + 1 :]:
            d = np.linalg.norm(a[:, None] - b[None], axis=-1)
            for j in np.flatnonzero(d.min(1) <= 0.5):
                x = 0.5 * (a[j] + b[d[j].argmin()])
                if all(np.linalg.norm(x - y) > 3.0 for y in found):
                    found.append(x)
    return np.array(found)


def _ridges(monkeypatch, faint: set[str]) -> None:
    """The image's ridges alone (:func:`.acceptance.faint_ridges`) read every ftrac_2005 curve
    in view, those in ``faint`` not clearly above zero."""
    ids = {c.id for c in F2005.lines} | {c.id for c in F2005.ellipses}
    monkeypatch.setattr(acceptance, "faint_ridges", lambda scene, pose, opts: (ids, set(faint)))


def _strays_off_the_crossings(seed: int = 5):
    """ftrac_2005's scene with strong blobs 5 px off each crossing of its predicted wires, where
    at most one wire passes within 3.5 px; also the crossings and the curves."""
    _, lab, uv = _scene_and_labelling(np.zeros((0, 2)), 15.0, F2005, seed=seed)
    curves = _curves(lab.pose.rotation, lab.pose.translation_mm)
    cross = _crossings(curves)
    cross = cross[np.linalg.norm(cross[:, None] - uv[None], axis=-1).min(1) > 2 * RB + 4]

    def wires_near(x: np.ndarray) -> int:
        return sum(np.linalg.norm(c - x, axis=1).min() <= 3.5 for c in curves)

    steps = 5.0 * np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)])
    off = np.array([next(x + d for d in steps if wires_near(x + d) <= 1) for x in cross])
    return off, cross


@pytest.mark.parametrize(
    ("faint", "unused", "refused"),
    [
        (set(), 0, False),
        ({"L2"}, 0, False),
        ({"L1", "L2"}, 0, True),
        ({"E1"}, 0, True),
        ({"E1", "E2"}, 0, True),
        (set(), 3, False),
        (set(), 4, True),
        ({"L2"}, 1, True),
        ({"E1"}, 3, True),
    ],
)
def test_a_pose_that_shows_its_fiducial_whole_is_not_refused_for_strays(monkeypatch, faint, unused, refused):
    """Strong blobs among the balls that the pose does not explain refuse a pose unless the
    image's ridges alone show its wires plainly and it uses enough of its balls: all of them
    with every ellipse and every straight wire but one plain, or at least two thirds of them
    (6 of ftrac_2005's 9) with every wire plain. Then its fiducial is there (over strong
    anatomy, among seeds) and the blobs are another object's. Two faint wires, a faint
    ellipse, a faint wire with a ball unused, or fewer balls (a near-mirror puts its wires on
    the true ones and leaves true balls among its own: four, seed 2131) refuse it."""
    _ridges(monkeypatch, faint)
    off, _ = _strays_off_the_crossings()
    assert len(off) > OPTS.max_stray_balls
    scene, lab, _ = _scene_and_labelling(off, 15.0, F2005, seed=5)
    for q in F2005.points[:unused]:
        lab.match.pop(q.id)
        lab.obs.points.pop(q.id)
    assert (acceptance.stray_balls(scene, lab, OPTS) is not None) == refused


def test_the_share_of_balls_a_whole_fiducial_needs_is_a_setting(monkeypatch):
    _ridges(monkeypatch, set())
    off, _ = _strays_off_the_crossings()
    scene, lab, _ = _scene_and_labelling(off, 15.0, F2005, seed=5)
    for q in F2005.points[:3]:
        lab.match.pop(q.id)
        lab.obs.points.pop(q.id)
    assert acceptance.stray_balls(scene, lab, OPTS) is None
    assert acceptance.stray_balls(scene, lab, TrackOptions(plain_wires_ball_share=1.0).acceptance) is not None


def test_blobs_where_two_of_the_poses_wires_cross_are_explained_by_it(monkeypatch):
    """Two wires crossing overlap in a spot as dense as a ball: the pose predicts it there. The
    same blobs moved 5 px off each crossing, to where at most one wire passes within 3.5 px,
    are strays as before (the wires read faint, so that they count)."""
    _ridges(monkeypatch, {"E1", "E2"})
    _, lab, uv = _scene_and_labelling(np.zeros((0, 2)), 15.0, F2005, seed=5)
    curves = _curves(lab.pose.rotation, lab.pose.translation_mm)
    cross = _crossings(curves)
    cross = cross[np.linalg.norm(cross[:, None] - uv[None], axis=-1).min(1) > 2 * RB + 4]
    assert len(cross) >= 4
    scene, lab, _ = _scene_and_labelling(cross, 15.0, F2005, seed=5)
    assert acceptance.at_wire_crossings(scene, lab.pose, cross).all()
    assert acceptance.stray_balls(scene, lab, OPTS) is None
    off, _ = _strays_off_the_crossings()
    scene, lab, _ = _scene_and_labelling(off, 15.0, F2005, seed=5)
    assert not acceptance.at_wire_crossings(scene, lab.pose, off).any()
    assert f"{len(off)} blobs as strong as the fiducial's balls" in acceptance.stray_balls(scene, lab, OPTS)
