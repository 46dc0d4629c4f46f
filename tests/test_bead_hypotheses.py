"""The bead hypotheses of a small fiducial seen in near-affine projection.

ftrac_mini is 1 × 1 × 2 cm at about 650 mm from the source: three of its balls give P3P two
poses tens of degrees apart that both put every other ball on the same blob. Both must stay
hypotheses; the right pose kept only when its RMS was the lower lost it to its twin, and a
labelling 178° off was then given out with confidence (``sequence_speed.py``'s ftrac_mini
run over anatomy, frames 85, 88 and 93)."""

from __future__ import annotations

import itertools
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, so3
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.segment import TrackOptions, identify, track_image

#: the sequence benchmark's camera: 1000 mm source to detector, 0.44 mm pixels
CAMERA = Camera(1000.0, (0.44, 0.44), (511.5, 511.5))


@pytest.fixture(scope="module")
def views():
    """200 views of ftrac_mini, seven of its nine balls seen at 0.15 px of noise each: the
    model, the truth (R, t), the blobs and the true labelling (model ball → blob)."""
    f = compute_features(load_design("ftrac_mini"))
    model = f.point_centers()
    R, t = Workspace(cone_deg=10.0, lateral_mm=10.0).sample(200, f.nominal_beam_direction, np.random.default_rng(5))
    rng = np.random.default_rng(6)
    out = []
    for k in range(len(R)):
        uv = identify.project(CAMERA, R[k], t[k], model)[0]
        seen = np.sort(rng.permutation(len(model))[:7])
        blobs = uv[seen] + rng.normal(0.0, 0.15, (len(seen), 2))
        out.append((model, R[k], t[k], blobs, {int(m): i for i, m in enumerate(seen)}))
    return out


def test_the_true_labelling_keeps_a_pose_near_the_truth(views):
    """In every view the true labelling is a hypothesis with a pose within 10° of the truth,
    the P3P twin beside it where there is one (before: 2 of these 200 kept the twin alone,
    111° and 129° off)."""
    twins = 0
    for model, R, _t, blobs, truth in views:
        hyps = [h for h in identify.bead_hypotheses(model, blobs, CAMERA, 2.0, keep=None) if h.match == truth]
        off = [float(so3.angle(h.R, R)) for h in hyps]
        assert min(off) < np.radians(10.0)
        twins += len(hyps) > 1
    # the case exists in this set: some true labellings come with two poses
    assert twins >= 3


def test_a_view_prior_keeps_only_the_poses_it_admits(views):
    """With a view known to 30° around a rotation 20° off the truth, every hypothesis lies
    within 30° + :data:`~.identify.SAME_POSE_RAD` of it and the true labelling is still found
    near the truth; with one 120° away, none is near the truth."""
    from ftrac_design.segment import ViewPrior

    margin = np.radians(30.0) + identify.SAME_POSE_RAD
    for k, (model, R, _t, blobs, truth) in enumerate(views[:40]):
        axis = np.random.default_rng(k).normal(size=3)
        axis /= np.linalg.norm(axis)
        near = ViewPrior(so3.exp(axis * np.radians(20.0)) @ R, np.radians(30.0))
        hyps = identify.bead_hypotheses(model, blobs, CAMERA, 2.0, keep=None, view=near)
        assert all(so3.angle(h.R, near.rotation) <= margin + 1e-9 for h in hyps)
        assert min(float(so3.angle(h.R, R)) for h in hyps if h.match == truth) < np.radians(10.0)
        far = ViewPrior(so3.exp(axis * np.radians(120.0)) @ R, np.radians(30.0))
        hyps = identify.bead_hypotheses(model, blobs, CAMERA, 2.0, keep=None, view=far)
        assert all(so3.angle(h.R, R) > np.radians(50.0) for h in hyps)


def test_poses_kept_for_one_labelling_are_distinct(views):
    """Two hypotheses of one labelling are never closer than ``SAME_POSE_RAD``: the noise of
    one P3P pose from triplet to triplet does not multiply the hypotheses."""
    for model, _R, _t, blobs, _truth in views[:60]:
        hyps = identify.bead_hypotheses(model, blobs, CAMERA, 2.0, keep=None)
        by_labelling: dict[tuple, list] = {}
        for h in hyps:
            by_labelling.setdefault(tuple(sorted(h.match.items())), []).append(h.R)
        for Rs in by_labelling.values():
            for i in range(len(Rs)):
                for j in range(i):
                    assert so3.angle(Rs[i], Rs[j]) >= identify.SAME_POSE_RAD


