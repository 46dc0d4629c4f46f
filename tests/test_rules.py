"""Design rules and the ``check`` command: every rule fires on a design made to break it
(one parameter of a preset changed), presets give the documented verdicts, bad input is
one line with exit 2."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from ftrac_design.cli.main import main
from ftrac_design.design import load_design, parse_design
from ftrac_design.design.presets import PRESETS_DIR
from ftrac_design.errors import InputError
from ftrac_design.manufacture.profiles import PROFILES, cut_sizes, rule_limits
from ftrac_design.manufacture.rules import RULES, check_design

MODELS = PRESETS_DIR


def with_param(preset: str, path: str, value):
    """``preset`` with the one key ``path`` (dotted, with ``[i]`` indices) set to ``value``."""
    data = tomllib.loads((MODELS / f"{preset}.toml").read_text())
    keys = re.findall(r"[^.\[\]]+|\[\d+\]", path)
    obj = data
    for k in keys[:-1]:
        obj = obj[int(k[1:-1])] if k.startswith("[") else obj.setdefault(k, {})
    last = keys[-1]
    if last.startswith("["):
        obj[int(last[1:-1])] = value
    else:
        obj[last] = value
    return parse_design(data, f"{preset}.toml")


def write_variant(tmp_path: Path, preset: str, extra: str) -> Path:
    p = tmp_path / f"{preset}_variant.toml"
    p.write_text((MODELS / f"{preset}.toml").read_text() + "\n" + extra + "\n")
    return p


# (rule, preset, key, value, profile): one parameter changed breaks exactly that rule
VIOLATIONS = [
    ("body.bore_wall", "ftrac_2005", "body.bore_diameter", 25.0, "cnc"),
    ("groove.tool", "ftrac_2005", "manufacturing.cnc.tool_diameter", 0.5, "cnc"),
    ("groove.tool", "ftrac_2005", "manufacturing.fdm.nozzle_diameter", 1.0, "fdm"),
    ("groove.depth", "ftrac_2005", "manufacturing.cnc.tool_diameter", 0.3, "cnc"),
    ("wires.crossing_clearance", "ftrac_2005", "seating.line_wire_depth", 0.8, "cnc"),
    ("pockets.spacing", "ftrac_2005", "lines[0].beads_z[2]", 13.5, "cnc"),
    ("grooves.spacing", "ftrac_2005", "ellipses[0].z_center", -5.5, "cnc"),
    ("pockets.retention", "nine_bead", "seating.free_bead_depth", 0.02, "cnc"),
    ("body.envelope", "nine_bead", "beads[8].z", 23.5, "cnc"),
    ("mount.coverage", "ftrac_2005", "mount.socket_depth", 4.5, "cnc"),
    ("mount.hole_edge", "ftrac_2005", "mount.width", 60.0, "cnc"),
    ("mount.hole_clearance", "ftrac_2005", "mount.holes_z.pitch", 25.0, "cnc"),
    ("connector.hole_edge", "ftrac_2005", "connector.edge_margin", 1.5, "cnc"),
    ("connector.walls", "ftrac_2005", "connector.pocket_wall", 0.5, "cnc"),
    ("connector.template_clearance", "ftrac_2005", "connector.axis_height", 40.0, "cnc"),
]


def test_every_rule_has_a_violation_case():
    names = {r.__name__ for r in RULES}
    assert len(names) == len(RULES) >= 14
    fired = {v[0] for v in VIOLATIONS}
    d = load_design(MODELS / "ftrac_2005.toml")
    assert {r.rule for r in check_design(d).results} == fired


@pytest.mark.parametrize("rule,preset,key,value,profile", VIOLATIONS, ids=[f"{v[0]}-{v[4]}" for v in VIOLATIONS])
def test_rule_fires(rule, preset, key, value, profile):
    base = check_design(load_design(MODELS / f"{preset}.toml"), profile)
    assert base.result(rule).verdict != "fail"
    report = check_design(with_param(preset, key, value), profile)
    r = report.result(rule)
    assert r.verdict == "fail"
    assert [v.rule for v in report.violations] == [rule]  # that rule only
    msg = r.message
    assert msg.startswith(rule + ":")
    assert f"{r.measured:.3f}" in msg
    assert f"{r.comparison} {r.limit:g}" in msg
    assert "\n" not in msg


def test_measured_values_match_hand_calculations():
    d = load_design(MODELS / "ftrac_2005.toml")
    r = check_design(d, "cnc")
    # wall under the bead pockets: R - (line depth + ball radius) - bore radius
    assert r.result("body.bore_wall").measured == pytest.approx(15 - (1.1 + 1.0) - 10)
    # crossing: (1.1 - 0.25) - (0.3 + 0.25)
    assert r.result("wires.crossing_clearance").measured == pytest.approx(0.3)
    # retention: pocket floor 2.1 mm below the surface, minus the rim's drop R - sqrt(R^2 - rho^2)
    rho = 1.98 / 2
    assert r.result("pockets.retention").measured == pytest.approx(2.1 - (15 - (15**2 - rho**2) ** 0.5))
    # coverage: E1's lowest point z_c - r tan(tau) - w/2, socket rim at -25 + 3
    low = -12.5 - 14.7 * 3**-0.5 - 0.25
    assert r.result("mount.coverage").measured == pytest.approx(low + 22)
    # groove depth / tool: (1.1 + 0.25) / 0.4
    assert r.result("groove.depth").measured == pytest.approx(1.35 / 0.4)


@pytest.mark.parametrize("profile", PROFILES)
def test_profile_changes_cut_sizes_exactly_as_stated(profile):
    d = load_design(MODELS / "ftrac_2005.toml")
    c = cut_sizes(d, profile)
    if profile == "cnc":
        p = d.manufacturing.cnc
        assert c.groove_width == pytest.approx(0.5 - p.wire_interference)
        assert c.pocket_diameter == pytest.approx(2.0 - p.bead_interference)
        assert c.socket_diameter == pytest.approx(30.0 - p.socket_interference)
        assert c.pin_hole_diameter == pytest.approx(1.2 - p.pin_interference)
        assert c.hole(4.5) == 4.5
    else:
        p = d.manufacturing.fdm
        assert c.groove_width == pytest.approx(0.5 + 2 * p.wire_clearance)
        assert c.pocket_diameter == pytest.approx(2.0 + 2 * p.bead_clearance)
        assert c.socket_diameter == pytest.approx(30.0 + p.press_allowance)
        assert c.pin_hole_diameter == pytest.approx(1.2 + p.press_allowance)
        assert c.hole(4.5) == pytest.approx(4.5 + p.hole_allowance)
    lim = rule_limits(d, profile)
    assert (lim.min_wall, lim.recommended_wall) == ((1.0, 1.5) if profile == "cnc" else (0.8, 1.2))


# what check says about the presets (quoted in docs/reference/design-rules.md)
PRESET_VERDICTS = {
    ("ftrac_2005", "cnc"): (set(), {"groove.depth"}),
    ("ftrac_2005", "fdm"): (set(), set()),
    ("ftrac_mini", "cnc"): (set(), {"body.bore_wall", "groove.depth", "pockets.spacing"}),
    ("ftrac_mini", "fdm"): (set(), {"wires.crossing_clearance", "pockets.spacing"}),
    ("nine_bead", "cnc"): (set(), set()),
    ("nine_bead", "fdm"): (set(), set()),
}


@pytest.mark.parametrize("preset,profile", sorted(PRESET_VERDICTS))
def test_preset_verdicts(preset, profile):
    r = check_design(load_design(MODELS / f"{preset}.toml"), profile)
    fails, warns = PRESET_VERDICTS[(preset, profile)]
    assert {x.rule for x in r.violations} == fails
    assert {x.rule for x in r.warnings} == warns


@pytest.mark.parametrize("preset,profile", sorted(PRESET_VERDICTS))
def test_check_cli_exit_codes(preset, profile, capsys):
    rc = main(["check", str(MODELS / f"{preset}.toml"), "--profile", profile])
    out, err = capsys.readouterr()
    fails, _ = PRESET_VERDICTS[(preset, profile)]
    assert rc == (1 if fails else 0)
    assert out.splitlines()[0].startswith(f"check {preset} ({profile}):")
    for rule in {r.rule for r in check_design(load_design(MODELS / f"{preset}.toml"), profile).results}:
        assert rule in out
    if fails:
        assert err.startswith("failed: ") and len(err.strip().splitlines()) == 1
        assert all(f in err for f in fails)
    else:
        assert err == ""


def test_check_json(tmp_path, capsys):
    # ftrac_mini with the end balls of L2 back at the paper's +-6.4 mm: 0.9 mm from the ellipse wires
    bad = tmp_path / "mini_long_l2.toml"
    bad.write_text(
        (MODELS / "ftrac_mini.toml")
        .read_text()
        .replace(
            "z_start = -5.0\nz_end = 5.0\nbeads_z = [-5.0, -0.8, 5.0]",
            "z_start = -6.4\nz_end = 6.4\nbeads_z = [-6.4, -0.8, 6.4]",
        )
    )
    rc = main(["check", str(bad), "--profile", "fdm", "--json"])
    out, _ = capsys.readouterr()
    assert rc == 1
    doc = json.loads(out)
    assert doc["format"] == "ftrac-check" and doc["profile"] == "fdm" and doc["ok"] is False
    rows = {r["rule"]: r for r in doc["rules"]}
    assert rows["pockets.spacing"]["verdict"] == "fail"
    for r in doc["rules"]:
        assert set(r) >= {"rule", "measured", "limit", "unit", "verdict", "message", "comparison"}


def test_check_default_profile_is_cnc(capsys):
    assert main(["check", str(MODELS / "ftrac_2005.toml")]) == 0
    assert "(cnc)" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra,key,expected",
    [
        ("[mount]\nsocket_depth = 3.0\nbogus = 1", "mount.bogus", "no such key"),
        ('[mount.holes_z]\npattern = "triangle"', "mount.holes_z.pattern", "pair"),
        ("[mount.holes_x]\ncounterbore_diameter = 4.0", "mount.holes_x.counterbore_diameter", "wider than the hole"),
        ("[connector]\npins = [[0, 0], [0, 0]]", "connector.pins", "two different grid nodes"),
        ("[connector]\npins = [[0, 0]]", "connector.pins", "at least 2"),
        ("[connector]\npins = [[0, 0], [1.5, 0]]", "connector.pins[1][0]", "an integer"),
        ("[connector]\npins = [[0, 0], [4, 3]]", "connector.pins[1]", "on the template"),
        ('[connector]\nsource_side = "left"', "connector.source_side", "posterior"),
        ("[connector]\npocket_depth = 20.0", "connector.pocket_depth", "less than thickness"),
        ("[mount]\nsocket_depth = 3.0\nkey_height = 2.9", "mount.key_height", "inside the socket"),
        (
            "[mount]\nsocket_depth = 3.0\nkey_height = 1.0\nkey_width = 30.0",
            "mount.key_width",
            "narrower than the cylinder",
        ),
        ("[mount]\nsocket_depth = 3.0\nwidth = 25.0", "mount.width", "wider than the socket"),
    ],
)
def test_bad_mount_and_connector_keys(tmp_path, capsys, extra, key, expected):
    src = (MODELS / "ftrac_2005.toml").read_text()
    path = tmp_path / "bad.toml"
    path.write_text(src + "\n" + extra + "\n")
    with pytest.raises(InputError) as ei:
        load_design(path)
    assert ei.value.key == key and expected in ei.value.expected
    rc = main(["check", str(path)])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and str(path) in err and key in err and "Traceback" not in err


def test_check_bad_profile_is_usage_error(capsys):
    assert main(["check", str(MODELS / "ftrac_2005.toml"), "--profile", "sla"]) == 2


def test_rules_do_not_import_cadquery():
    code = (
        "import sys, ftrac_design.manufacture.rules as r, ftrac_design.cli.check;"
        "from ftrac_design.design import load_design;"
        f"r.check_design(load_design({str(MODELS / 'ftrac_2005.toml')!r}));"
        "assert 'cadquery' not in sys.modules and 'OCP' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
