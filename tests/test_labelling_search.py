"""Which bead hypotheses are refined into labellings: the first few always, and the rest of
those found while the best pose so far rests on little (two or more balls unexplained, or
fewer than half the wires), so that a near-mirror labelling ranked first cannot pass for want
of the right one ranked below it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_fuzz_observation import FEATURES

from ftrac_design.pose import NoiseModel, Pose
from ftrac_design.segment import TrackOptions, identify, pipeline
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
    pose = Pose(h.R, h.t, converged, 0.3, np.eye(6), {}, 3, None if converged else "refused")
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


def test_a_pose_on_every_feature_stops_after_the_first_four(refine):
    table, _ = refine
    table[0] = (True, ALL_BALLS, ALL_LINES + ALL_ELLIPSES, 300.0)
    _, calls = _run(refine, _hypotheses(8))
    assert calls == [0, 1, 2, 3]


def test_the_extension_stops_once_a_full_pose_is_found(refine):
    table, _ = refine
    for i in range(4):
        table[i] = (True, ALL_BALLS[:6], ALL_ELLIPSES, 900.0)
    table[4] = (True, ALL_BALLS[:8], ALL_LINES, 400.0)
    _, calls = _run(refine, _hypotheses(8))
    assert calls == [0, 1, 2, 3, 4]


def test_no_converged_pose_asks_for_no_more_work(refine):
    """Refusals alone do not extend the search: the work is kept for the other polarity and
    region, where the right pose was on a blurred image of the tuning seed."""
    table, _ = refine
    for i in range(8):
        table[i] = (False, ALL_BALLS[:5], [], 2000.0)
    _, calls = _run(refine, _hypotheses(8))
    assert calls == [0, 1, 2, 3]


def test_the_options_set_both_counts(refine):
    table, _ = refine
    for i in range(8):
        table[i] = (True, ALL_BALLS[:5], ALL_ELLIPSES, 2000.0)
    _, calls = _run(refine, _hypotheses(8), labellings_if_weak=4)
    assert calls == [0, 1, 2, 3]
    _, calls2 = _run(refine, _hypotheses(8), labellings=2, labellings_if_weak=6)
    assert calls2[4:] == [0, 1, 2, 3, 4, 5]


def test_a_wireless_design_is_judged_on_its_balls_alone():
    nine = FEATURES["nine_bead"]
    assert not nine.lines and not nine.ellipses
    h = _hypotheses(1)[0]
    all_nine = [p.id for p in nine.points]
    assert not pipeline._rests_on_little(nine, [_labelling(h, True, all_nine[:-1], [], 1.0)])
    assert pipeline._rests_on_little(nine, [_labelling(h, True, all_nine[:-2], [], 1.0)])
