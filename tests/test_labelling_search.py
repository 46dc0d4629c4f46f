"""Which bead hypotheses are refined into labellings, and against what the best one's rivals
are judged.

The first few hypotheses are always refined, and the rest of those found while the best pose
so far rests on little (two or more balls unexplained, or fewer than half the wires), so that
a near-mirror labelling ranked first cannot pass for want of the right one ranked below it.
A rival is judged against the best labelling as it was before the body's projection was
subtracted at its pose too: only the best had that subtraction."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_fuzz_observation import FEATURES

from ftrac_design.pose import Diagnostics, NoiseModel, Pose, so3
from ftrac_design.segment import TrackOptions, identify, pipeline, pixelfit
from ftrac_design.segment.labelling import Labelling, NoLabelling

F = FEATURES["ftrac_2005"]
ALL_BALLS = [p.id for p in F.points]
ALL_LINES = [c.id for c in F.lines]
ALL_ELLIPSES = [c.id for c in F.ellipses]


def _hypotheses(n: int) -> list[identify.BeadHypothesis]:
    """``n`` hypotheses 20° apart about the view axis, each matching five balls."""
    return [
        identify.BeadHypothesis(
            Rotation.from_rotvec([0.0, 0.0, np.radians(20.0 * i)]).as_matrix(), np.array([0.0, 0.0, 600.0]), {}, 5, 0.5
        )
        for i in range(n)
    ]


def _labelling(h, converged: bool, balls: list[str], curves: list[str], score: float) -> Labelling:
    # σ of 0.06° per axis, 0.1 mm across the view and 1 mm in depth: a tracked pose's order
    cov = np.diag([1e-6, 1e-6, 1e-6, 0.01, 0.01, 1.0])
    pose = Pose(h.R, h.t, converged, 0.3, cov, {}, 3, None if converged else "refused")
    obs = SimpleNamespace(
        points={b: np.zeros(2) for b in balls},
        lines={c: None for c in curves if c in ALL_LINES},
        ellipses={c: None for c in curves if c in ALL_ELLIPSES},
    )
    return Labelling(pose, obs, NoiseModel(), {}, None, {}, score=score)


@pytest.fixture
def refine(monkeypatch):
    """Refinement stubbed by a table: hypothesis index → (converged, balls, curves, score);
    returns the list of indices refined."""
    calls: list[int] = []
    table: dict[int, tuple] = {}

    def evaluate(scene, h, opts):
        i = round(np.degrees(Rotation.from_matrix(h.R).magnitude()) / 20.0)
        calls.append(i)
        if i not in table:
            raise NoLabelling("stub: no pose")
        return _labelling(h, *table[i])

    monkeypatch.setattr(pipeline, "evaluate", evaluate)
    monkeypatch.setattr(pipeline, "with_agreement", lambda scene, lab, opts: lab)
    monkeypatch.setattr(pipeline.acceptance, "absent_wires", lambda scene, pose, opts: None)
    return table, calls


def _run(table_calls, hyps, **opts):
    table, calls = table_calls
    o = TrackOptions(**opts)
    scene = SimpleNamespace(features=F)
    labs = pipeline._labellings(scene, hyps, pipeline.Budget(o.search), o.labelling, o.acceptance)
    return labs, calls


def test_a_pose_on_five_balls_and_no_line_has_the_hypotheses_below_it_refined(refine):
    """The first four give a near-mirror pose on five of nine balls and the two ellipses; the
    sixth, the right one, explains every feature: it is refined, scores best, and ends the
    search."""
    table, _ = refine
    weak = (True, ALL_BALLS[:5], ALL_ELLIPSES, 2080.0)
    for i in range(4):
        table[i] = weak
    table[5] = (True, ALL_BALLS, ALL_LINES + ALL_ELLIPSES, 300.0)
    labs, calls = _run(refine, _hypotheses(8))
    assert calls == list(range(6))
    assert min(labs, key=lambda lab: lab.score).score == 300.0


WEAK = (True, ALL_BALLS[:6], ALL_ELLIPSES, 900.0)


@pytest.mark.parametrize(
    "given, expected",
    [
        pytest.param({0: (True, ALL_BALLS, ALL_LINES + ALL_ELLIPSES, 300.0)}, [0, 1, 2, 3], id="full-pose-first"),
        pytest.param(
            {**dict.fromkeys(range(4), WEAK), 4: (True, ALL_BALLS[:8], ALL_LINES, 400.0)},
            [0, 1, 2, 3, 4],
            id="extension-ends-at-a-full-pose",
        ),
        # refusals alone do not extend the search: the work is kept for the other polarity
        # and region, where the right pose was on a blurred image of the tuning seed
        pytest.param(dict.fromkeys(range(8), (False, ALL_BALLS[:5], [], 2000.0)), [0, 1, 2, 3], id="refusals-only"),
    ],
)
def test_where_the_search_stops(refine, given, expected):
    table, _ = refine
    table.update(given)
    _, calls = _run(refine, _hypotheses(8))
    assert calls == expected


def test_the_options_set_both_counts(refine):
    table, _ = refine
    for i in range(8):
        table[i] = (True, ALL_BALLS[:5], ALL_ELLIPSES, 2000.0)
    _, calls = _run(refine, _hypotheses(8), labellings_if_weak=4)
    assert calls == [0, 1, 2, 3]
    _, calls2 = _run(refine, _hypotheses(8), labellings=2, labellings_if_weak=6)
    assert calls2[4:] == [0, 1, 2, 3, 4, 5]


def test_a_bead_only_design_never_extends_the_search():
    """Its poses need all its balls but two anyway, and no wire tells a near-mirror apart."""
    nine = FEATURES["nine_bead"]
    assert not nine.lines and not nine.ellipses
    h = _hypotheses(1)[0]
    all_nine = [p.id for p in nine.points]
    assert not pipeline._rests_on_little(nine, [_labelling(h, True, all_nine[:-2], [], 1.0)])
    assert pipeline._rests_on_little(F, [_labelling(h, True, ALL_BALLS[:-2], ALL_LINES + ALL_ELLIPSES, 1.0)])
    assert not pipeline._rests_on_little(F, [_labelling(h, True, ALL_BALLS[:-1], ALL_LINES[:1] + ALL_ELLIPSES, 1.0)])


def test_only_an_answer_its_wires_do_not_confirm_is_challenged():
    """The wider search challenges balls alone or fewer than half the wires as contours
    (the two wrong answers it exists for: 8 balls and none, 6 balls and 2 of 5), not an
    answer that shows most wires but leaves two balls unexplained; a bead-only design never."""
    h = _hypotheses(1)[0]
    unshown = pipeline._wires_unshown
    assert unshown(F, _labelling(h, True, ALL_BALLS[:-1], [], 1.0))
    assert unshown(F, _labelling(h, True, ALL_BALLS[:6], ALL_LINES[:2], 1.0))
    assert unshown(F, _labelling(h, True, ALL_BALLS, ALL_ELLIPSES, 1.0))
    assert not unshown(F, _labelling(h, True, ALL_BALLS[:7], ALL_LINES[:1] + ALL_ELLIPSES, 1.0))
    assert not unshown(F, _labelling(h, True, ALL_BALLS[:5], ALL_LINES, 1.0))
    nine = FEATURES["nine_bead"]
    assert not unshown(nine, _labelling(h, True, [p.id for p in nine.points][:7], [], 1.0))


def _pass_other_tests(monkeypatch, pixel_z: dict[float, float] | None = None):
    """Every acceptance test but the rivals' passes; the image's pixels prefer the pose
    compared first by ``pixel_z[angle]`` units over one turned ``angle`` degrees from it
    about the view axis (no word on the others, nor on any without ``pixel_z``)."""

    def compare(scene, first, seconds):
        out = []
        for q in seconds:
            a = round(float(np.degrees(so3.angle(q.rotation, first.rotation))))
            z = (pixel_z or {}).get(a)
            out.append(None if z is None else pixelfit.PixelComparison(z, 1.0, z, 1.0, 1.0, 100))
        return out

    monkeypatch.setattr(pipeline.acceptance.pixelfit, "compare", compare)
    monkeypatch.setattr(pipeline.acceptance, "wire_support", lambda scene, pose, opts, also=None: ([], {}))
    monkeypatch.setattr(pipeline.acceptance, "too_little_evidence", lambda scene, lab, opts: None)
    monkeypatch.setattr(pipeline.acceptance, "misshapen_balls", lambda scene, lab, opts: None)
    monkeypatch.setattr(pipeline.acceptance, "small_balls", lambda scene, lab, opts: None)
    monkeypatch.setattr(pipeline.acceptance, "stray_balls", lambda scene, lab, opts: None)
    monkeypatch.setattr(pipeline.acceptance, "displaced_balls", lambda scene, lab, opts: None)
    monkeypatch.setattr(pipeline.acceptance, "uncontrolled", lambda scene, lab, opts: None)
    monkeypatch.setattr(pipeline.acceptance, "undetermined", lambda scene, lab: None)


def test_a_rival_that_tied_before_the_body_was_subtracted_refuses_the_pose(monkeypatch):
    """Before the subtraction the best labelling beat a rival 180° away by 4 χ²; after it, the
    best explained two balls more and led by 108: the tie stands, the pose is refused."""
    _pass_other_tests(monkeypatch)
    h = _hypotheses(1)[0]
    turned = identify.BeadHypothesis(
        Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix() @ h.R, h.t + [0.0, 0.0, 2.0], {}, 7, 0.5
    )
    first = _labelling(h, True, ALL_BALLS[:7], ALL_ELLIPSES[:1], 504.5)
    redone = _labelling(h, True, ALL_BALLS, ALL_ELLIPSES[:1], 400.0)
    rival = _labelling(turned, True, ALL_BALLS[:8], ALL_ELLIPSES, 508.4)
    opts = TrackOptions().acceptance
    kept = pipeline.accept_best(None, redone, [rival], Diagnostics(), opts)
    assert kept.pose.converged
    refused = pipeline.accept_best(None, redone, [rival], Diagnostics(), opts, first)
    assert not refused.pose.converged
    assert refused.pose.error.startswith("ambiguous identification")
    # a rival far behind before the subtraction as well (beyond a near-mirror's wider margin
    # too: this one is turned 180°) is no rival
    behind = max(opts.ambiguity_chi2, opts.mirror_ambiguity_chi2) + 1.0
    far_behind = _labelling(turned, True, ALL_BALLS[:8], ALL_ELLIPSES, 504.5 + behind)
    assert pipeline.accept_best(None, redone, [far_behind], Diagnostics(), opts, first).pose.converged


def test_a_rival_inside_the_best_poses_covariance_is_no_other_answer(monkeypatch):
    """A labelling 8 mm deeper, 12 χ² behind: the pose's covariance either allows that depth
    (σ 5 mm: χ²₆ 2.6, the pose is given out and already says so) or does not (σ 1 mm: χ²₆ 64,
    ambiguous)."""
    _pass_other_tests(monkeypatch)
    h = _hypotheses(1)[0]
    deeper = identify.BeadHypothesis(h.R, h.t + [0.0, 0.0, 8.0], {}, 7, 0.5)
    opts = TrackOptions().acceptance
    for sigma_z, given in ((5.0, True), (1.0, False)):
        best = _labelling(h, True, ALL_BALLS, ALL_LINES + ALL_ELLIPSES, 100.0)
        best.pose.covariance = np.diag([1e-6, 1e-6, 1e-6, 0.01, 0.01, sigma_z**2])
        rival = _labelling(deeper, True, ALL_BALLS, ALL_LINES + ALL_ELLIPSES, 112.0)
        m = pipeline.acceptance.inside_covariance(best.pose, rival.pose)
        assert m == pytest.approx((8.0 / sigma_z) ** 2)
        out = pipeline.accept_best(None, best, [rival], Diagnostics(), opts)
        assert out.pose.converged is given, (sigma_z, out.pose.error)


def test_inside_covariance_follows_the_rotation_convention():
    """The rotation part is the left rotation vector log(R_other R_poseᵀ): a turn of 0.01 rad
    about the view axis reads as 1 σ when that axis's σ is 0.01 rad, and the same turn on the
    right of a tilted pose reads as the same turn on the left rotated into camera axes."""
    h = _hypotheses(1)[0]
    tilted = Rotation.from_rotvec([0.4, -0.2, 0.3]).as_matrix()
    base = _labelling(identify.BeadHypothesis(tilted, h.t, {}, 9, 0.5), True, ALL_BALLS, [], 1.0).pose
    base.covariance = np.diag([1e-2, 1e-2, 1e-4, 1.0, 1.0, 1.0])
    turned = Rotation.from_rotvec([0.0, 0.0, 0.01]).as_matrix() @ tilted
    other = _labelling(identify.BeadHypothesis(turned, h.t, {}, 9, 0.5), True, ALL_BALLS, [], 1.0).pose
    assert pipeline.acceptance.inside_covariance(base, other) == pytest.approx(1.0, rel=1e-6)
    base.covariance = None
    assert pipeline.acceptance.inside_covariance(base, other) == np.inf


def test_an_image_is_given_the_refusal_of_the_region_that_got_furthest():
    """Of the regions searched without a pose, the image's refusal is the one that got
    furthest: an ambiguity (two answers) over a labelling refined to a pose, over more balls
    used, over blobs alone — not the first region's, which may have had nothing to read."""
    from ftrac_design.segment.options import failed_result

    blank = failed_result("no fiducial found: 0 bead-like blobs", diagnostics=Diagnostics(blobs=0))
    blobs = failed_result("no fiducial found: 12 blobs, none matching", diagnostics=Diagnostics(blobs=12))
    posed = failed_result(
        "identification not confirmed", diagnostics=Diagnostics(blobs=9, labellings_tested=3, beads_matched=5)
    )
    more = failed_result("too little evidence", diagnostics=Diagnostics(blobs=7, labellings_tested=1, beads_matched=7))
    tie = failed_result(
        "ambiguous identification",
        diagnostics=Diagnostics(blobs=5, labellings_tested=2, beads_matched=5, alternatives=[{}, {}]),
    )
    ranked = sorted([tie, blank, more, posed, blobs], key=pipeline._progress)
    assert [r.pose.error.split(":")[0] for r in ranked] == [
        "no fiducial found",
        "no fiducial found",
        "identification not confirmed",
        "too little evidence",
        "ambiguous identification",
    ]
    assert ranked[0] is blank


