"""The press-fit test coupon: sizes stepped around the profile's, its program verified like the
body's, the fit that held fed back into the design, and ``ftrac-design coupon`` end to end."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from ftrac_design.cli.main import main
from ftrac_design.design import load_design
from ftrac_design.machining.gcode import parse_gcode
from ftrac_design.machining.model import SlotCut, tooling
from ftrac_design.machining.post import emit
from ftrac_design.machining.simulate import verify
from ftrac_design.machining.toolpath import plan_program
from ftrac_design.manufacture.coupon import coupon_csv, plan_coupon
from ftrac_design.manufacture.profiles import cut_sizes


@pytest.mark.parametrize("preset, profile", [("ftrac_2005", "cnc"), ("ftrac_mini", "fdm"), ("nine_bead", "cnc")])
def test_sizes_step_around_the_profile(preset, profile):
    d = load_design(preset)
    c = plan_coupon(d, profile)
    cuts = cut_sizes(d, profile)
    grooves = [s for s in c.steps if s.kind == "groove"]
    pockets = [s for s in c.steps if s.kind == "pocket"]
    step = {"cnc": 0.01, "fdm": 0.05}[profile]
    if d.wire is None:
        assert not grooves and not c.plan.slots
    else:
        assert [s.size for s in grooves] == pytest.approx(cuts.groove_width + step * np.arange(-3, 4))
        fits = [d.wire.diameter - s.size if profile == "cnc" else (s.size - d.wire.diameter) / 2 for s in grooves]
        assert [s.fit for s in grooves] == pytest.approx(fits)
    assert [s.size for s in pockets] == pytest.approx(cuts.pocket_diameter + step * np.arange(-3, 4))
    az = sorted(s.azimuth for s in c.steps)
    assert len(set(np.round(az, 9))) == len(az)  # every cut at its own A
    rows = list(csv.DictReader(coupon_csv(c).splitlines()))
    assert len(rows) == len(c.steps) and all(r["holds"] == "" for r in rows)
    for cut in (*c.plan.slots, *c.plan.pockets):  # inside the coupon, clear of the grip
        z0, z1 = (
            (cut.z0 - cut.end_radius, cut.z1 + cut.end_radius)
            if isinstance(cut, SlotCut)
            else (cut.z - cut.diameter / 2, cut.z + cut.diameter / 2)
        )
        assert -c.stock.half_length + 5.0 <= z0 + 1e-9 and z1 < c.stock.half_length


def test_thinnest_wall_is_checked_against_the_design_rules():
    d = load_design("ftrac_mini")
    c = plan_coupon(d, "cnc")
    n = len(c.plan.slots)
    slot_wall = 2 * c.plan.slots[0].floor_radius * math.sin(math.pi / n) - max(s.width for s in c.plan.slots)
    assert c.min_wall <= slot_wall + 1e-12 and c.min_wall >= 1.0
    with pytest.raises(ValueError, match="thinnest wall"):
        plan_coupon(d, "cnc", count=15, step=0.001)  # fifteen pockets round a 10 mm cylinder


def test_sizes_never_narrower_than_the_end_mill():
    d = load_design("ftrac_mini")  # 0.28 mm grooves, 0.25 mm end mill
    c = plan_coupon(d, "cnc", step=0.02)
    widths = [s.size for s in c.steps if s.kind == "groove"]
    assert widths[0] == pytest.approx(0.25) and np.allclose(np.diff(widths), 0.02)


def test_rounded_slot_intervals_end_on_its_surface():
    s = SlotCut("S", 0.3, 4.2, 5.2, 0.3, -1.0, 1.0, 0.125)
    rng = np.random.default_rng(3)
    th = 0.3 + rng.uniform(-0.05, 0.05, 400)
    z = rng.uniform(-1.2, 1.2, 400)
    lo, hi = s.ray_interval(th, z, 5.0)
    hit = np.isfinite(lo)
    assert 100 < hit.sum() < 400
    assert np.allclose(s.sdf(lo[hit], th[hit], z[hit]), 0.0, atol=1e-9)
    inner = hi[hit] < 5.0
    assert np.allclose(s.sdf(hi[hit][inner], th[hit][inner], z[hit][inner]), 0.0, atol=1e-9)


def test_coupon_program_cuts_the_coupon():
    d = load_design("ftrac_2005")
    c = plan_coupon(d, "cnc")
    tools = tooling(d.manufacturing.cnc, min(p.diameter for p in c.plan.pockets))
    text = emit(plan_program(c.plan, tools), "fanuc")
    v = verify(parse_gcode(text), c.plan, tools={1: tools.groove.diameter, 2: tools.pocket.diameter}, grid_mm=0.04)
    assert v.ok and v.gouges == 0 and v.max_deviation_mm < 2e-3
    # a square-ended reference would be gouged by the end mill's round ends
    square = c.plan.__class__(
        c.plan.name,
        c.stock,
        (),
        tuple(SlotCut(s.id, s.azimuth, s.floor_radius, s.top_radius, s.width, s.z0, s.z1) for s in c.plan.slots),
        c.plan.pockets,
    )
    bad = verify(parse_gcode(text), square, tools={1: tools.groove.diameter, 2: tools.pocket.diameter}, grid_mm=0.04)
    # up to the end mill's radius past each square end (sampled on a 0.04 mm grid)
    assert bad.gouges > 0 and 0.15 < bad.max_overcut_mm <= tools.groove.diameter / 2 + 1e-3


def test_interference_feeds_back_into_the_design(tmp_path, capsys):
    out = tmp_path / "mini_fit.toml"
    assert main(["coupon", "ftrac_mini", "--interference", "0.03,0.01", "--write-design", str(out)]) == 0
    d = load_design(out)
    assert d.manufacturing.cnc.wire_interference == 0.03 and d.manufacturing.cnc.bead_interference == 0.01
    orig = load_design("ftrac_mini")
    assert cut_sizes(d, "cnc").groove_width == pytest.approx(orig.wire.diameter - 0.03)
    assert cut_sizes(d, "cnc").pocket_diameter == pytest.approx(orig.bead.diameter - 0.01)
    assert d.model_dump(exclude={"manufacturing"}) == orig.model_dump(exclude={"manufacturing"})
    assert (
        main(
            [
                "coupon",
                "ftrac_mini",
                "--profile",
                "fdm",
                "--interference",
                "0.1,0.12",
                "--write-design",
                str(tmp_path / "f.toml"),
            ]
        )
        == 0
    )
    assert load_design(tmp_path / "f.toml").manufacturing.fdm.wire_clearance == 0.1


@pytest.mark.parametrize(
    "args, where",
    [
        (["coupon", "ftrac_mini", "--interference", "0.03"], "--interference"),
        (["coupon", "ftrac_mini", "--interference", "0.03,0.01"], "--interference"),
        (["coupon", "ftrac_mini", "--step", "0"], "--step"),
        (["coupon", "ftrac_mini", "-o", "{tmp}/afile"], "afile"),
        (["coupon", "nothing_here"], "nothing_here"),
    ],
)
def test_coupon_bad_input_exits_2_with_one_line(tmp_path, capsys, args, where):
    (tmp_path / "afile").write_text("x")
    assert main([a.format(tmp=tmp_path) for a in args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and where in err


@pytest.mark.xdist_group("cad")
def test_coupon_command_builds_a_valid_part(tmp_path):
    import trimesh

    out = tmp_path / "c"
    assert main(["coupon", "ftrac_mini", "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "coupon.csv",
        "coupon.ngc",
        "coupon.ngc.verify.json",
        "coupon.png",
        "coupon.step",
        "coupon.stl",
        "drawing_coupon.pdf",
        "drawing_coupon.svg",
    ]
    _drawing_states_the_plan(out, load_design("ftrac_mini"))
    mesh = trimesh.load(out / "coupon.stl")
    assert mesh.is_volume
    c = plan_coupon(load_design("ftrac_mini"), "cnc")
    blank = math.pi * c.stock.outer_radius**2 * 2 * c.stock.half_length
    v = verify(parse_gcode((out / "coupon.ngc").read_text()), c.plan, grid_mm=0.04)
    removed = blank - mesh.volume
    engraved_max = len(c.steps) * 5 * c.label_height**2 * 0.1  # five characters of the label's height, 0.1 deep
    assert v.reference_mm3 * 0.99 < removed < v.reference_mm3 * 1.01 + engraved_max


def _svg_dims(path) -> dict[str, str]:
    """{dimension key: printed text} of a drawing (texts under ``dim.coupon.<key>`` groups)."""
    import xml.etree.ElementTree as ET

    ns = "{http://www.w3.org/2000/svg}"
    found: dict[str, str] = {}

    def walk(el, gid):
        own = el.get("id", gid) if el.tag == f"{ns}g" else gid
        if el.tag == f"{ns}text" and own:
            found[own] = "".join(el.itertext())
        for child in el:
            walk(child, own)

    walk(ET.parse(path).getroot(), None)
    return {k[len("dim.coupon.") :]: v for k, v in found.items() if k.startswith("dim.coupon.")} | {
        k: v for k, v in found.items() if k.startswith("tb.")
    }


def _value(text: str) -> float:
    import re

    m = re.match(r"^[ØR]?(-?\d+\.\d+)", text)
    assert m, text
    return float(m.group(1))


def _drawing_states_the_plan(out, design):
    """Every step's A, z, size, depth, part Ø and fit printed as the plan has them (to the printed
    0.001 mm / 0.01°), the profile's fit-critical tolerance on every size, the design file's sha256."""
    import hashlib

    from ftrac_design.design.presets import preset_path
    from ftrac_design.manufacture.profiles import drawing_tolerances

    c = plan_coupon(design, "cnc")
    printed = _svg_dims(out / "drawing_coupon.svg")
    crit = drawing_tolerances("cnc").critical
    cuts = {k.id: k for k in (*c.plan.slots, *c.plan.pockets)}
    R = c.stock.outer_radius
    assert abs(_value(printed["coupon.outer_diameter"]) - 2 * R) <= 5e-4
    assert abs(_value(printed["coupon.length"]) - 2 * c.stock.half_length) <= 5e-4
    for st in c.steps:
        cut = cuts[st.id]
        z = (cut.z0 + cut.z1) / 2 if st.kind == "groove" else cut.z
        expect = {
            "A": math.degrees(st.azimuth) % 360,
            "z": z,
            "size": st.size,
            "depth": R - cut.floor_radius,
            "part": st.part_diameter,
            "fit": st.part_diameter - st.size,
        }
        for key, value in expect.items():
            tol = 5e-3 if key == "A" else 5e-4
            assert abs(_value(printed[f"{st.id}.{key}"]) - value) <= tol + 1e-9, (st.id, key, printed[f"{st.id}.{key}"])
        assert f"±{crit:.3f}" in printed[f"{st.id}.size"] and printed[f"{st.id}.size"].endswith("◆")
    assert printed["tb.sha256"] == hashlib.sha256(preset_path("ftrac_mini").read_bytes()).hexdigest()


@pytest.mark.xdist_group("cad")
def test_fdm_coupon_is_a_3mf_with_its_print_settings(tmp_path):
    """Printed, the coupon comes as a 3MF (read back by trimesh: the STL's triangles and volume) with
    the slicer settings the fdm profile assumes."""
    import json

    import trimesh

    out = tmp_path / "c"
    assert main(["coupon", "ftrac_mini", "--profile", "fdm", "-o", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert "coupon.3mf" in names and "print_settings.json" in names and "coupon.ngc" not in names
    stl = trimesh.load(out / "coupon.stl")
    scene = trimesh.load(out / "coupon.3mf")
    (mesh,) = scene.geometry.values() if isinstance(scene, trimesh.Scene) else (scene,)
    assert len(mesh.faces) == len(stl.faces) and abs(mesh.volume - stl.volume) <= 1e-6 * stl.volume
    settings = json.loads((out / "print_settings.json").read_text())
    assert settings["profile"] == "fdm" and settings["design"] == "ftrac_mini"
