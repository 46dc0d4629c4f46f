"""4-axis machining: the material-removal simulator against closed-form swept volumes, the
reference cuts' exact ray intervals, the posts read back move for move, a wrong program
caught as a gouge, the cycle time of hand-timed moves, and ``ftrac-design gcode`` end to end
(no CadQuery is imported by any of it)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.special import ellipe, ellipk

from ftrac_design.cli.main import main
from ftrac_design.design import load_design
from ftrac_design.errors import InputError
from ftrac_design.machining.gcode import cycle_time, parse_gcode
from ftrac_design.machining.model import (
    CutPlan,
    EllipseCut,
    Machine,
    PocketCut,
    SlotCut,
    Stock,
    Tooling,
    make_tool,
    pocket_tool_diameter,
    tooling,
)
from ftrac_design.machining.post import POSTS, emit
from ftrac_design.machining.simulate import Grid, placement_step, reference_layer, scallop, union_volume, verify
from ftrac_design.machining.toolpath import plan_program
from ftrac_design.manufacture.gcode import body_program

R = 5.0
STOCK = Stock(R, 0.0, 2.0)


def _tools(groove: float, pocket: float | None = None) -> Tooling:
    g = make_tool(1, groove, 91.0, 24000.0, 2, 0.0072)
    p = g if pocket is None else make_tool(2, pocket, 91.0, 24000.0, 2, 0.0072)
    return Tooling(g, p, 0.5 * groove, math.radians(3.0))


def _run(plan: CutPlan, tools: Tooling, post: str = "linuxcnc", grid: float = 0.01):
    text = emit(plan_program(plan, tools), post)
    diameters = {tools.groove.number: tools.groove.diameter, tools.pocket.number: tools.pocket.diameter}
    return text, verify(parse_gcode(text), plan, tools=diameters, grid_mm=grid)


def test_straight_slot_removes_its_closed_form_volume():
    # a slot through the whole stock (its round ends fall outside), floor plane 0.4 below R,
    # cut in two side passes: V = 2h ∫_{-w/2}^{w/2} (√(R² − t²) − f) dt
    w, f = 0.5, 4.6
    slot = SlotCut("S", math.radians(30.0), f, R + 0.2, w, -3.0, 3.0)
    plan = CutPlan("slot", STOCK, slots=(slot,))
    _, v = _run(plan, _tools(0.4))
    t = w / 2
    area = t * math.sqrt(R * R - t * t) + R * R * math.asin(t / R) - w * f
    exact = 2 * STOCK.half_length * area
    assert v.reference_mm3 == pytest.approx(exact, rel=2e-3)
    assert v.removed_mm3 == pytest.approx(exact, rel=2e-3)
    assert v.max_deviation_mm < 2e-3 and v.gouges == 0 and v.ok


def test_round_pocket_removes_its_closed_form_volume():
    # a flat-bottomed radial hole of radius a, floor f from the axis, in a solid cylinder R:
    # V = ∫∫_disk (√(R² − t²) − f) = (4R/3)[(R² + a²)E(k) − (R² − a²)K(k)] − π a² f, k = a/R
    a, f = 0.5, 4.4
    pocket = PocketCut("P", math.radians(200.0), 0.3, f, 2 * a, R + 0.2 - f)
    plan = CutPlan("pocket", STOCK, pockets=(pocket,))
    _, v = _run(plan, _tools(0.4, 0.6))
    m = (a / R) ** 2
    exact = 4 * R / 3 * ((R * R + a * a) * ellipe(m) - (R * R - a * a) * ellipk(m)) - math.pi * a * a * f
    assert v.reference_mm3 == pytest.approx(exact, rel=2e-3)
    assert v.removed_mm3 == pytest.approx(exact, rel=2e-3)
    assert v.max_deviation_mm < 2e-3 and v.ok


def test_union_volume_counts_overlaps_once():
    g = Grid.for_stock(STOCK, 0.02)
    slot = SlotCut("S", 0.0, 4.6, R, 0.5, -1.0, 1.0)
    one = reference_layer(g, slot)
    assert union_volume(g, [one, one]) == pytest.approx(union_volume(g, [one]), rel=1e-12)
    assert union_volume(g, []) == 0.0


def test_ellipse_ray_interval_is_exact():
    # the secant roots agree with a bisection of the exact inside test to 1e-9 mm
    e = EllipseCut.from_plane("E", 4.82, [0.0, -math.sin(0.5), math.cos(0.5)], 0.4, 0.28, 0.15, 0.5)
    rng = np.random.default_rng(1)
    th = rng.uniform(0, 2 * math.pi, 300)
    z = e.z(th) + rng.uniform(-0.2, 0.2, 300)
    lo, hi = e.ray_interval(th, z, R)
    hit = np.isfinite(lo)
    assert 50 < hit.sum() < 300
    eps = 1e-9
    assert np.all(e.sdf(lo[hit] + eps, th[hit], z[hit]) <= 0) and np.all(e.sdf(hi[hit] - eps, th[hit], z[hit]) <= 0)
    outside_lo = (lo[hit] - eps < e.seat_radius - e.floor_depth) | (e.sdf(lo[hit] - 1e-7, th[hit], z[hit]) > 0)
    assert np.all(outside_lo)
    at_top = hi[hit] >= R - 1e-12
    assert np.all(at_top | (e.sdf(hi[hit] + 1e-7, th[hit], z[hit]) > 0))
    # rays that miss are outside everywhere between the floor and the top
    rs = np.linspace(e.seat_radius - e.floor_depth, R, 400)
    for k in np.flatnonzero(~hit)[:20]:
        assert np.all(e.sdf(rs, th[k], z[k]) > 0)


def test_scallop_step_is_consistent():
    for d in (0.25, 0.4, 1.5):
        assert scallop(placement_step(d, 1e-3), d) == pytest.approx(1e-3, rel=1e-9)


def _mini():
    d = load_design("ftrac_mini")
    return d, body_program(d, "cnc", check=False)


@pytest.mark.parametrize("post", sorted(POSTS))
def test_post_reads_back_move_for_move(post):
    d, bp = _mini()
    prog = plan_program(bp.plan, tooling(d.manufacturing.cnc, 0.98))
    text = emit(prog, post)
    parsed = [m for m in parse_gcode(text).moves if np.all(np.isfinite(m.end))]
    planned = prog.moves
    assert len(parsed) == len(planned)
    for p, q in zip(planned, parsed):
        assert p.kind == q.kind and p.feed_mode == q.feed_mode
        assert np.allclose(p.end, q.end, atol=5e-5)
        if p.kind != "rapid":
            assert q.f == pytest.approx(p.f, rel=1e-3, abs=0.05)
        if p.kind == "arc":
            assert np.allclose(p.centre, q.centre, atol=1e-4) and p.ccw == q.ccw
    tc = parse_gcode(text).tool_changes
    assert tc == [1, 2]  # one change per tool
    assert not parse_gcode(text).faults  # the A brake is off whenever A turns
    if post == "fanuc":
        assert text.splitlines()[1].startswith("O1000") and "M10" in text and "M11" in text
        assert text.rstrip().splitlines()[-2].endswith("M30")


def test_cycle_time_of_hand_timed_moves():
    text = "\n".join(
        [
            "G21 G90 G94",
            "T1 M6",
            "S1000 M3",
            "G0 X0 Y0 Z10 A0",
            "G0 X50",  # 50 mm rapid
            "G1 X60 F100",  # 10 mm at 100 mm/min: 6 s
            "G93 G1 A90 F2",  # inverse time: 1/2 min = 30 s
            "G94 G3 X60 Y0 I-5 J0 F31.41592653589793",  # a full circle of r 5 at π·10 mm/min: 60 s
            "M5",
            "M2",
        ]
    )
    t = cycle_time(parse_gcode(text), Machine(rapid_linear=3000.0, rapid_a=3600.0, tool_change_s=7.0))
    assert t["feed_s"] == pytest.approx(96.0)
    assert t["rapid_s"] == pytest.approx(60 * (50 / 3000))  # the first rapid starts nowhere known: untimed
    assert t["tool_change_s"] == 7.0


@pytest.mark.parametrize(
    "bad",
    [
        "G1 X1 Q3",
        "G18 G1 X1 F10",
        "G1 X1",
        "G1 X0 Y0 F10\nG2 X1 Y0 F10",
        "G93 T1 M6 S10 M3 G1 X1 F1\nG1 X2",
        "(unclosed G0 X1",
    ],
)
def test_reader_refuses_what_it_does_not_know(bad):
    with pytest.raises(InputError) as exc:
        parse_gcode("G21 G90\n" + bad, "p.ngc")
    assert str(exc.value).startswith("p.ngc: line ")


def test_reader_reports_cutting_with_the_spindle_stopped_and_a_with_the_brake_on():
    text = "G21 G90\nT1 M6\nG0 X0 Y0 Z10 A0\nG1 X1 F10\nS100 M3\nM10\nG1 A5 F10\n"
    faults = parse_gcode(text).faults
    assert any("spindle stopped" in f for f in faults) and any("brake" in f for f in faults)


def _small_plan() -> CutPlan:
    e = EllipseCut.from_plane("E1", 4.82, [0.0, -math.sin(0.5), math.cos(0.5)], 0.0, 0.28, 0.15, 0.5)
    s = SlotCut("L1", math.radians(100.0), 4.2, R + 0.2, 0.28, -1.5, 1.5)
    p1 = PocketCut("B1", math.radians(100.0), -1.5, 3.85, 0.98, R + 0.2 - 3.85)
    p2 = PocketCut("B2", math.radians(100.0), 1.5, 3.85, 0.98, R + 0.2 - 3.85)
    return CutPlan("small", Stock(R, 2.5, 3.0), (e,), (s,), (p1, p2))


def test_the_right_program_passes_and_a_wrong_one_is_caught():
    plan, tools = _small_plan(), _tools(0.25, 0.6)
    _, good = _run(plan, tools, grid=0.02)
    assert good.ok and good.gouges == 0 and good.max_deviation_mm < 2e-3
    assert abs(good.volume_difference) < 0.01
    # the slot cut 0.05 mm too far round: it eats into the wall beside L1
    wrong = replace(plan, slots=(replace(plan.slots[0], azimuth=plan.slots[0].azimuth + 0.05 / 4.2),))
    text = emit(plan_program(wrong, tools))
    bad = verify(parse_gcode(text), plan, tools={1: 0.25, 2: 0.6}, grid_mm=0.02)
    assert not bad.ok and bad.gouges > 0
    assert 0.045 < bad.max_overcut_mm < 0.07  # 0.05 mm at the floor, more at the outer surface
    assert bad.gouge_examples[0].startswith("L1:")
    # the ellipse cut 0.03 mm too deep
    deep = replace(plan, ellipses=(replace(plan.ellipses[0], floor_depth=0.18),))
    bad = verify(parse_gcode(emit(plan_program(deep, tools))), plan, tools={1: 0.25, 2: 0.6}, grid_mm=0.02)
    assert bad.gouges > 0 and bad.max_overcut_mm == pytest.approx(0.03, abs=0.005)
    # a program that leaves the pockets out is an undercut, and short on volume
    none = replace(plan, pockets=())
    bad = verify(parse_gcode(emit(plan_program(none, tools))), plan, tools={1: 0.25, 2: 0.6}, grid_mm=0.02)
    assert not bad.ok and bad.max_undercut_mm > 0.1 and bad.volume_difference < -0.01


def test_a_rapid_through_the_stock_is_caught():
    plan, tools = _small_plan(), _tools(0.25, 0.6)
    text = emit(plan_program(plan, tools)).replace("G0 Z7.0000", "G0 Z4.0000", 1)
    v = verify(parse_gcode(text), plan, tools={1: 0.25, 2: 0.6}, grid_mm=0.02)
    assert v.rapid_faults and not v.ok


def test_pocket_tool_choice():
    assert pocket_tool_diameter(1.98) == 1.5 and pocket_tool_diameter(0.98) == 0.6
    with pytest.raises(ValueError):
        pocket_tool_diameter(1.98, 0.5)


def test_gcode_command_writes_a_verified_program(tmp_path, capsys):
    out = tmp_path / "mini.ngc"
    assert main(["gcode", "ftrac_mini", "-o", str(out), "--grid", "0.04"]) == 0
    report = json.loads((tmp_path / "mini.ngc.verify.json").read_text())
    assert report["ok"] and report["max_deviation_mm"] <= 0.01 and report["gouges"] == 0
    assert abs(report["volume_difference"]) <= 0.01 and report["cycle_time_s"]["total_s"] > 0
    assert "PASS" in capsys.readouterr().out
    # the same file checked as a foreign program passes too
    assert main(["gcode", "ftrac_mini", "--check", str(out), "--grid", "0.04"]) == 0


@pytest.mark.parametrize(
    "args, where",
    [
        (["gcode", "no_such_design"], "no_such_design"),
        (["gcode", "ftrac_mini", "--check", "{tmp}/missing.ngc"], "missing.ngc"),
        (["gcode", "ftrac_mini", "--check", "{tmp}/bad.ngc"], "bad.ngc: line 2"),
        (["gcode", "ftrac_mini", "--post", "haas"], "--post"),
        (["gcode", "ftrac_mini", "--grid", "0"], "--grid"),
        (["gcode", "ftrac_mini", "-o", "{tmp}"], "{tmp}"),
    ],
)
def test_gcode_command_bad_input_exits_2_with_one_line(tmp_path, capsys, args, where):
    (tmp_path / "bad.ngc").write_text("G21 G90\nG1 X1 W2 F10\n")
    args = [a.format(tmp=tmp_path) for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and where.format(tmp=tmp_path) in err
    assert not list(tmp_path.glob("*.verify.json"))
