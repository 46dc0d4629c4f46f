"""Which bead hypotheses are refined first, and the balls a hypothesis predicts where the blob
search kept none.

A hypothesis is ranked by the balls it matches and by what the image shows along the wires its
pose predicts: a right labelling of four balls, whose wires the image shows, comes before wrong
ones of six balls whose wires lie on bare background. Where the pose predicts a ball the blob
search did not keep, a ball fitted there joins the scene when it is one as the search would have
kept it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_fuzz_observation import FEATURES

from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import TrackOptions, evidence, identify, pipeline
from ftrac_design.segment.detection import balls_at, detect
from ftrac_design.segment.image import to_density
from ftrac_design.xray import render

OPTS = TrackOptions()


@pytest.fixture(scope="module")
def scene_2005(f2005):
    """A rendered raw radiograph of ftrac_2005 (its pose drawn from the workspace) as the image
    path sees it, with that pose."""
    R, t = Workspace().sample(1, f2005.nominal_beam_direction, np.random.default_rng(11))
    rad = render(f2005, R[0], t[0], Camera(), rng=np.random.default_rng(11))
    g = to_density(rad.raw.astype(float), "dense-dark")
    return detect(g, f2005, Camera(), OPTS.finding), R[0], t[0]


def test_the_ranking_measure_reads_the_wires_the_dense_measure_reads(scene_2005):
    """At the true pose every line and ellipse is plainly shown: the coarse measure sums each
    curve's clipped median (3 noise units at most) to within one unit of the dense measure's
    (:func:`evidence.curve_support`, a sample every 0.5 px), and reads at least 2.5 per curve."""
    scene, R, t = scene_2005
    coarse = evidence.ranking_support(scene, R[None], t[None], scene.bead_exclusion())[0]
    dense = {k: c.ridge for k, c in evidence.curve_support(scene, R, t, scene.bead_exclusion()).items()}
    lo, hi = evidence.RANK_CLIP
    assert len(dense) == 5
    assert coarse == pytest.approx(sum(np.clip(v, lo, hi) for v in dense.values()), abs=1.0)
    assert coarse >= 2.5 * len(dense)


@pytest.mark.parametrize("shift_mm", [(60.0, 0.0, 0.0), (0.0, -60.0, 0.0), (-60.0, 0.0, 0.0)])
def test_wires_predicted_on_bare_background_read_nothing(scene_2005, shift_mm):
    """The same pose moved 60 mm across the view, so that its wires fall on the image's bare
    background: the measure reads about zero (under 1.5 noise units over five curves, where
    the true pose reads over 12.5), as the dense measure does there (within one unit); one call
    for many poses gives each pose its own value."""
    scene, R, t = scene_2005
    t2 = t + np.array(shift_mm)
    both = evidence.ranking_support(scene, np.stack([R, R]), np.stack([t2, t]), scene.bead_exclusion())
    alone = evidence.ranking_support(scene, R[None], t2[None], scene.bead_exclusion())[0]
    dense = {k: c.ridge for k, c in evidence.curve_support(scene, R, t2, scene.bead_exclusion()).items()}
    assert abs(both[0]) < 1.5
    assert both[0] == pytest.approx(sum(dense.values()), abs=1.0)
    assert both[0] == pytest.approx(alone)
    assert both[1] >= 12.5


def test_a_right_hypothesis_of_four_balls_comes_before_wrong_ones_of_six(scene_2005):
    """Wrong poses (turned 40–160° about the view axis, or moved 25 mm across it) matching six
    balls, and the true pose matching four: ranked by count alone the wrong ones come first,
    ranked with the wires the true one does; the ranking keeps every hypothesis."""
    scene, R, t = scene_2005
    wrong = []
    for turn in (40.0, 100.0, 160.0):
        Q = Rotation.from_rotvec([0.0, 0.0, np.radians(turn)]).as_matrix()
        wrong.append(identify.BeadHypothesis(Q @ R, t, {}, 6, 0.5))
    wrong.append(identify.BeadHypothesis(R, t + np.array([25.0, 0.0, 0.0]), {}, 6, 0.5))
    right = identify.BeadHypothesis(R, t, {}, 4, 0.5)
    hyps = sorted(wrong + [right], key=lambda h: -h.count)
    ranked = pipeline.ranked_hypotheses(scene, hyps, OPTS.finding.hypothesis_wire_weight)
    assert ranked[0].R is right.R and ranked[0].t is right.t
    assert len(ranked) == len(hyps)
    assert ranked[0].rank > max(h.rank for h in ranked[1:]) + 2
    by_count = pipeline.ranked_hypotheses(scene, hyps, 0.0)
    assert [h.count for h in by_count] == [6, 6, 6, 6, 4]


def test_a_bead_only_design_keeps_the_order_by_count():
    """nine_bead has no wire: the hypotheses come back as they were, each ranked by its count."""
    scene = SimpleNamespace(features=FEATURES["nine_bead"])
    hyps = [identify.BeadHypothesis(np.eye(3), np.array([0.0, 0.0, 600.0]), {}, c, 0.5) for c in (7, 5, 4)]
    out = pipeline.ranked_hypotheses(scene, hyps, 0.5)
    assert out == hyps
    assert [h.rank for h in out] == [7.0, 5.0, 4.0]


def _without(scene, drop: np.ndarray):
    keep = np.setdiff1d(np.arange(len(scene.beads)), drop)
    return scene.with_detections(scene.T, scene.beads.take(keep), scene.ridges), keep


def test_balls_the_search_did_not_keep_are_fitted_where_the_pose_predicts_them(scene_2005):
    """Three of the scene's balls taken out of its blob list: fitted where the true pose
    predicts them, they come back within 0.05 px of their first fit; a prediction on bare
    background, or at a ball still in the list, gives none."""
    scene, R, t = scene_2005
    uv = identify.project(scene.camera, R, t, scene.features.point_centers())[0]
    near = np.linalg.norm(uv[:, None] - scene.beads.uv[None], axis=-1).argmin(1)
    drop = near[[0, 4, 8]]
    fewer, _ = _without(scene, drop)
    tol = OPTS.finding.hypothesis_tol_radii * scene.scales.bead_radius_px
    got = balls_at(fewer, uv, OPTS.finding.bead_min_snr, tol)
    assert len(got) == 3
    d = np.linalg.norm(got.uv[:, None] - scene.beads.uv[drop][None], axis=-1)
    assert d.min(1).max() < 0.05
    assert len(balls_at(fewer, uv + np.array([40.0, 0.0]), OPTS.finding.bead_min_snr, tol)) == 0
    assert len(balls_at(scene, uv, OPTS.finding.bead_min_snr, tol)) == 0


def test_predicted_balls_are_appended_so_the_hypotheses_matches_stand(scene_2005):
    """The scene with a hypothesis' predicted balls keeps every blob it had, at the same index,
    and gains the balls the search had not kept (here the two taken out); a hypothesis whose
    balls all have a blob adds nothing."""
    scene, R, t = scene_2005
    uv = identify.project(scene.camera, R, t, scene.features.point_centers())[0]
    near = np.linalg.norm(uv[:, None] - scene.beads.uv[None], axis=-1).argmin(1)
    fewer, _ = _without(scene, near[[1, 6]])
    h = identify.BeadHypothesis(R, t, {}, 7, 0.5)
    out = pipeline.with_predicted_balls(fewer, [h], OPTS.finding, OPTS.acceptance)
    assert len(out.beads) == len(fewer.beads) + 2
    assert np.array_equal(out.beads.uv[: len(fewer.beads)], fewer.beads.uv)
    same = pipeline.with_predicted_balls(scene, [h], OPTS.finding, OPTS.acceptance)
    assert same is scene


def test_a_first_hypothesis_with_every_ball_keeps_the_order_by_count(scene_2005):
    """When the first hypothesis has a blob for all nine balls the wires are not consulted:
    a hypothesis of four balls whose wires the image shows stays behind it, and no ball is
    fitted at the predictions."""
    scene, R, t = scene_2005
    Q = Rotation.from_rotvec([0.0, 0.0, np.radians(100.0)]).as_matrix()
    hyps = [identify.BeadHypothesis(Q @ R, t, {}, 9, 0.5), identify.BeadHypothesis(R, t, {}, 4, 0.5)]
    assert pipeline.ranked_hypotheses(scene, hyps, OPTS.finding.hypothesis_wire_weight) == hyps
    fewer, _ = _without(scene, np.array([0, 1]))
    assert pipeline.with_predicted_balls(fewer, hyps, OPTS.finding, OPTS.acceptance) is fewer


def test_many_poses_ranked_at_once_read_as_each_alone(scene_2005):
    """The coarse measure of 40 poses — the truth, and turned or moved so that some wires fall
    on bare background, off the image or under another pose's balls — is each pose's own,
    whatever the chunk they are taken in (one at a time, or all in one)."""
    scene, R, t = scene_2005
    rng = np.random.default_rng(4)
    Rs = np.stack([R] + [Rotation.from_rotvec(rng.normal(0, 0.6, 3)).as_matrix() @ R for _ in range(39)])
    ts = np.stack([t] + [t + rng.normal(0, 15.0, 3) for _ in range(39)])
    together = evidence.ranking_support(scene, Rs, ts, scene.bead_exclusion())
    one_by_one = evidence.ranking_support(scene, Rs, ts, scene.bead_exclusion(), chunk=1)
    assert np.array_equal(together, one_by_one)
    assert together[0] >= 12.5 and together[1:].min() < 5.0


def _least_squares_pose(camera, model, uv, R0, t0):
    """The matched balls' reprojection minimum by SciPy's trust-region solver, from (R0, t0)."""
    from scipy.optimize import least_squares

    def residual(x):
        R = Rotation.from_rotvec(x[:3]).as_matrix() @ R0
        return (identify.project(camera, R, t0 + x[3:], model)[0] - uv).ravel()

    x = least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    return Rotation.from_rotvec(x[:3]).as_matrix() @ R0, t0 + x[3:]


def test_polished_poses_reach_the_matched_balls_least_squares_pose(f2005):
    """Hypotheses of four, six and nine balls (noisy blobs, some not a ball's) whose poses are
    off by ~2° and 30 mm: each polished pose is SciPy's least-squares pose on its own matched
    balls (within 1e-5° and 1e-4 mm); a hypothesis with no ball matched keeps its pose."""
    cam, model = Camera(), f2005.point_centers()
    rng = np.random.default_rng(3)
    R, t = Workspace().sample(1, f2005.nominal_beam_direction, rng)
    uv = identify.project(cam, R[0], t[0], model)[0] + rng.normal(0.0, 0.3, (len(model), 2))
    blobs = np.concatenate([rng.uniform(0, 1000, (5, 2)), uv])  # the balls' blobs after five others
    hyps = []
    for n in (4, 6, 9):
        Q = Rotation.from_rotvec(rng.normal(0.0, 0.02, 3)).as_matrix()
        balls = rng.choice(len(model), n, replace=False)
        match = {int(b): int(b) + 5 for b in balls}
        hyps.append(identify.BeadHypothesis(Q @ R[0], t[0] + rng.normal(0.0, 15.0, 3), match, n, 1.0))
    hyps.append(identify.BeadHypothesis(R[0], t[0] + 9.0, {}, 0, 1.0))
    Rp, tp = identify.polished_poses(cam, model, blobs, hyps)
    for h, Ri, ti in zip(hyps[:3], Rp, tp):
        balls = sorted(h.match)
        Rs, ts = _least_squares_pose(cam, model[balls], blobs[[h.match[b] for b in balls]], h.R, h.t)
        assert np.degrees(Rotation.from_matrix(Ri.T @ Rs).magnitude()) < 1e-5
        assert np.abs(ti - ts).max() < 1e-4
    assert np.array_equal(Rp[3], hyps[3].R) and np.array_equal(tp[3], hyps[3].t)


def test_a_right_hypothesis_is_ranked_by_its_wires_where_its_balls_put_them(scene_2005):
    """The right labelling of four balls carried by a pose 1.5° and 30 mm off (as P3P of three
    close balls gives it), against wrong poses matching six: the wires are read at the pose of
    its four balls, so it comes first, and it reads within one noise unit of the true pose;
    where no view is set apart from its mirror image (an infinite threshold) they are read at
    the poses given."""
    scene, R, t = scene_2005
    model = scene.features.point_centers()
    uv = identify.project(scene.camera, R, t, model)[0]
    near = np.linalg.norm(uv[:, None] - scene.beads.uv[None], axis=-1).argmin(1)
    off = Rotation.from_rotvec([np.radians(1.5), 0.0, 0.0]).as_matrix()
    right = identify.BeadHypothesis(
        off @ R, t + np.array([0.0, 0.0, 30.0]), {b: int(near[b]) for b in (0, 3, 5, 8)}, 4, 1.0
    )
    wrong = [
        identify.BeadHypothesis(Rotation.from_rotvec([0.0, 0.0, np.radians(a)]).as_matrix() @ R, t, {}, 6, 0.5)
        for a in (40.0, 100.0, 160.0)
    ]
    far = evidence.ranking_support(scene, right.R[None], right.t[None], scene.bead_exclusion())[0]
    ranked = pipeline.ranked_hypotheses(
        scene, wrong + [right], OPTS.finding.hypothesis_wire_weight, mirror_px=OPTS.acceptance.mirror_signal_px
    )
    true = evidence.ranking_support(scene, R[None], t[None], scene.bead_exclusion())[0]
    assert ranked[0].match == right.match and ranked[0].R is right.R
    assert ranked[0].rank - 4 == pytest.approx(OPTS.finding.hypothesis_wire_weight * true, abs=0.5)
    assert far < true - 3.0
    # where no view is set apart from its mirror image, the wires are read at the P3P poses
    unpolished = pipeline.ranked_hypotheses(scene, wrong + [right], OPTS.finding.hypothesis_wire_weight)
    beside_mirror = pipeline.ranked_hypotheses(
        scene, wrong + [right], OPTS.finding.hypothesis_wire_weight, mirror_px=np.inf
    )
    assert [h.rank for h in beside_mirror] == [h.rank for h in unpolished]
    assert unpolished[[h.match for h in unpolished].index(right.match)].rank == pytest.approx(4 + 0.5 * far)
