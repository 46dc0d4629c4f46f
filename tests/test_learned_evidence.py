"""A labelling whose wire contours could not be measured, confirmed by the learned detector's
wire map alone, must explain all but one of a wire design's balls; so must one whose wire
contours appeared only once the body's projection was subtracted at its pose. A pose resting on
balls alone must fit them as well as balls fit: its χ² no more improbable than the probability
at which one feature is dropped."""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_pose
from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation
from ftrac_design.segment import TrackOptions, acceptance, evidence, identify, pipeline, track_image
from ftrac_design.segment.detection import Scene, scales
from ftrac_design.segment.labelling import Labelling
from ftrac_design.segment.noise import calibrated_covariance
from ftrac_design.segment.region import mirror_signal_px
from ftrac_design.xray import render

#: the learned detector's 64 most probable candidates of a frame, with which the near-mirror
#: cases below were found (the 256 kept by default now find the right labelling first there)
FOUND_WITH = TrackOptions(detector_candidates=64)


@pytest.mark.parametrize(
    ("preset", "balls", "ridge", "refused"),
    [
        ("ftrac_2005", 8, 0.0, False),
        ("ftrac_2005", 7, 0.0, True),
        ("ftrac_2005", 7, 3.0, False),
        ("nine_bead", 7, 0.0, False),
    ],
)
def test_a_labelling_confirmed_by_the_network_alone_needs_all_but_one_ball(preset, balls, ridge, refused, monkeypatch):
    """No wire contour measured, every wire confirmed by the network: 8 of ftrac_2005's 9
    balls are enough, 7 are not (a near-mirror labelling can fit 7 of 9) — unless the image's
    own ridges show every wire where the pose puts them (here 3 noise units along each, in a
    view set apart from its mirror image). A design with no wires keeps its own rule: all
    but two balls (7 of nine_bead's 9)."""
    features = compute_features(load_design(preset))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = [p.id for p in features.points][:balls]
    obs = simulate_observation(features, Camera(), R[0], t[0], include=set(ids))
    assert len(obs.points) == balls and not obs.lines and not obs.ellipses
    monkeypatch.setattr(evidence, "learned_confirms_wires", lambda *a, **k: True)
    curves = [c.id for c in features.lines] + [e.id for e in features.ellipses]
    shown = {fid: evidence.CurveSupport(ridge, 400, 0.9) for fid in curves}
    monkeypatch.setattr(evidence, "curve_support", lambda *a, **k: shown)
    scene = SimpleNamespace(features=features, scales=SimpleNamespace(ridge_sigma_px=1.35), bead_exclusion=lambda: None)
    lab = _labelling(obs, R[0], t[0])
    why = acceptance.too_little_evidence(scene, lab, TrackOptions().acceptance)
    if refused:
        assert why is not None and f"{balls} beads and no wires cannot verify" in why and "need ≥ 8" in why
    else:
        assert why is None


def _labelling(obs, R, t, wires_at_first: bool = True) -> Labelling:
    pose = SimpleNamespace(rotation=R, translation_mm=t)
    return Labelling(pose, obs, None, {}, identify.Contours(), {}, wires_at_first=wires_at_first)


@pytest.mark.parametrize(("balls", "at_first", "refused"), [(7, True, False), (7, False, True), (8, False, False)])
def test_wire_contours_seen_only_after_the_body_subtraction_do_not_confirm_a_labelling(
    balls, at_first, refused, monkeypatch
):
    """Seven of ftrac_2005's balls and one ellipse's contour: enough when the labelling explained
    a wire before the body was subtracted, not when that contour appeared only after it (a
    near-mirror labelling's ellipse on the other ellipse's image) and the image's ridges do not
    show its wires where the pose puts them; eight balls are enough either way."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = [p.id for p in features.points][:balls]
    obs = simulate_observation(features, Camera(), R[0], t[0], include=set(ids) | {"E1"})
    assert len(obs.points) == balls and list(obs.ellipses) == ["E1"] and not obs.lines
    monkeypatch.setattr(evidence, "learned_confirms_wires", lambda *a, **k: False)
    bare = {fid: evidence.CurveSupport(0.0, 400, 0.0) for fid in ("L1", "L2", "L3", "E1", "E2")}
    monkeypatch.setattr(evidence, "curve_support", lambda *a, **k: bare)
    lab = _labelling(obs, R[0], t[0], wires_at_first=at_first)
    assert lab.confirmed_by_wires is at_first
    scene = SimpleNamespace(features=features, scales=SimpleNamespace(ridge_sigma_px=1.35), bead_exclusion=lambda: None)
    why = acceptance.too_little_evidence(scene, lab, TrackOptions().acceptance)
    if refused:
        assert why is not None and "wires seen only after the body's subtraction cannot verify" in why
    else:
        assert why is None


@pytest.mark.parametrize(
    ("factor", "curves", "refused"), [(0.98, False, False), (1.02, False, True), (3.0, True, False)]
)
def test_balls_alone_are_refused_where_their_chi2_is_less_probable_than_a_dropped_feature(factor, curves, refused):
    """Eight balls (χ² with 10 degrees of freedom): a variance factor just inside the χ²₁₀
    quantile at ``feature_p_value`` passes and one just beyond it is refused; a pose that also
    explains a wire contour is judged by the wire, not by this test."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = {p.id for p in features.points[:8]} | ({"E1"} if curves else set())
    obs = simulate_observation(features, Camera(), R[0], t[0], include=ids)
    opts = TrackOptions().acceptance
    vf = factor * chi2.isf(opts.feature_p_value, 10) / 10
    lab = replace(_labelling(obs, R[0], t[0]), variance_factor=vf)
    why = acceptance.balls_misfit(lab, opts)
    assert (why is not None and "χ²10" in why) if refused else why is None


