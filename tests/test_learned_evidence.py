"""The learned detector's evidence for a labelling whose wire contours could not be measured:
its wires must run the way the pose predicts them, and such a labelling must explain all but
one of a wire design's balls."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.detector.decode import decode
from ftrac_design.detector.normalise import STRIDE, working_scale
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace, simulate_observation
from ftrac_design.segment import TrackOptions, acceptance, evidence, identify
from ftrac_design.segment.detection import detect
from ftrac_design.training.targets import target_maps
from ftrac_design.xray import render


@pytest.fixture(scope="module")
def f2005():
    return compute_features(load_design("ftrac_2005"))


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(p, 1e-6, 1 - 1e-6)
    return np.log(p / (1 - p))


def test_wire_alignment_is_cos_2_dtheta():
    """A cell map of wires at 30°: a tangent along them reads 1, across them −1, at 45° 0,
    whichever sense the tangent has."""
    H = W = 64
    cells = (H // STRIDE, W // STRIDE)
    t = np.linspace(0, 1, 400)[:, None]
    d = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    line = np.array([8.0, 16.0]) + t * 50 * d
    y, _ = target_maps(np.zeros((0, 2)), [line], np.ones((H, W), bool), 1, cells)
    maps = np.zeros((6,) + cells, np.float32)
    maps[0] = -20.0
    maps[3] = _logit(y[3])
    maps[4:6] = y[4:6]
    det = decode(maps, 1, (H, W))
    uv = line[150:250:10]
    across = np.array([-d[1], d[0]])
    at45 = np.array([np.cos(np.pi / 6 + np.pi / 4), np.sin(np.pi / 6 + np.pi / 4)])
    for tangent, want in ((d, 1.0), (-d, 1.0), (across, -1.0), (at45, 0.0)):
        got = det.wire_alignment(uv, np.repeat(tangent[None], len(uv), 0))
        np.testing.assert_allclose(got, want, atol=1e-6)


def test_the_network_confirms_wires_only_where_they_run_the_predicted_way(f2005):
    """Maps that show every wire of a clean view where it is, as the network's targets do:
    they confirm the true pose. The same maps with each wire's direction turned 90° (the
    probability unchanged, as where a wrong pose's ellipse crosses real wires) confirm
    nothing."""
    features = f2005
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(5))
    R, t = R[0], t[0]
    rad = render(features, R, t, Camera(), rng=np.random.default_rng(5))
    g = -np.log(np.maximum(rad.raw, 1.0) / float(rad.raw.max()))
    H, W = g.shape
    opts = TrackOptions().finding
    s = working_scale(3.41)
    cells = (H // s // STRIDE, W // s // STRIDE)
    uv = identify.project(Camera(), R, t, features.point_centers())[0]
    curves = [p for _, p in identify.curve_samples(features, Camera(), R, t).values()]
    y, _ = target_maps(uv, curves, np.ones((H, W), bool), s, cells)
    maps = np.zeros((6,) + cells, np.float32)
    maps[0], maps[1:3], maps[3], maps[4:6] = _logit(y[0]), y[1:3], _logit(y[3]), y[4:6]
    seen = decode(maps, s, (H, W))
    scene = detect(g, features, Camera(), opts, None, None, seen)
    assert evidence.learned_confirms_wires(scene, R, t)
    maps[4:6] = -y[4:6]
    turned = detect(g, features, Camera(), opts, None, None, decode(maps, s, (H, W)))
    assert not evidence.learned_confirms_wires(turned, R, t)
    # the probability alone still shows every wire
    sup = evidence.learned_wire_support(turned, R, t, turned.bead_exclusion())
    assert len(sup) >= 2 and min(sup.values()) >= 0.3


@pytest.mark.parametrize(
    ("preset", "balls", "refused"), [("ftrac_2005", 8, False), ("ftrac_2005", 7, True), ("nine_bead", 7, False)]
)
def test_a_labelling_confirmed_by_the_network_alone_needs_all_but_one_ball(preset, balls, refused, monkeypatch):
    """No wire contour measured, every wire confirmed by the network: 8 of ftrac_2005's 9
    balls are enough, 7 are not (a near-mirror labelling can fit 7 of 9). A design with no
    wires keeps its own rule: all but two balls (7 of nine_bead's 9)."""
    features = compute_features(load_design(preset))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(2))
    ids = [p.id for p in features.points][:balls]
    obs = simulate_observation(features, Camera(), R[0], t[0], include=set(ids))
    assert len(obs.points) == balls and not obs.lines and not obs.ellipses
    monkeypatch.setattr(evidence, "learned_confirms_wires", lambda *a, **k: True)
    lab = SimpleNamespace(
        obs=obs, contours=identify.Contours(), pose=SimpleNamespace(rotation=R[0], translation_mm=t[0])
    )
    why = acceptance.too_little_evidence(SimpleNamespace(features=features), lab, TrackOptions().acceptance)
    if refused:
        assert why is not None and f"{balls} beads and no wires cannot verify" in why and "need ≥ 8" in why
    else:
        assert why is None