def test_the_pixels_settle_a_tie_only_by_their_margin_and_against_every_turned_labelling(monkeypatch):
    """A rival 40° off about the view axis, 5 χ² behind: a tie, refused — unless the pixels
    prefer the best by ``pixel_tie_z`` (3) units, and no labelling turned from it (a third, 60°
    off, not tied: 100 χ² behind) explains them better by as many."""
    h = _hypotheses(4)
    opts = TrackOptions().acceptance
    best = _labelling(h[0], True, ALL_BALLS, ALL_ELLIPSES, 100.0)
    tied = _labelling(h[2], True, ALL_BALLS, ALL_ELLIPSES, 105.0)
    behind = _labelling(h[3], True, ALL_BALLS, ALL_ELLIPSES, 200.0)
    for pixel_z, given in (
        (None, False),
        ({40: 2.9}, False),
        ({40: 3.1}, True),
        ({40: 3.1, 60: -2.9}, True),
        ({40: 3.1, 60: -3.1}, False),
    ):
        _pass_other_tests(monkeypatch, pixel_z)
        diag = Diagnostics()
        out = pipeline.accept_best(None, best, [tied, behind], diag, opts)
        assert out.pose.converged is given, (pixel_z, out.pose.error)
        if not given:
            assert out.pose.error.startswith("ambiguous identification") and diag.settled_by_pixels is None
        else:
            # the pose says which rival the pixels refuted, and by how much; it reads back
            assert diag.settled_by_pixels == [{"rotation_deg": 40.0, "translation_mm": 0.0, "z": 3.1}]
            assert Diagnostics.from_dict(diag.to_dict()).settled_by_pixels == diag.settled_by_pixels
    _pass_other_tests(monkeypatch, {40: 10.0})
    off = pipeline.accept_best(None, best, [tied, behind], Diagnostics(), replace(opts, pixel_tie_z=0.0))
    assert not off.pose.converged