@pytest.mark.parametrize(
    ("factor", "ridge", "missing", "refused"),
    [
        (0.98, 0.0, ("E1", "E2"), False),
        (1.02, 0.0, ("E1", "E2"), True),
        (1.02, 0.0, ("E2",), True),
        (1.02, 3.0, ("E1", "E2"), False),
        (1.02, 0.0, ("L1",), False),
        (1.02, 0.0, (), False),
    ],
)
def test_an_ellipse_on_the_network_s_word_alone_needs_features_that_fit(factor, ridge, missing, refused, monkeypatch):
    """Six balls and two lines' contours (χ² with 10 degrees of freedom), every curve on the
    network's wire map (0.9): where an ellipse has no contour and no ridge (0 noise units;
    present from 3 spreads of a 400-sample median, 0.44), a variance factor just beyond the
    χ²₁₀ quantile at ``feature_p_value`` is refused and one just inside passes; an ellipse
    whose ridge shows (3 units), a line on the network's word alone, or no curve missing
    leaves the fit unjudged."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = {p.id for p in features.points[:6]} | {"L2", "L3"}
    obs = simulate_observation(features, Camera(), R[0], t[0], include=ids)
    assert len(obs.points) == 6 and sorted(obs.lines) == ["L2", "L3"] and not obs.ellipses
    sup = {fid: evidence.CurveSupport(ridge if fid.startswith("E") else 0.0, 400, 0.9) for fid in ("L1", "E1", "E2")}
    monkeypatch.setattr(evidence, "curve_support", lambda *a, **k: sup)
    monkeypatch.setattr(evidence, "learned_confirms_wires", lambda *a, **k: True)
    scene = SimpleNamespace(features=features, scales=SimpleNamespace(ridge_sigma_px=1.35), bead_exclusion=lambda: None)
    opts = TrackOptions().acceptance
    vf = factor * chi2.isf(opts.feature_p_value, 10) / 10
    lab = replace(_labelling(obs, R[0], t[0]), variance_factor=vf, contours=identify.Contours(missing=list(missing)))
    why = acceptance.vouched_misfit(scene, lab, opts)
    if refused:
        assert why is not None and "χ²10" in why and f"{', '.join(sorted(missing))} only the learned detector" in why
    else:
        assert why is None
    assert acceptance.too_little_evidence(scene, lab, opts) == why


@pytest.mark.parametrize(
    ("preset", "balls", "curves", "refused"),
    [
        ("ftrac_2005", ("B1", "B2", "B3", "B4"), ("E1",), True),
        ("ftrac_2005", ("B5", "B6", "B7"), (), True),
        ("ftrac_2005", ("B1", "B2", "B3", "B5"), ("E1",), False),
        ("ftrac_2005", ("B1", "B2", "B3", "B4"), ("L2", "E1"), False),
        ("ftrac_mini", ("B1", "B2", "B3", "B4"), ("E2",), True),
        ("nine_bead", ("B1", "B2", "B3", "B4"), (), False),
    ],
)
def test_balls_of_one_wire_and_one_curve_are_no_labelling(preset, balls, curves, refused):
    """Balls that all lie on one wire leave the turn about it to the curves: with one curve
    or none, refused, the wire named; a ball of another wire among them, a second curve to
    check the first, or a design whose balls lie on no wire, is not judged so."""
    features = compute_features(load_design(preset))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    obs = simulate_observation(features, Camera(), R[0], t[0], include=set(balls) | set(curves))
    assert sorted(obs.points) == sorted(balls) and len(obs.lines) + len(obs.ellipses) == len(curves)
    why = acceptance.balls_of_one_wire(features, obs)
    if refused:
        wire = {p.id: p.line for p in features.points}[balls[0]]
        assert why is not None and f"{len(balls)} beads used all lie on wire {wire}" in why
    else:
        assert why is None


@pytest.mark.parametrize(
    ("seed", "n", "k", "deg", "mm"),
    [(2128, 200, 118, 1.0, 3.0), (2127, 20, 12, 0.5, 1.0)],
)
def test_a_faint_side_view_on_four_balls_of_one_wire_is_tracked_right(seed, n, k, deg, mm, realism_tracked):
    """Two faint display-dark views of ftrac_2005 whose labelling rests on the four balls of
    wire L1. With one ellipse alone to fix the turn about it (seed 2128, image 118) the pose
    was given 4.1° and 6.6 mm off: that labelling refused, the classical detectors' second
    look finds the right one. With two lines and both ellipses (seed 2127, image 12) the
    labelling is right and given."""
    res, d_deg, d_mm, _ = realism_tracked("ftrac_2005", "display-dark", k, seed, n)
    assert res.pose.converged, res.pose.error
    assert d_deg < deg and d_mm < mm


def test_balls_at_the_noise_they_were_measured_with_pass():
    """Balls displaced by the noise model's own σ, the pose solved and its variance factor
    calibrated as the tracker does: the test does not refuse them (20 views)."""
    features = compute_features(load_design("ftrac_mini"))
    Rs, ts = Workspace().sample(20, features.nominal_beam_direction, np.random.default_rng(5))
    ids = {p.id for p in features.points}
    noise, opts = NoiseModel(), TrackOptions().acceptance
    for k, (R, t) in enumerate(zip(Rs, ts)):
        # a uniform magnitude in [0, e] mm has a per-axis σ of e / √6: the model's σ for e = 0.25 mm
        obs = simulate_observation(features, Camera(), R, t, 0.25, np.random.default_rng(100 + k), include=ids)
        pose = solve_pose(features, obs, SolverOptions(noise=noise))
        vf = calibrated_covariance(features, obs, pose, noise)
        assert pose.converged and vf is not None
        assert acceptance.balls_misfit(replace(_labelling(obs, R, t), variance_factor=vf), opts) is None


def _stub_scene(features, ridge_spreads: float, learned: bool):
    """A scene of ``features`` in a 1024² image where every predicted curve's ridge evidence
    reads ``ridge_spreads`` × the spread of its own median (:func:`.evidence.median_spread`)
    and the learned detector's wire probability is 0.6 everywhere (or it is absent)."""
    scene = SimpleNamespace(features=features, camera=Camera(), scales=SimpleNamespace(ridge_sigma_px=1.2))
    scene.readable = lambda uv, margin_px=0.0: np.isfinite(uv).all(-1) & (np.abs(uv - 512.0) < 500).all(-1)
    scene.ridge_evidence = lambda uv, nrm: np.full(len(uv), ridge_spreads * evidence.median_spread(scene, len(uv)))
    scene.learned = object() if learned else None
    scene.learned_wire = lambda uv: np.full(len(uv), 0.6)
    scene.bead_exclusion = lambda extra_px=1.0: np.full(len(features.points), 6.0)
    return scene