def _cluttered_view():
    """ftrac_2005's nine balls among 24 clutter blobs, strongest first: one ball of each wire
    ranked 2nd, 4th and 6th, the others 13th to 25th (the learned detector ranks brachytherapy
    seeds seen end-on above balls); model, truth (R, t) and the blobs."""
    f = compute_features(load_design("ftrac_2005"))
    model = f.point_centers()
    R, t = Workspace(cone_deg=10.0, lateral_mm=10.0).sample(1, f.nominal_beam_direction, np.random.default_rng(8))
    uv = identify.project(CAMERA, R[0], t[0], model)[0]
    rng = np.random.default_rng(9)
    lo, hi = uv.min(0) - 20, uv.max(0) + 20
    clutter = lo + rng.random((24, 2)) * (hi - lo)
    ranks = [2, 4, 6, 13, 14, 17, 19, 22, 25]
    blobs = np.empty((33, 2))
    # B1, B5 and B8 (one per wire: not collinear) first
    blobs[ranks] = uv[[0, 4, 7, 1, 2, 3, 5, 6, 8]] + rng.normal(0.0, 0.15, (9, 2))
    blobs[[k for k in range(33) if k not in ranks]] = clutter
    return model, R[0], t[0], blobs


def _right(hyps, R) -> bool:
    return any(h.count >= 7 and so3.angle(h.R, R) < np.radians(2.0) for h in hyps)


def test_a_wider_search_finds_balls_ranked_below_clutter():
    """The first search's 24 triplets of the 12 strongest blobs hold no three balls here, so
    the right labelling never forms; the wider search (the 48 triplets of the 16 strongest
    that follow, none of the first's tried again) finds it."""
    model, R, t, blobs = _cluttered_view()
    first = identify.bead_hypotheses(model, blobs, CAMERA, 3.4, image_triplets=24, keep=None)
    assert not _right(first, R)
    wide = identify.bead_hypotheses(
        model, blobs, CAMERA, 3.4, image_triplets=48, keep=None, blobs=16, after=24, patience=None
    )
    assert _right(wide, R)
    tried = set(identify._image_triplets(blobs, 24))
    assert not tried & set(identify._image_triplets(blobs, 48, k=16, skip=frozenset(tried)))


def test_an_image_the_first_search_refuses_is_tracked_by_the_wider_search():
    """The realism benchmark's strong-anatomy image 49 of seed 2079 (200 per condition): every
    labelling of the first search is refused, and the wider search gives the right pose. (The
    seeds-and-needles images this test held before — 4 of seed 2080, where the network ranked
    a dozen seeds above the balls, then 199 of seed 2079 — moved with the ball fits' changes:
    the first is tracked by the first search now, the second by neither.)"""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import track_realism

    img, R, t, camera, _ = track_realism.make_image("ftrac_2005", "strong-anatomy", 49, 2079, 200)
    features = track_realism.preset_features("ftrac_2005")
    assert not track_image(img, features, camera, replace(TrackOptions(), wide_triplets=0)).pose.converged
    res = track_image(img, features, camera)
    assert res.pose.converged, res.pose.error
    dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R, t)
    assert np.degrees(np.linalg.norm(dr)) < 0.5 and np.linalg.norm(dt) < 1.0


def test_a_second_look_does_not_break_the_first_looks_tie():
    """A pose the classical second look gives is refused when it is one of the two answers the
    learned detector's pass refused as a tie (:func:`.acceptance.among_rivals`: within 10° in
    rotation of either), and given when it is neither; then, the realism benchmark's ftrac_mini
    strong-anatomy image 6 of seed 2099 (10 per condition, its lines unreadable in this view),
    where the network's pass tied the right labelling with one 132° off and the classical
    search alone gives the one 132° off where a near-mirror ties only at the narrower margin
    (``mirror_ambiguity_chi2=25``): refused as ambiguous, not that pose."""
    from ftrac_design.pose import Pose, so3
    from ftrac_design.segment import acceptance

    R0 = so3.exp(np.array([0.3, -0.2, 0.1]))
    flipped = so3.exp(np.array([0.0, np.pi * 0.7, 0.0])) @ R0
    alts = [{"rotation": R.tolist(), "translation_mm": [0.0, 0.0, 600.0], "noise_scale": 1.0} for R in (R0, flipped)]

    def pose(R):
        return Pose(R, np.array([0.0, 0.0, 600.0]), True, 1.0, np.eye(6), {}, 0)

    assert "123.1° away" in acceptance.among_rivals(pose(so3.exp(np.array([0.0, 0.05, 0.0])) @ R0), alts)
    assert acceptance.among_rivals(pose(flipped), alts) is not None
    assert acceptance.among_rivals(pose(so3.exp(np.array([0.0, 0.0, 0.5])) @ R0), alts) is None
    assert acceptance.among_rivals(pose(R0), None) is None

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import track_realism

    img, R, t, camera, _ = track_realism.make_image("ftrac_mini", "strong-anatomy", 6, 2099, 10)
    features = track_realism.preset_features("ftrac_mini")
    # a near-mirror tied only as any rival is, as when this was written: the classical search
    # alone gives the pose 132° off, and the second look's pose is refused as the tie's
    narrow = replace(TrackOptions(), mirror_ambiguity_chi2=25.0)
    alone = track_image(img, features, camera, replace(narrow, detector="classical")).pose
    assert alone.converged and np.degrees(so3.angle(alone.rotation, R)) > 100
    res = track_image(img, features, camera, narrow)
    assert not res.pose.converged
    assert "an earlier look at the image found this pose" in res.pose.error
    # by default the classical search ties that near-mirror itself: no pose either way
    assert not track_image(img, features, camera).pose.converged
    assert min(np.degrees(so3.angle(np.asarray(a["rotation"]), R)) for a in res.diagnostics.alternatives) < 1.0


