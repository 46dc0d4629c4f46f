"""Segmentability: image-plane clearances between features on closed-form
cases (beads, crossing and parallel wires, concentric circles, collinear lines of the
published design), their invariance to a roll about the optical axis, the public
constraint function, and the analysis integration."""

from __future__ import annotations

import numpy as np
import pytest

from ftrac_design.analysis.segmentability import ClearanceSettings, image_clearance, pair_clearances, stretch_distance
from ftrac_design.features.model import EllipseFeature, Features, LineFeature, PointFeature
from ftrac_design.pose.camera import Camera
from ftrac_design.pose.simulate import rotations_from_beams

CAM = Camera()  # f = 1000 mm, 0.44 mm pixels: fx = fy = 2272.7 px
Z = 667.0
K = CAM.fx / Z  # px per mm in a plane facing the camera at depth Z


def _flat(points=(), lines=(), ellipses=()) -> Features:
    return Features("t", None, None, np.array([0.0, 0.0, 1.0]), tuple(points), tuple(lines), tuple(ellipses))


def _facing(B: int = 1):
    """Camera axes = F axes, F origin on the principal ray at depth Z: the plane z = 0 is
    imaged by a similarity with scale K."""
    return np.repeat(np.eye(3)[None], B, 0), np.tile([0.0, 0.0, Z], (B, 1))


def _line(fid, a, b, w=0.5):
    return LineFeature(fid, np.array(a, float), np.array(b, float), w)


def _get(pc, a, b):
    return pc.clearance_px[:, pc.pairs.index((a, b))]


def test_two_beads_clearance_is_centre_distance_minus_radii():
    f = _flat([PointFeature("A", np.array([-3.0, 0.0, 0.0]), 2.0), PointFeature("B", np.array([4.0, 0.0, 0.0]), 1.0)])
    R, t = _facing()
    pc = pair_clearances(f, CAM, R, t)
    assert pc.kinds == ["bead-bead"]
    np.testing.assert_allclose(_get(pc, "A", "B"), (7.0 - 1.0 - 0.5) * K, rtol=1e-12)
    # closer than their radii: merged
    f2 = _flat([PointFeature("A", np.zeros(3), 2.0), PointFeature("B", np.array([1.5, 0, 0]), 2.0)])
    c, flag = image_clearance(f2, CAM, R, t)
    np.testing.assert_allclose(c, -0.5 * K, rtol=1e-12)
    assert flag.tolist() == [True]


def test_bead_on_a_foreign_wire_counts_on_its_own_does_not():
    own = PointFeature("P", np.array([0.0, 0.0, 0.0]), 2.0, line="L1")
    other = PointFeature("Q", np.array([0.0, 5.0, 0.0]), 2.0, line="L2")
    f = _flat([own, other], [_line("L1", [-20, 0, 0], [20, 0, 0]), _line("L2", [-20, 5, 0], [20, 5, 0])])
    R, t = _facing()
    pc = pair_clearances(f, CAM, R, t)
    assert ("P", "L1") not in pc.pairs and ("Q", "L2") not in pc.pairs
    # Q is 5 mm from L1's centre-line: 5 K − bead radius − wire half-width
    np.testing.assert_allclose(_get(pc, "Q", "L1"), (5.0 - 1.0 - 0.25) * K, rtol=1e-12)
    # parallel wires 5 mm apart: their distance minus both half-widths
    np.testing.assert_allclose(_get(pc, "L1", "L2"), (5.0 - 0.5) * K, rtol=1e-9)


@pytest.mark.parametrize("theta_deg", [90.0, 30.0, 10.0, 4.0])
def test_crossing_wires_clear_by_half_the_stretch_times_sin_theta(theta_deg):
    """f = |s| sin θ along either wire from the crossing: the best window of S px is centred
    on it, so the clearance is S/2 · sin θ − both half-widths (flat crossings overlap)."""
    th = np.radians(theta_deg)
    half = 48 / 2 / K  # 48 px long in the image: 1 px vertex spacing at 48 samples
    d = np.array([np.cos(th), np.sin(th), 0.0])
    f = _flat(lines=[_line("A", [-half, 0, 0], [half, 0, 0]), _line("B", -half * d, half * d)])
    R, t = _facing()
    cs = ClearanceSettings(stretch_px=10.0, line_samples=48)
    pc = pair_clearances(f, CAM, R, t, cs)
    widths = 0.5 * K
    expected = 5.0 * np.sin(th) - widths
    # windows start/end at vertices 1 px apart: exact here (the crossing is a vertex, 5 px
    # is a whole number of spacings)
    np.testing.assert_allclose(_get(pc, "A", "B"), expected, atol=1e-9)
    assert bool(pc.overlap()[0, 0]) == (expected < 0)