@pytest.mark.parametrize(
    ("ridge_spreads", "learned", "absent"),
    [(-0.4, True, "none"), (-0.6, True, "long"), (-0.4, False, "all"), (40.0, False, "none")],
)
def test_a_long_curve_whose_ridge_reads_below_zero_overrules_the_network(monkeypatch, ridge_spreads, learned, absent):
    """The network's map vouches for a curve whose ridge is weak, not for a long one whose
    ridge stands half its spread below zero (what a lattice of balls gave, where the network's
    wire map is high everywhere); a short one keeps it (between balls the ridge reads their
    flanks). Without the network a weak ridge is absent, a plain one present. Every ridge here
    is as weak as the rest, the ellipses' too: the network's word is judged first as where an
    ellipse shows its ridge, then as it stands, for none of them
    (:func:`test_the_networks_word_does_not_stand_for_every_ellipse_at_once`)."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(3))
    scene = _stub_scene(features, ridge_spreads, learned)
    sup = evidence.curve_support(scene, R[0], t[0], scene.bead_exclusion())
    assert set(sup) == {c.id for c in features.lines} | {c.id for c in features.ellipses}
    long = {fid for fid, c in sup.items() if c.samples * 0.5 >= evidence.OVERRULE_MIN_PX}
    assert long and long != set(sup)  # both kinds in view
    overruled = long if learned and ridge_spreads < -evidence.RIDGE_OVERRULES else set()
    assert all(c.learned == (0.6 if learned and fid not in overruled else 0.0) for fid, c in sup.items())
    assert evidence.learned_confirms_wires(scene, R[0], t[0]) is (learned and not overruled)
    pose = SimpleNamespace(rotation=R[0], translation_mm=t[0])
    opts = TrackOptions().acceptance
    with monkeypatch.context() as m:
        m.setattr(acceptance, "an_ellipse_shown", lambda *a: True)
        missing, _ = acceptance.wire_support(scene, pose, opts)
    assert set(missing) == {"none": set(), "long": long, "all": set(sup)}[absent]
    missing, _ = acceptance.wire_support(scene, pose, opts)
    assert set(missing) == (set() if ridge_spreads > 0 else set(sup))


def _ids_2005() -> list[str]:
    """ftrac_2005's curves: its lines, then its ellipses."""
    features = compute_features(load_design("ftrac_2005"))
    return [c.id for c in features.lines] + [c.id for c in features.ellipses]


def _curves_reading(monkeypatch, weak: dict, learned: dict, gone: set):
    """A ftrac_2005 scene whose curve support (:func:`.evidence.curve_support`, 400 samples
    each) reads ``weak``'s ridges (spreads of their median) where given, a plain 40 spreads
    elsewhere, the network's ``learned`` probability (0 where not given), and no curve in
    ``gone``. Returns the scene and the curves' ids."""
    features = compute_features(load_design("ftrac_2005"))
    scene = _stub_scene(features, 0.0, True)
    ids = _ids_2005()
    n = 400
    spread = evidence.median_spread(scene, n)

    def support(scene_, R, t, exclusion):
        return {
            fid: evidence.CurveSupport(ridge=weak.get(fid, 40.0) * spread, samples=n, learned=learned.get(fid, 0.0))
            for fid in ids
            if fid not in gone
        }

    monkeypatch.setattr(acceptance.evidence, "curve_support", support)
    return scene, ids