def test_the_rival_the_pixels_prefer_is_judged_first(monkeypatch):
    """The least misfit (a near-mirror that read two blobs more) and a rival 40° from it, tied:
    where the pixels prefer the rival by 3 units it is judged first, the other among its rivals;
    a rival that has not converged, or one the pixels prefer by less, is not."""
    h = _hypotheses(3)
    opts = TrackOptions().acceptance
    least = _labelling(h[0], True, ALL_BALLS, ALL_ELLIPSES, 100.0)
    tied = _labelling(h[2], True, ALL_BALLS, ALL_ELLIPSES, 110.0)
    _pass_other_tests(monkeypatch, {40: -3.1})
    first, rest = pipeline.acceptance.pixel_preferred(None, least, [tied], opts)
    assert first is tied and rest == [least]
    _pass_other_tests(monkeypatch, {40: -2.9})
    assert pipeline.acceptance.pixel_preferred(None, least, [tied], opts)[0] is least
    _pass_other_tests(monkeypatch, {40: -3.1})
    unconverged = _labelling(h[2], False, ALL_BALLS, ALL_ELLIPSES, 110.0)
    assert pipeline.acceptance.pixel_preferred(None, least, [unconverged], opts)[0] is least


@pytest.mark.parametrize(
    ("absent", "redo_curves", "revived"),
    [
        (["E1"], ALL_ELLIPSES[1:], False),
        (["E1"], ALL_ELLIPSES, True),
        (["L3"], ALL_ELLIPSES[:1], True),
        (["L3", "E2"], ALL_ELLIPSES[:1] + ALL_LINES, False),
    ],
)
def test_the_body_subtracted_redo_revives_a_labelling_only_with_the_ellipses_it_was_refused_for(
    monkeypatch, absent, redo_curves, revived
):
    """A labelling refused for putting wire on bare background is refitted on the image with the
    body subtracted, and that converges and passes every test: where the refusal named an
    ellipse, the redo is the answer only if it found that ellipse's contour (the body's edge
    had hidden it) — a wrong labelling puts the ellipses, the longest wires, on bare
    background, and the subtraction adds no evidence of a wire the image never showed. A
    straight wire alone, the faintest feature, need not show."""
    _pass_other_tests(monkeypatch)
    h = _hypotheses(1)[0]
    first = _labelling(h, True, ALL_BALLS[:4], ALL_ELLIPSES[1:], 300.0)
    first = replace(first, pose=replace(first.pose, converged=False, error=pipeline.acceptance.no_wire_there(absent)))
    redone = _labelling(h, True, ALL_BALLS[:4], redo_curves, 290.0)
    # the curves read as bare background at the refused pose only: the redo's pass (as E1
    # did, at 1.2 noise units, on the image that led to this rule)
    monkeypatch.setattr(
        pipeline.acceptance,
        "unshown_curves",
        lambda scene, pose, opts, also=None: ([] if pose.converged else absent, {}),
    )
    monkeypatch.setattr(pipeline, "_with_body_subtracted", lambda g, scene, best, *a: (redone, scene))
    scene = SimpleNamespace(features=SimpleNamespace(body=object(), ellipses=F.ellipses))
    opts = TrackOptions()
    diag = Diagnostics()
    out, _ = pipeline._judged(None, scene, [first], [], diag, opts.finding, opts.labelling, opts.acceptance)
    assert out.pose.converged is revived
    assert bool(diag.body_subtracted) is revived
    if not revived:
        assert out.pose.error.startswith(pipeline.acceptance.NO_WIRE_THERE)
