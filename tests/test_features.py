"""features.json (SPEC §2) and the feature geometry helpers the CAD takes its paths from."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import MODELS, PRESETS

from ftrac_design.design import load_design
from ftrac_design.errors import InputError
from ftrac_design.features import compute_features, features_to_dict, load_features, write_features


@pytest.fixture(scope="module", params=PRESETS)
def preset_features(request):
    design = load_design(MODELS / f"{request.param}.toml")
    return design, compute_features(design)


def _is_vec(v, n=3):
    return isinstance(v, list) and len(v) == n and all(isinstance(x, float) for x in v)


def test_spec_structure(preset_features, tmp_path):
    design, f = preset_features
    path = write_features(tmp_path / "features.json", f)
    d = json.loads(path.read_text(encoding="utf-8"))
    assert d["format"] == "ftrac-features" and d["version"] == 1 and d["units"] == "mm"
    assert d["design"]["name"] == design.name
    assert d["design"]["sha256"] == design.sha256 and len(d["design"]["sha256"]) == 64
    assert d["design"]["source"].endswith(f"{design.name}.toml")
    assert _is_vec(d["nominal_beam_direction"])
    for key in ("points", "lines", "ellipses", "frames"):
        assert key in d
    for p in d["points"]:
        assert set(p) <= {"id", "center", "diameter", "line"} and {"id", "center", "diameter"} <= set(p)
        assert _is_vec(p["center"]) and p["diameter"] > 0
    for ln in d["lines"]:
        assert set(ln) == {"id", "start", "end", "wire_diameter"}
        assert _is_vec(ln["start"]) and _is_vec(ln["end"])
    for e in d["ellipses"]:
        assert set(e) == {"id", "center", "major_axis", "minor_axis", "semi_major", "semi_minor", "wire_diameter"}
        assert e["semi_major"] >= e["semi_minor"] > 0
    for name in ("mount_from_fiducial", "template_from_fiducial"):
        T = np.array(d["frames"][name])
        assert T.shape == (4, 4) and np.allclose(T[3], [0, 0, 0, 1])
    ids = [x["id"] for k in ("points", "lines", "ellipses") for x in d[k]]
    assert len(ids) == len(set(ids))
    line_ids = {ln["id"] for ln in d["lines"]}
    assert all(p.get("line") in line_ids for p in d["points"] if "line" in p)
    # counts match the design
    assert len(d["ellipses"]) == len(design.ellipses) and len(d["lines"]) == len(design.lines)
    assert len(d["points"]) == sum(len(ln.beads_z) for ln in design.lines) + len(design.beads)
    # and it reads back to the same geometry
    back = load_features(path)
    assert back.ids == f.ids
    assert np.allclose(back.point_centers(), f.point_centers(), atol=0, rtol=0)


def test_ellipse_axes_orthonormal(preset_features):
    _, f = preset_features
    for e in f.ellipses:
        assert abs(np.linalg.norm(e.major_axis) - 1) < 1e-12
        assert abs(np.linalg.norm(e.minor_axis) - 1) < 1e-12
        assert abs(e.major_axis @ e.minor_axis) < 1e-12
        # the seated ellipse lies on the cylinder of radius b about the body axis
        pts = e.sample(np.linspace(0, 2 * np.pi, 360))
        assert np.allclose(np.hypot(pts[:, 0], pts[:, 1]), e.semi_minor, atol=1e-9)


def test_beads_on_their_lines(preset_features):
    _, f = preset_features
    for p in f.points:
        if p.line is None:
            continue
        ln = f.line(p.line)
        d = ln.direction
        r = p.center - ln.start
        dist = np.linalg.norm(r - (r @ d) * d)
        assert dist < 1e-9
        assert -1e-9 <= ln.parameter(p.center) <= 1 + 1e-9


def test_seating_depths_match_design(preset_features):
    design, f = preset_features
    R = design.outer_radius
    for e in f.ellipses:
        assert math.isclose(R - e.semi_minor, design.seating.ellipse_wire_depth, abs_tol=1e-12)
    for ln in f.lines:
        assert math.isclose(R - math.hypot(*ln.start[:2]), design.seating.line_wire_depth, abs_tol=1e-12)
    for p in f.points:
        depth = R - math.hypot(*p.center[:2])
        want = design.seating.line_wire_depth if p.line else design.free_bead_depth
        assert math.isclose(depth, want, abs_tol=1e-12)


def test_line_crosses_under_ellipse(preset_features):
    """Where a line wire crosses an ellipse wire the line wire's top is below the ellipse wire."""
    design, f = preset_features
    for ln in f.lines:
        for e in f.ellipses:
            rl, re = math.hypot(*ln.start[:2]), e.semi_minor
            assert rl + ln.wire_diameter / 2 <= re - e.wire_diameter / 2 + 1e-12


def test_ellipse_tangent_is_derivative(features_2005):
    for e in features_2005.ellipses:
        s = np.linspace(0, 2 * np.pi, 50)
        h = 1e-6
        num = (e.sample(s + h) - e.sample(s - h)) / (2 * h)
        num /= np.linalg.norm(num, axis=1, keepdims=True)
        assert np.allclose(e.tangent(s), num, atol=1e-8)