@pytest.mark.parametrize(
    ("weak", "network", "gone", "absent"),
    [
        ({"L2": 0.0}, set(), set(), []),
        ({"L2": -2.0}, set(), set(), []),
        ({"L2": 0.0, "L3": 0.0}, set(), set(), ["L2", "L3"]),
        ({"E1": 0.0}, set(), set(), ["E1"]),
        ({"L2": 0.0, "E2": 1.0}, {"E2"}, set(), ["L2"]),
        ({"L2": 0.0}, set(), {"E2"}, ["L2"]),
        ({}, set(), set(), []),
    ],
)
def test_one_faint_straight_wire_is_excused_where_the_others_show_plainly(monkeypatch, weak, network, gone, absent):
    """A straight wire whose ridge reads at or below zero, alone, does not refuse a pose whose
    other curves — both ellipses among them — stand clearly above zero on the ridges; two
    such wires, an ellipse, an ellipse the network alone vouches for, or one out of view do.
    Ridges in spreads of their own median (:func:`.evidence.median_spread`), 40 where plain."""
    scene, ids = _curves_reading(monkeypatch, weak, {fid: 0.6 for fid in network}, gone)
    pose = SimpleNamespace(rotation=np.eye(3), translation_mm=np.zeros(3))
    opts = TrackOptions().acceptance
    assert acceptance.unshown_curves(scene, pose, opts)[0] == absent
    plain = acceptance.wire_support(scene, pose, opts)[0]
    assert plain == sorted(set(weak) - network, key=ids.index)
    assert acceptance.absent_wires(scene, pose, opts) == acceptance.no_wire_there(absent)


@pytest.mark.parametrize(
    ("weak", "gone", "absent"),
    [
        ({"E1": 0.0, "E2": 0.0}, set(), ["E1", "E2"]),
        ({"E1": 0.0, "E2": 0.0, "L2": 0.0}, set(), ["L2", "E1", "E2"]),
        ({"E1": 0.0}, {"E2"}, ["E1"]),
        ({"E1": 0.0}, set(), []),
        ({"E1": 0.0, "L2": 0.0}, set(), []),
        ({"L1": 0.0, "L2": 0.0, "L3": 0.0}, set(), []),
    ],
)
def test_the_networks_word_does_not_stand_for_every_ellipse_at_once(monkeypatch, weak, gone, absent):
    """The network's map reads 0.6 along every curve; the curves in ``weak`` have no ridge
    (0 spreads), the rest a plain one. It vouches for weak curves while an ellipse in view
    shows its ridge, and for none of them where no ellipse does: the longest wires, which
    show under blur and in a dark window, all on bare background (fresh seed 2131, round
    field 12, a pose 18.7° off on six balls and one line, its ellipses at 0.2 and 0.18 where
    0.5 was needed)."""
    scene, ids = _curves_reading(monkeypatch, weak, dict.fromkeys(_ids_2005(), 0.6), gone)
    pose = SimpleNamespace(rotation=np.eye(3), translation_mm=np.zeros(3))
    assert acceptance.wire_support(scene, pose, TrackOptions().acceptance)[0] == absent


def test_a_blurred_view_whose_one_straight_wire_reads_faint_is_tracked(realism_tracked):
    """ftrac_2005 under 2 px of blur (tuning seed 2126, 20 per condition, image 13): all nine
    balls and both ellipses, but wire L1's ridge reads 0.8 noise units at the true pose, below
    the 3 spreads a present wire stands above zero; the pose was refused for it. The other
    four curves plain, it is given, within 1° and 2 mm of the truth and inside its covariance."""
    res, d_deg, d_mm, chi2_6 = realism_tracked("ftrac_2005", "blur-2px", 13, 2126, 20)
    assert res.pose.converged, res.pose.error
    assert d_deg < 1.0 and d_mm < 2.0
    assert chi2_6 < chi2.isf(1e-4, 6)