def test_an_answer_s_own_blobs_form_the_labelling_the_strongest_blobs_never_did():
    """The balls ranked below 24 clutter blobs: neither the first search nor the wider one
    holds three balls in a triplet. An answer that put six balls on their blobs and three on
    clutter (``labelled``) forms the right labelling from its own triplets; the same search
    without them does not."""
    model, R, t, blobs = _cluttered_view()
    near = np.linalg.norm(blobs[:, None] - identify.project(CAMERA, R, t, model)[0][None], axis=-1)
    ball_of = near.argmin(1)
    is_ball = near.min(1) < 1.0
    blobs, ball_of = np.concatenate([blobs[~is_ball], blobs[is_ball]]), np.r_[ball_of[~is_ball], ball_of[is_ball]]
    answer = {b: int(ball_of[b]) for b in range(24, 33)}
    for clutter, b in zip((0, 1, 2), sorted(answer)[:3]):
        answer[clutter] = answer.pop(b)  # three of its balls on clutter
    search = dict(image_triplets=48, keep=None, blobs=16, after=24, patience=None)
    assert not _right(identify.bead_hypotheses(model, blobs, CAMERA, 3.4, **search), R)
    found = identify.bead_hypotheses(model, blobs, CAMERA, 3.4, labelled=answer, labelled_triplets=84, **search)
    assert _right(found, R)
    none = identify.bead_hypotheses(model, blobs, CAMERA, 3.4, labelled=answer, labelled_triplets=0, **search)
    assert not _right(none, R)


def test_an_answer_s_triplets_are_its_largest_triangles_first_and_keep_two_labels():
    """:func:`.identify._triplets_among`: only the given blobs, no collinear three, the
    largest triangle first, at most the limit; :func:`.identify._one_relabelled`: two of the
    three labels kept, any allowed bead in the third place."""
    uv = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [0.0, 10.0], [5.0, 40.0], [100.0, 100.0]])
    tri = identify._triplets_among(uv, (0, 1, 2, 3, 4), 3, np.inf)
    assert len(tri) == 3 and all(set(abc) <= {0, 1, 2, 3, 4} for abc in tri)
    assert (0, 1, 2) not in tri
    a, b, c = (uv[list(col)] for col in zip(*tri))
    area = list(np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]) / 2)
    assert area == sorted(area, reverse=True) and area[0] == 400.0
    allowed = np.array([r for r in itertools.permutations(range(5), 3) if r != (4, 1, 2)])
    rows = {tuple(r) for r in identify._one_relabelled((0, 1, 2), allowed).tolist()}
    assert (0, 1, 2) in rows and (3, 1, 2) in rows and (0, 4, 2) in rows and (0, 1, 3) in rows
    assert (4, 1, 2) not in rows  # not allowed
    assert all(sum(a == b for a, b in zip(r, (0, 1, 2))) >= 2 for r in rows)
    assert len(rows) == 6  # the labels, and two other beads in each of three places, less (4, 1, 2)


@pytest.mark.parametrize("raster", [True, False])
def test_the_blob_lookup_answers_as_the_k_d_tree_does(raster, monkeypatch):
    """The look-up that skips points no blob is near gives, point by point, the k-d tree's
    nearest blob within the tolerance and its distance (∞ and n where there is none) — for
    points just inside and just outside the tolerance, far away, at the 10⁹ px that stands for
    a degenerate pose and on blobs that coincide; with its raster left out, the tree's own."""
    from scipy.spatial import cKDTree

    if not raster:
        monkeypatch.setattr(identify._BlobLookup, "MAX_RASTER_PX", 0)
    rng = np.random.default_rng(3)
    blobs = np.vstack([rng.uniform(100.0, 400.0, (30, 2)), [[250.3, 250.7], [250.3, 250.7]]])
    tol = 4.0
    ang = rng.uniform(0.0, 2 * np.pi, 4000)
    ring = (
        blobs[rng.integers(len(blobs), size=4000)]
        + (tol + rng.uniform(-1e-6, 1e-6, 4000))[:, None] * np.c_[np.cos(ang), np.sin(ang)]
    )
    q = np.vstack([ring, rng.uniform(-50.0, 550.0, (20000, 2)), [[1e9, 1e9], [-1e9, 3.0]]])
    lookup = identify._BlobLookup(blobs, tol)
    assert (lookup.mask is not None) == raster
    d, j = lookup.query(q)
    d0, j0 = cKDTree(blobs).query(q, distance_upper_bound=tol)
    assert np.array_equal(d, d0) and np.array_equal(j, j0)
    assert np.isfinite(d).sum() > 2000