def test_stretch_window_error_is_at_most_half_a_spacing_times_the_slope():
    rng = np.random.default_rng(1)
    for _ in range(20):
        h = rng.uniform(0.5, 3.0)
        x = np.arange(0.0, 100.0, h)
        c = rng.uniform(30, 70)
        slope = rng.uniform(0.05, 1.0)
        P = np.stack([x, np.zeros_like(x)], -1)[None]
        f = (slope * np.abs(x - c))[None]
        got = stretch_distance(f, P, 10.0)[0]
        assert 5.0 * slope - 1e-9 <= got <= 5.0 * slope + h / 2 * slope + 1e-9


def test_concentric_circles_and_a_bead_at_their_centre():
    """Face-on circles of radii 10 and 14 mm around a bead: every clearance in closed form,
    within the polygon's sag (reported)."""
    ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    f = _flat(
        [PointFeature("P", np.zeros(3), 2.0)],
        [],
        [
            EllipseFeature("E1", np.zeros(3), ex, ey, 10.0, 10.0, 0.5),
            EllipseFeature("E2", np.zeros(3), ex, ey, 14.0, 14.0, 0.5),
        ],
    )
    R, t = _facing()
    pc = pair_clearances(f, CAM, R, t)
    sag = pc.sampling_error_px
    assert 0 < sag < 0.1 and np.isclose(sag, 14 * K * (1 - np.cos(np.pi / ClearanceSettings().ellipse_samples)))
    np.testing.assert_allclose(_get(pc, "P", "E1"), (10 - 1 - 0.25) * K, atol=sag)
    np.testing.assert_allclose(_get(pc, "E1", "E2"), (4 - 0.5) * K, atol=sag)
    assert set(pc.kinds) == {"bead-ellipse", "ellipse-ellipse"}
    # a bead on an ellipse's wire is reported but not counted by default
    assert "bead-ellipse" not in ClearanceSettings().counted
    assert pc.minimum()[0] == _get(pc, "E1", "E2")[0]
    counted_all = pair_clearances(f, CAM, R, t, ClearanceSettings(counted=("bead-ellipse",)))
    assert counted_all.minimum()[0] == _get(pc, "P", "E1")[0]


def test_published_lines_l2_l3_collinear_when_the_source_is_in_their_plane(features_2005):
    """Beam along L3 − L2 (both wires along z) with the source in their plane: both project
    onto one image line — overlap by both widths."""
    f = features_2005
    L2, L3 = f.line("L2"), f.line("L3")
    b = (L3.start - L2.start) * np.array([1.0, 1.0, 0.0])
    b /= np.linalg.norm(b)
    C = (L2.start + L2.end) / 2 - 640.0 * b  # the source, in F
    R = rotations_from_beams(b[None], np.array([0.3]))
    t = -(R[0] @ C)[None]
    pc = pair_clearances(f, CAM, R, t)
    i = pc.pairs.index(("L2", "L3"))
    z2 = (R[0] @ (L2.start + L2.end) / 2 + t[0])[2]
    z3 = (R[0] @ (L3.start + L3.end) / 2 + t[0])[2]
    widths = 0.25 * CAM.fx * (1 / z2 + 1 / z3)
    np.testing.assert_allclose(pc.clearance_px[0, i], -widths, atol=1e-6)
    c, flag = image_clearance(f, CAM, R, t)
    assert flag[0] and c[0] <= -widths + 1e-6
    # the source 30 mm out of their plane (same beam): the lines separate
    C2 = C + 30.0 * np.cross(b, [0.0, 0.0, 1.0])
    pc2 = pair_clearances(f, CAM, R, -(R[0] @ C2)[None])
    assert pc2.clearance_px[0, i] > 0


def test_every_clearance_is_invariant_to_a_roll_about_the_optical_axis(features_2005):
    """Rolling the camera about its own axis rotates the image about the principal point:
    no distance changes, at any pose (on or off the principal ray)."""
    from ftrac_design.analysis.sampling import workspace_poses
    from ftrac_design.pose.simulate import Workspace

    R, t = workspace_poses(Workspace(), features_2005.nominal_beam_direction, 6, seed=4)
    base = pair_clearances(features_2005, CAM, R, t).clearance_px
    for phi in (0.4, 2.0, 4.5):
        c, s = np.cos(phi), np.sin(phi)
        Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        rolled = pair_clearances(features_2005, CAM, Rz @ R, t @ Rz.T).clearance_px
        np.testing.assert_allclose(rolled, base, atol=1e-8)


def test_batch_equals_one_pose_at_a_time(features_2005):
    from ftrac_design.analysis.sampling import workspace_poses
    from ftrac_design.pose.simulate import Workspace

    R, t = workspace_poses(Workspace(), features_2005.nominal_beam_direction, 5, seed=2)
    whole = pair_clearances(features_2005, CAM, R, t, chunk=2).clearance_px
    for k in range(5):
        np.testing.assert_allclose(
            pair_clearances(features_2005, CAM, R[k : k + 1], t[k : k + 1]).clearance_px[0], whole[k], atol=1e-12
        )