def test_a_wire_the_image_showed_before_the_body_was_subtracted_is_there():
    """The modelled body's limb subtracted too strongly can take a wire's ridge with it: a
    curve the unsubtracted image shows is present, whatever the subtracted one reads; one
    neither shows is absent."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(3))
    pose = SimpleNamespace(rotation=R[0], translation_mm=t[0])
    after, before, bare = (_stub_scene(features, k, False) for k in (-0.6, 40.0, 0.0))
    opts = TrackOptions().acceptance
    assert set(acceptance.wire_support(after, pose, opts)[0]) == set(
        evidence.curve_support(after, R[0], t[0], after.bead_exclusion())
    )
    assert acceptance.wire_support(after, pose, opts, also=before)[0] == []
    assert acceptance.wire_support(before, pose, opts, also=after)[0] == []
    assert len(acceptance.wire_support(after, pose, opts, also=bare)[0]) == len(features.lines) + len(features.ellipses)


def test_a_dewarping_plate_is_not_taken_for_ftrac_2005():
    """A 17 × 17 plate of 2.7 mm balls 5.9 mm apart, distorted, in a round field (the
    no-fiducial benchmark's grid plate 20 of seed 2069): the network's wire map reads 0.4–0.6
    all over the lattice, and a labelling of five balls on three rows of it was given out as
    ftrac_2005 with both ellipses on bare plate; no pose, whichever detector."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from no_fiducial import grid

    img = grid(20, 2069)
    features = compute_features(load_design("ftrac_2005"))
    camera = Camera(principal_point_px=(img.shape[1] / 2, img.shape[0] / 2))
    for detector in ("auto", "classical"):
        res = track_image(img, features, camera, TrackOptions(detector=detector))
        assert not res.pose.converged, detector


def test_ellipses_only_the_network_shows_need_features_that_fit(monkeypatch):
    """A dewarping plate (the no-fiducial benchmark's grid plate 64 of seed 2126) taken for
    ftrac_2005 on six balls and two lines fitting at p = 6·10⁻¹³, both ellipses with no
    contour and no ridge, present on the network's wire map alone: no pose — for its
    ellipses on bare plate, and, where the network's word stood for them, for those ellipses
    with features that do not fit. Without either test the same image gives that pose, so the
    image exercises both. The hypotheses are ranked by their wires at their P3P poses alone,
    as when the image was found: ranked again at fitted poses, the search refines other
    labellings first and refuses them as inconsistent before this one is refined."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from no_fiducial import grid

    monkeypatch.setattr(pipeline, "POLISHED", 0)
    img = grid(64, 2126)
    features = compute_features(load_design("ftrac_2005"))
    camera = Camera(principal_point_px=(img.shape[1] / 2, img.shape[0] / 2))
    res = track_image(img, features, camera, TrackOptions(detector="learned"))
    assert not res.pose.converged
    monkeypatch.setattr(acceptance, "an_ellipse_shown", lambda *a: True)
    res = track_image(img, features, camera, TrackOptions(detector="learned"))
    assert not res.pose.converged
    assert "E1, E2 only the learned detector shows" in res.pose.error
    monkeypatch.setattr(acceptance, "vouched_ellipses", lambda *a: [])
    assert track_image(img, features, camera, TrackOptions(detector="learned")).pose.converged


def test_a_lattice_the_network_did_not_rank_is_not_taken_for_nine_bead():
    """A grid plate in a round field (the no-fiducial benchmark's grid plate 42 of seed 2090):
    nine_bead fitted seven balls of the lattice; only two of the lattice's other balls among
    them had been fitted (the network ranks its candidates and the strongest are fitted), so
    the stray-ball test saw two; the network reads 17 there. No pose."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from no_fiducial import grid

    img = grid(42, 2090)
    camera = Camera(principal_point_px=(img.shape[1] / 2, img.shape[0] / 2))
    res = track_image(img, compute_features(load_design("nine_bead")), camera)
    assert not res.pose.converged


@pytest.mark.parametrize("reads", [1.0, 0.2])
def test_network_peaks_are_the_blobs_the_network_reads_as_balls(reads):
    """Blobs (σ one radius, 10 noise units) at the nine balls and at five points among them:
    every local maximum is found, to the pixel, where the network reads balls; none where it
    does not."""
    features = compute_features(load_design("nine_bead"))
    camera = Camera()
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(3))
    uv = identify.project(camera, R[0], t[0], features.point_centers())[0]
    sc = scales(features, camera, TrackOptions().finding)
    rng = np.random.default_rng(4)
    lo, hi = uv.min(0), uv.max(0)
    extra = np.round(lo + rng.uniform(0.2, 0.8, (5, 2)) * (hi - lo))
    blobs = np.vstack([np.round(uv), extra])
    keep = np.linalg.norm(blobs[:, None] - blobs[None], axis=-1) + np.eye(len(blobs)) * 1e9
    blobs = blobs[keep.min(1) > 4 * sc.bead_radius_px]
    H, W = int(2 * camera.principal_point_px[1] + 1), int(2 * camera.principal_point_px[0] + 1)
    yy, xx = np.mgrid[0:H, 0:W]
    snr = np.zeros((H, W), np.float32)
    for u, v in blobs:
        snr += (10 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * sc.bead_radius_px**2))).astype(np.float32)
    net = SimpleNamespace(ball_probability=lambda p: np.full(len(p), reads))
    z = np.zeros((H, W), np.float32)
    scene = Scene(features, camera, sc, z, np.ones_like(z), None, None, blob_snr=snr, learned=net)
    found = acceptance.network_peaks(scene, uv, np.ones(len(uv), bool), 0.7)
    if reads < 0.5:
        assert len(found) == 0
        return
    inside = blobs[(blobs >= 0).all(1) & (blobs[:, 0] < W) & (blobs[:, 1] < H)]
    assert len(found) == len(inside)
    assert np.linalg.norm(found[:, None] - inside[None], axis=-1).min(1).max() < 1e-9


@pytest.mark.parametrize(
    ("probability", "refused"), [([0.29, 0.01, 0.2], True), ([0.29, 0.5, 0.2], False), ([], False)]
)
def test_a_classical_pose_needs_the_network_to_read_one_of_its_balls(probability, refused):
    why = acceptance.unseen_balls(np.array(probability))
    assert (why is not None) == refused
    if refused:
        assert "none of the 3 balls" in why and "at most 0.29" in why


def test_another_fiducials_frame_is_not_taken_for_nine_bead_by_the_classical_second_look(another_fiducial):
    """A raw frame of ftrac_mini over bright anatomy (the no-fiducial benchmark's "another
    fiducial" 46 of seed 2088): tracked as nine_bead, the network found no labelling and the
    classical second look fitted the helix to seven blobs where dark edges cross, 939 mm from
    the source; the network reads 0.01–0.29 at those seven. No pose."""
    shown, res = another_fiducial(46, 2088, "nine_bead")
    assert shown == "ftrac_mini"
    assert not res.pose.converged
    assert res.diagnostics.detector_tried == ["learned", "classical"]