def test_wire_segments_butt_against_beads(features_2005):
    f = features_2005
    for ln in f.lines:
        beads = f.beads_on(ln.id)
        zs = [b.center[2] for b in beads]
        assert zs == sorted(zs)
        segs = f.wire_segments(ln.id)
        r = beads[0].diameter / 2
        for a, b in segs:
            # every piece lies on the line, between balls, and touches no ball's interior
            assert ln.parameter(a) >= -1e-12 and ln.parameter(b) <= 1 + 1e-12
            for bead in beads:
                zb = bead.center[2]
                assert b[2] <= zb - r + 1e-9 or a[2] >= zb + r - 1e-9
        # pieces plus the balls' diameters inside the line account for the whole length
        inside = sum(min(ln.end[2], bd.center[2] + r) - max(ln.start[2], bd.center[2] - r) for bd in beads)
        assert math.isclose(f.wire_length(ln.id) + inside, ln.length, abs_tol=1e-9)
    assert math.isclose(f.wire_length("L1"), 26.0) and len(f.wire_segments("L1")) == 3


def test_wire_segments_without_beads(features_2005):
    f = features_2005.subset({"L3", "E1"})  # drops the beads: L3 runs bare end to end
    ((a, b),) = f.wire_segments("L3")
    assert np.allclose(a, f.line("L3").start) and np.allclose(b, f.line("L3").end)
    assert math.isclose(f.wire_length("E1"), f.ellipses[0].circumference)


def test_wire_pieces_are_every_lines_segments_computed_once(features_2005):
    import dataclasses

    f = features_2005
    want = [(ln.id, a, b) for ln in f.lines for a, b in f.wire_segments(ln.id)]
    got = f.wire_pieces
    assert [g[0] for g in got] == [w[0] for w in want]
    assert all(np.array_equal(g[1], w[1]) and np.array_equal(g[2], w[2]) for g, w in zip(got, want))
    assert f.wire_pieces is got  # cached on the instance
    # a line its beads cover whole (two 2 mm balls on a 4 mm line): its centre line
    ln = f.lines[0]
    short = dataclasses.replace(ln, end=ln.start + 4.0 * ln.direction)
    pts = tuple(
        dataclasses.replace(p, center=short.start + (1.0 + 2.0 * k) * ln.direction, line=ln.id)
        for k, p in enumerate(q for q in f.points if q.line == ln.id)
        if k < 2
    )
    g = dataclasses.replace(f, lines=(short,), points=pts, ellipses=())
    assert g.wire_segments(ln.id) == []
    ((fid, a, b),) = g.wire_pieces
    assert fid == ln.id and np.array_equal(a, short.start) and np.array_equal(b, short.end)


def test_features_dict_is_json(features_2005):
    json.dumps(features_to_dict(features_2005), allow_nan=False)


def test_the_body_is_part_of_the_features(preset_features, tmp_path):
    """The design's body travels with its features: computed from the design, and read back from
    features.json through the design file its source names, found beside the file or as a preset."""
    design, f = preset_features
    assert f.body == design.body
    assert load_features(write_features(tmp_path / "features.json", f)).body == design.body
    doc = features_to_dict(f)
    doc["design"]["source"] = f"/elsewhere/models/{design.name}.toml"  # another checkout: the preset
    (tmp_path / "moved.json").write_text(json.dumps(doc))
    assert load_features(tmp_path / "moved.json").body == design.body
    doc["design"]["source"] = None
    (tmp_path / "none.json").write_text(json.dumps(doc))
    assert load_features(tmp_path / "none.json").body is None


@pytest.mark.parametrize(
    "body, toml, key, expected",
    [
        ({"outer_diameter": 30.0, "length": -5.0, "bore_diameter": 20.0}, None, "body.length", "greater than 0"),
        ({"outer_diameter": 30.0, "length": 50.0}, None, "body.bore_diameter", "required"),
        (None, "[body]\nouter_diameter = 30.0\nlength = 50.0\nbore_diameter = 32.0\n", "design.source", "bore"),
        (None, "name = \n", "design.source", "TOML"),
        (None, 'name = "x"\n', "design.source", "[body]"),
    ],
)
def test_a_body_that_cannot_be_loaded_is_bad_input(features_2005, tmp_path, capsys, body, toml, key, expected):
    """features.json naming a body it cannot load, in its own body key or in the design file its
    source names: exit 2, one line naming the features file, the key and what was expected."""
    from ftrac_design.cli.main import main

    doc = features_to_dict(features_2005)
    if body is not None:
        doc["body"] = body
    else:
        (tmp_path / "design.toml").write_text(toml)
        doc["design"]["source"] = "design.toml"  # beside the features file
    path = tmp_path / "features.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as err:
        load_features(path)
    assert err.value.file == str(path) and err.value.key == key and expected in err.value.expected
    assert main(["radiograph", "--features", str(path), "--workspace-sample", "1", "-o", str(tmp_path / "rg")]) == 2
    out = capsys.readouterr().err
    assert out.count("\n") == 1 and str(path) in out and key in out and not (tmp_path / "rg").exists()