def test_nominal_view_of_the_published_design_is_clear(features_2005):
    """In the AP view at the isocentre nothing overlaps: the design file's bead heights were
    chosen to keep beads off the other wires there."""
    from ftrac_design.analysis.sampling import isocentre_poses

    R, t = isocentre_poses(np.array([features_2005.nominal_beam_direction]), Z)
    pc = pair_clearances(features_2005, CAM, R, t)
    assert pc.clearance_px.min() > 0
    c, flag = image_clearance(features_2005, CAM, R, t)
    assert not flag[0] and c[0] == pc.minimum()[0]


# ---- the analysis: analysis.json, thresholds, compare --------------------------------------

FAST = ["--poses", "300", "--atlas-step-deg", "15", "--no-plots", "--score-images", "0", "--image-atlas-step-deg", "0"]


@pytest.fixture(scope="module")
def features_json(tmp_path_factory, features_2005):
    from ftrac_design.features.io import write_features

    path = tmp_path_factory.mktemp("seg") / "features.json"
    write_features(path, features_2005)
    return path


def test_analyze_reports_segmentability_and_its_threshold_fails_the_design(tmp_path, capsys, features_json):
    import json

    from ftrac_design.cli.main import main

    out = tmp_path / "an"
    assert main(["analyze", str(features_json), "-o", str(out), *FAST, "--max-overlap-share", "0.01"]) == 1
    doc = json.loads((out / "analysis.json").read_text())
    sg = doc["segmentability"]
    assert set(sg) >= {
        "settings",
        "sampling_error_px",
        "clearance_px",
        "overlap_share",
        "kinds",
        "pairs_overlap_share",
        "worst_poses",
        "atlas",
    }
    assert sg["settings"]["poses"] == 300 and set(sg["clearance_px"]) == {"min", "p5", "median"}
    assert sg["kinds"]["bead-ellipse"]["counted"] is False and sg["kinds"]["line-line"]["counted"] is True
    # the overlap share is the mean of the per-pose verdicts and at least every kind's share
    assert 0.01 < sg["overlap_share"] <= 1 and all(
        sg["overlap_share"] >= v["overlap_share"] for v in sg["kinds"].values() if v["counted"]
    )
    w = sg["worst_poses"][0]
    assert w["clearance_px"] == sg["clearance_px"]["min"] and "-" in w["pair"]
    assert {"overlap_share_of_sphere", "overlap_share_of_cone"} <= set(sg["atlas"])
    assert doc["thresholds"]["max_overlap_share"] == 0.01 and doc["thresholds"]["min_clearance_px"] is None
    check = [c for c in doc["checks"] if c["figure"] == "overlap share"]
    assert check and check[0]["passed"] is False and doc["passed"] is False
    # the existing figures are untouched
    assert {"figures", "groups", "features", "worst_poses", "atlas"} <= set(doc)
    captured = capsys.readouterr()
    assert "segmentability" in captured.out
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "overlap share" in err[0]


def test_min_clearance_threshold_and_the_design_file_table(tmp_path, capsys):
    import json

    from conftest import MODELS

    from ftrac_design.cli.main import main

    design = tmp_path / "mini.toml"
    design.write_text((MODELS / "ftrac_mini.toml").read_text() + "max_overlap_share = 0.9\nmin_clearance_px = -10.0\n")
    out = tmp_path / "a"
    assert main(["analyze", str(design), "-o", str(out), *FAST]) == 0
    doc = json.loads((out / "analysis.json").read_text())
    assert {c["figure"] for c in doc["checks"]} >= {"overlap share", "clearance p5"} and doc["passed"]
    # the command line wins over the design file
    assert main(["analyze", str(design), "-o", str(out), *FAST, "--min-clearance-px", "50"]) == 1
    err = capsys.readouterr().err
    assert "clearance p5" in err and "< 50" in err
    design.write_text((MODELS / "ftrac_mini.toml").read_text() + "max_overlap_share = 1.5\n")
    assert main(["analyze", str(design), "-o", str(tmp_path / "b"), *FAST]) == 2


def test_compare_shows_segmentability(tmp_path, capsys):
    import json

    from conftest import MODELS

    from ftrac_design.cli.main import main

    out = tmp_path / "c.png"
    assert (
        main(
            [
                "compare",
                str(MODELS / "ftrac_2005.toml"),
                str(MODELS / "nine_bead.toml"),
                "--poses",
                "200",
                "--score-images",
                "0",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "overlap" in text and "clear p5" in text
    doc = json.loads(out.with_suffix(".json").read_text())
    assert all(d["segmentability"]["overlap_share"] is not None for d in doc["designs"])