@pytest.mark.parametrize("undetermined_asked", [True, False])
def test_anatomy_alone_is_not_taken_for_nine_bead_by_the_networks_own_pass(undetermined_asked, monkeypatch):
    """A frame of anatomy with no fiducial at all (the no-fiducial benchmark's anatomy 60 of
    seed 2109): tracked as nine_bead, the network's own pass fitted the helix to seven of its
    candidates, each of which it read 0.01–0.21 — a pose 888 mm from the source with a depth
    σ of 108 mm. Two rules refuse it, each alone: the pose places the fiducial no better than
    its size, and balls the network does not read as balls confirm no bead-only pose, from
    either pass; the classical second look finds none either."""

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from no_fiducial import anatomy

    if not undetermined_asked:
        monkeypatch.setattr(pipeline.acceptance, "undetermined", lambda scene, lab: None)
    img = anatomy(60, 2109)
    camera = Camera(principal_point_px=(img.shape[1] / 2, img.shape[0] / 2))
    res = track_image(img, compute_features(load_design("nine_bead")), camera)
    assert not res.pose.converged
    if undetermined_asked:
        head = "too little evidence: the pose places the fiducial only to ±"
        assert res.pose.error.startswith(head)
        assert float(res.pose.error[len(head) :].split(" mm")[0]) > 100  # the depth σ of 108 mm
    else:
        assert res.pose.error.startswith("identification not confirmed: the learned detector reads none of the 7 balls")
    assert res.diagnostics.detector_tried == ["learned", "classical"]


@pytest.mark.parametrize(
    ("crowded", "at_first", "mirror_px", "refused"),
    [(2, True, 0.0, False), (1, True, 0.0, True), (1, True, 2.0, False), (6, False, 2.0, True), (0, True, 2.0, True)],
)
def test_balls_that_crowd_in_pairs_count_where_wires_confirm_the_labelling(crowded, at_first, mirror_px, refused):
    """Three of ftrac_2005's balls used (of two wires) and every wire's contour: the balls the labelling left
    out because their blobs blend in pairs, but which the image shows where it puts them,
    make up the five a labelling needs — when its wire contours were there from the first
    (not only once the body was subtracted) — or the four it needs where the view is set
    apart from its mirror image (``mirror_signal_px``; 0: never)."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = {"B1", "B2", "B5"} | {c.id for c in features.lines} | {c.id for c in features.ellipses}
    obs = simulate_observation(features, Camera(), R[0], t[0], include=ids)
    lab = _labelling(obs, R[0], t[0], wires_at_first=at_first)
    lab = replace(lab, contours=identify.Contours(crowded_shown=crowded))
    scene = SimpleNamespace(features=features, learned=None)  # the classical path: no network to confirm
    why = acceptance.too_little_evidence(scene, lab, TrackOptions(mirror_signal_px=mirror_px).acceptance)
    if refused:
        assert why is not None and "3 beads could be used" in why
    else:
        assert why is None


@pytest.mark.parametrize(("variance_factor", "refused"), [(5.82, True), (2.08, False), (None, False)])
def test_crowded_balls_confirm_a_view_not_set_apart_from_its_mirror_only_with_a_good_fit(variance_factor, refused):
    """ftrac_mini seen where perspective cannot set a view apart from its mirror image (its
    signal below 2 px everywhere in the workspace): four balls of three wires and one ellipse's contour, and
    five unused balls beside them that the image shows. A near-mirror labelling's unused
    balls fall on the right one's blobs too, so they make up the five balls it needs only
    where the features it fitted fit as features do: χ²₇ = 7 × 5.82 (p = 9·10⁻⁷, the
    near-mirror of held-out seed 2124, 178° off) is refused, 7 × 2.08 (p = 0.04, a right
    pose there) is not."""
    features = compute_features(load_design("ftrac_mini"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    assert mirror_signal_px(features, Camera(), R[0], t[0]) < 2.0
    ids = {"B1", "B2", "B5", "B8", "E1"}
    obs = simulate_observation(features, Camera(), R[0], t[0], include=ids)
    lab = _labelling(obs, R[0], t[0])
    lab = replace(lab, contours=identify.Contours(crowded_shown=5), variance_factor=variance_factor)
    scene = SimpleNamespace(features=features, learned=None)
    opts = TrackOptions().acceptance
    why = acceptance.too_little_evidence(scene, lab, opts)
    if refused:
        assert why is not None and "4 beads beside balls that crowd its others" in why and "χ²7 = 40.7" in why
    else:
        assert why is None
    # without the crowded balls the four are too few, however well they fit
    alone = acceptance.too_little_evidence(scene, replace(lab, contours=identify.Contours()), opts)
    assert alone is not None and "4 beads could be used (need 5" in alone


def test_a_display_frame_s_near_mirror_of_ftrac_mini_is_refused():
    """The image where that happened (held-out seed 2124, 20 per condition, display-bright
    image 1): the answer used four balls and one ellipse's contour, 178° and 27 mm off,
    χ²₇ = 40.7 of its features. Refused, it leaves the right labelling (0.6° off, its depth
    7.8 mm off within its own covariance: χ²₆ of its error below 25.7); with the fit not asked
    of crowded balls (``crowd_p_value=0``), the near-mirror is given."""
    from test_wider_rivals import _image

    img, features, R, t = _image("ftrac_mini", "display-bright", 1, 2124, 20)
    res = track_image(img, features, Camera(), FOUND_WITH)
    assert res.pose.converged, res.pose.error
    dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R, t)
    e = np.concatenate([dr, dt])
    assert math.degrees(float(np.linalg.norm(dr))) < 1.0
    assert float(e @ np.linalg.solve(res.pose.covariance, e)) < chi2.isf(1e-4, 6)
    wrong = track_image(img, features, Camera(), replace(FOUND_WITH, crowd_p_value=0.0))
    assert wrong.pose.converged
    dr, dt = pose_errors(wrong.pose.rotation, wrong.pose.translation_mm, R, t)
    assert math.degrees(float(np.linalg.norm(dr))) > 170.0 and float(np.linalg.norm(dt)) > 20.0


def test_a_side_view_whose_balls_overlap_in_pairs_is_tracked():
    """ftrac_2005 seen from the side (the independent check's first pose of seed 2027): six of
    its balls overlap in three pairs 5–8 px apart and only the other three can be fitted;
    with all five wires' contours the pose is given, within 0.1° and 0.5 mm of the truth."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(30, features.nominal_beam_direction, np.random.default_rng(2027))
    img = render(features, R[0], t[0], Camera(), rng=np.random.default_rng(0)).raw
    res = track_image(img, features, Camera())
    assert res.pose.converged, res.pose.error
    assert sorted(res.observation.points) == ["B3", "B8", "B9"]
    dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R[0], t[0])
    assert np.degrees(np.linalg.norm(dr)) < 0.1 and np.linalg.norm(dt) < 0.5


@pytest.mark.parametrize(("depth_sigma_mm", "refused"), [(74.0, True), (30.0, False), (1.0, False)])
def test_a_pose_that_places_the_fiducial_no_better_than_its_size_is_refused(depth_sigma_mm, refused):
    """nine_bead's largest extent is 37.8 mm (its balls): a pose whose depth σ is 74 mm (Poisson noise tracked as
    nine_bead, no-fiducial seed 2110) says nothing of where the fiducial is; 30 mm and 1 mm
    pass this test (others judge them)."""
    features = compute_features(load_design("nine_bead"))
    c, s = np.cos(0.3), np.sin(0.3)
    Q = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # the worst direction off the axes
    C = np.zeros((6, 6))
    C[:3, :3] = 1e-6 * np.eye(3)
    C[3:, 3:] = Q @ np.diag([1.0, 1.0, depth_sigma_mm**2]) @ Q.T
    lab = SimpleNamespace(pose=SimpleNamespace(covariance=C))
    why = acceptance.undetermined(SimpleNamespace(features=features), lab)
    assert (why is not None) == refused
    if refused:
        assert "±74 mm" in why and "38 mm" in why


def test_a_blurred_frame_s_balls_are_confirmed_by_the_ridges_of_its_wires():
    """ftrac_2005 under 2 px of blur (seed 2125, 20 per condition, blur image 7): six balls
    fitted and no wire contour, too faint point by point, while the ridges along the pose's
    ellipses stand well above zero. The right labelling is given (within 1° and 3 mm, χ²₆ of
    its error below 25.7); where the ridges' word is never taken (``ridge_confirm_p_value=1``)
    it is refused for its six balls."""
    from test_wider_rivals import _image

    img, features, R, t = _image("ftrac_2005", "blur-2px", 7, 2125, 20)
    res = track_image(img, features, Camera())
    assert res.pose.converged, res.pose.error
    assert len(res.observation.points) == 6 and not (res.observation.lines or res.observation.ellipses)
    dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R, t)
    e = np.concatenate([dr, dt])
    assert math.degrees(float(np.linalg.norm(dr))) < 1.0 and float(np.linalg.norm(dt)) < 3.0
    assert float(e @ np.linalg.solve(res.pose.covariance, e)) < chi2.isf(1e-4, 6)
    never = track_image(img, features, Camera(), TrackOptions(ridge_confirm_p_value=1.0))
    assert not never.pose.converged and "6 beads and no wires cannot verify" in never.pose.error


@pytest.mark.parametrize(("preset", "balls"), [("ftrac_mini", 8), ("ftrac_2005", 5)])
def test_ridges_confirm_no_view_tied_to_its_mirror_and_no_fewer_than_six_balls(preset, balls):
    """The ridges' word is not asked where perspective cannot set the view apart from its
    mirror image (ftrac_mini: a near-mirror labelling puts its wires where the right one's
    lie) nor for fewer than six balls, however plain the wires: no image is read."""
    features = compute_features(load_design(preset))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = {p.id for p in features.points[:balls]}
    lab = _labelling(simulate_observation(features, Camera(), R[0], t[0], include=ids), R[0], t[0], False)
    scene = SimpleNamespace(features=features)  # any look at the image would fail
    assert not acceptance.ridges_confirm(scene, lab, TrackOptions().acceptance)


@pytest.mark.parametrize(
    ("preset", "turn_deg", "shift_mm", "margin", "rival"),
    [
        ("ftrac_mini", 176.0, 2.0, 26.6, True),
        ("ftrac_mini", 176.0, 2.0, 55.0, False),
        ("ftrac_mini", 176.0, 200.0, 26.6, False),
        ("ftrac_mini", 60.0, 2.0, 26.6, False),
        ("ftrac_mini", 60.0, 2.0, 20.0, True),
        ("ftrac_2005", 176.0, 2.0, 26.6, False),
        ("ftrac_2005", 176.0, 2.0, 20.0, True),
    ],
)
def test_a_near_mirror_ties_at_a_wider_margin_only_where_the_view_is_its_mirror_s(
    preset, turn_deg, shift_mm, margin, rival
):
    """A labelling turned 90° or more from the best and no farther than the fiducial's extent
    ties with it within 50 of its misfit in a view perspective does not set apart from its
    mirror image (ftrac_mini's: a near-mirror 176° off fitted 3 balls and both ellipses 26.6
    better than the right one, held-out seed 2126), within 25 otherwise: one 200 mm away (a
    nine_bead labelling 235 mm off is no mirror), one turned less, and any in ftrac_2005's
    views, whose perspective sets them apart."""
    features = compute_features(load_design(preset))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    obs = simulate_observation(features, Camera(), R[0], t[0])
    cov = np.diag([1e-6] * 3 + [1e-2] * 3)
    best = replace(_labelling(obs, R[0], t[0]), score=40.0)
    best = replace(best, pose=SimpleNamespace(rotation=R[0], translation_mm=t[0], covariance=cov, noise_scale=1.0))
    turn = Rotation.from_rotvec(np.radians(turn_deg) * np.array([1.0, 0.0, 0.0])).as_matrix()
    other = replace(best, score=40.0 + margin)
    moved = t[0] + np.array([shift_mm, 0.0, 0.0])
    other = replace(
        other, pose=SimpleNamespace(rotation=turn @ R[0], translation_mm=moved, error=None, noise_scale=1.0)
    )
    r = acceptance.rival(SimpleNamespace(features=features), best, other, TrackOptions().acceptance)
    assert (r is not None) == rival
    if rival:
        assert r[0].startswith(f"ambiguous identification: another labelling {turn_deg:.1f}°")


def test_a_round_field_s_near_mirror_of_ftrac_mini_is_no_answer():
    """The image where that happened (held-out seed 2126, 20 per condition, round-field image
    12): three balls and both ellipses fitted 176° off, 26.6 better than the right labelling,
    and given with χ²₆ of its error 1.3·10⁵. Judged as a tie, the image's pixels prefer the
    right one: no confident wrong pose is given (here the right labelling, its error within
    its covariance); at the narrower margin (``mirror_ambiguity_chi2=25``) the near-mirror is."""
    from test_wider_rivals import _image

    img, features, R, t = _image("ftrac_mini", "round-shutter", 12, 2126, 20)
    res = track_image(img, features, Camera(), FOUND_WITH)
    if res.pose.converged:
        dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R, t)
        e = np.concatenate([dr, dt])
        assert float(e @ np.linalg.solve(res.pose.covariance, e)) < chi2.isf(1e-4, 6)
        assert math.degrees(float(np.linalg.norm(dr))) < 1.0
    wrong = track_image(img, features, Camera(), replace(FOUND_WITH, mirror_ambiguity_chi2=25.0))
    assert wrong.pose.converged
    dr, _ = pose_errors(wrong.pose.rotation, wrong.pose.translation_mm, R, t)
    assert math.degrees(float(np.linalg.norm(dr))) > 170.0


@pytest.mark.parametrize(
    ("balls", "faint", "unread", "confirmed"),
    [
        (7, {"L1", "L2", "L3"}, set(), True),
        (6, {"L1", "L2", "L3"}, set(), False),
        (6, {"L2"}, set(), True),
        (7, {"E1", "L1"}, set(), False),
        (7, {"L1", "L2"}, {"E2"}, False),
        (9, {"L1", "L2", "L3"}, set(), True),
    ],
)
def test_ridges_confirm_a_labelling_on_all_balls_but_two_whose_ellipses_read_plain(
    monkeypatch, balls, faint, unread, confirmed
):
    """Under 2 px of blur a face-on straight wire reads faint while both ellipses, the longest
    wires, stand clear of zero: the ridges confirm a labelling on all of ftrac_2005's balls but
    two whose every ellipse the image can be read at and reads plain, whatever its straight
    wires read (tuning seeds 2142 and 2144: five right labellings on seven balls refused so);
    with fewer balls only one curve may read faint, and never an ellipse, nor where an ellipse
    falls where the image cannot be read."""
    features = compute_features(load_design("ftrac_2005"))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = {p.id for p in features.points[:balls]}
    lab = _labelling(simulate_observation(features, Camera(), R[0], t[0], include=ids), R[0], t[0], False)
    readable = {"L1", "L2", "L3", "E1", "E2"} - unread
    monkeypatch.setattr(acceptance, "mirror_distinct", lambda *a, **k: True)
    monkeypatch.setattr(acceptance, "faint_ridges", lambda scene, pose, opts: (readable, set(faint)))
    scene = SimpleNamespace(features=features)
    assert acceptance.ridges_confirm(scene, lab, TrackOptions().acceptance) == confirmed
