"""``build`` as a whole: every file written and hashed in the manifest, the profile changing
cut sizes only, the design-rule gate with ``--force``, and atomic output."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cad_support as S
import pytest

from ftrac_design.cad.build import OUTPUT_FILES
from ftrac_design.cli.main import main
from ftrac_design.fileio import sha256_file
from ftrac_design.manufacture.profiles import cut_sizes

pytestmark = pytest.mark.xdist_group("cad")


@pytest.mark.parametrize("preset", S.PRESETS)
def test_every_file_written_and_hashed(preset):
    res = S.build(preset)
    names = sorted(p.name for p in res.out_dir.iterdir())
    assert names == sorted(OUTPUT_FILES)
    m = json.loads((res.out_dir / "manifest.json").read_text())
    assert set(m["files"]) == set(OUTPUT_FILES) - {"manifest.json"}
    for name, info in m["files"].items():
        assert info["sha256"] == sha256_file(res.out_dir / name)
        assert info["bytes"] == (res.out_dir / name).stat().st_size
    assert m["profile"] == "cnc" and m["force"] is False
    assert m["design"]["sha256"] == S.design_of(preset).sha256
    assert m["versions"]["ocp"] not in ("", "unknown")
    assert m["beads"]["count"] == len(
        S.design_of(preset).lines
        and [b for ln in S.design_of(preset).lines for b in ln.beads_z]
        or S.design_of(preset).beads
    )
    assert m["manufacturing"]["rules"]["ok"] is True
    assert {"stock", "wires", "beads"} <= set(m["bom"])
    assert m["build_time_s"] > 0 and set(m["timings_s"]) >= {"body", "export_body", "render"}


@pytest.mark.parametrize("preset", ["ftrac_2005", "ftrac_mini"])
def test_profiles_differ_in_cut_sizes_only(preset):
    cnc, fdm = S.build(preset, "cnc"), S.build(preset, "fdm")
    # the feature geometry (and so the solver's input) does not depend on the profile
    assert (cnc.out_dir / "features.json").read_bytes() == (fdm.out_dir / "features.json").read_bytes()
    d = S.design_of(preset)
    for res, profile in ((cnc, "cnc"), (fdm, "fdm")):
        cuts = cut_sizes(d, profile)
        m = json.loads((res.out_dir / "manifest.json").read_text())
        assert m["profile"] == profile and m["cut_sizes"] == cuts.as_dict()
        with open(res.out_dir / "grooves.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        grooves = [float(r["cut_width_mm"]) for r in rows if r["kind"] != "pocket"]
        pockets = [float(r["cut_width_mm"]) for r in rows if r["kind"] == "pocket"]
        assert grooves and pockets
        assert grooves == pytest.approx([cuts.groove_width] * len(grooves), abs=1e-6)
        assert pockets == pytest.approx([cuts.pocket_diameter] * len(pockets), abs=1e-6)
    wire, bead = d.wire.diameter, d.bead.diameter
    assert cut_sizes(d, "cnc").groove_width == pytest.approx(wire - d.manufacturing.cnc.wire_interference)
    assert cut_sizes(d, "fdm").groove_width == pytest.approx(wire + 2 * d.manufacturing.fdm.wire_clearance)
    assert cut_sizes(d, "fdm").pocket_diameter == pytest.approx(bead + 2 * d.manufacturing.fdm.bead_clearance)
    # and the printed part has less material: wider grooves, larger pockets
    v = [json.loads((r.out_dir / "manifest.json").read_text())["volumes_mm3"]["body"] for r in (cnc, fdm)]
    assert v[1] < v[0]


def _violating(tmp_path: Path) -> Path:
    """ftrac_2005 with a 0.5 mm end mill: narrower than the 0.48 mm press-fit groove."""
    text = (S.MODELS / "ftrac_2005.toml").read_text()
    if "[manufacturing.cnc]" in text:
        text = text.replace("[manufacturing.cnc]", "[manufacturing.cnc]\ntool_diameter = 0.5", 1)
    else:
        text += "\n[manufacturing.cnc]\ntool_diameter = 0.5\n"
    p = tmp_path / "too_big_tool.toml"
    p.write_text(text)
    return p


def test_rule_violation_refused_unless_forced(tmp_path, capsys):
    design = _violating(tmp_path)
    out = tmp_path / "out"
    assert main(["build", str(design), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "groove.tool" in err and "--force" in err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]

    assert main(["build", str(design), "-o", str(out), "--force"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["force"] is True and m["manufacturing"]["rules"]["ok"] is False
    assert any("groove.tool" in v for v in m["manufacturing"]["rules"]["violations"])


def test_failed_build_leaves_nothing(tmp_path, monkeypatch):
    from ftrac_design.cad import build as B
    from ftrac_design.cad import render

    def boom(*a, **k):
        raise RuntimeError("render failed")

    monkeypatch.setattr(render, "render_png", boom)
    out = tmp_path / "out"
    with pytest.raises(RuntimeError):
        B.build_fiducial(S.design_of("nine_bead"), out)
    assert list(tmp_path.iterdir()) == []


def test_refuses_to_replace_a_foreign_directory(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    assert main(["build", str(S.MODELS / "nine_bead.toml"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--output" in err and len(err.strip().splitlines()) == 1
    assert (out / "thesis.tex").read_text() == "precious"


def test_assembly_step_holds_every_part_named_coloured_and_placed():
    """The build's assembly.step re-imports with body, every wire piece and bead, the mount,
    the connector and its pins, named and coloured; the body is the fiducial.step solid, every
    bead centre lies inside its bead, and the mount sits where features.json's frame puts it."""
    import numpy as np
    from fixture_support import assembly_parts, inside

    from ftrac_design.cad.export import BEAD_COLOR, BODY_COLOR, WIRE_COLOR
    from ftrac_design.cad.fixture import MOUNT_COLOR
    from ftrac_design.features import load_features

    res = S.build("ftrac_2005")
    parts = assembly_parts(res.out_dir / "assembly.step")
    f = load_features(res.out_dir / "features.json")
    m = json.loads((res.out_dir / "manifest.json").read_text())
    beads = {f"bead_{p.id}" for p in f.points}
    wires = {piece["name"] for piece in m["wires"]["line_pieces"]} | {f"wire_{e.id}" for e in f.ellipses}
    assert set(parts) == {"body", "mount", "connector", "pin_1", "pin_2"} | beads | wires
    assert parts["body"][1] == pytest.approx(BODY_COLOR, abs=1e-6)
    assert parts["mount"][1] == pytest.approx(MOUNT_COLOR, abs=1e-6)
    for name in beads:
        assert parts[name][1] == pytest.approx(BEAD_COLOR, abs=1e-6)
    for name in wires:
        assert parts[name][1] == pytest.approx(WIRE_COLOR, abs=1e-6)
    from ftrac_design.cad.body import volume

    assert volume(parts["body"][0]) == pytest.approx(m["volumes_mm3"]["body"], rel=1e-6)
    for p in f.points:
        assert inside(parts[f"bead_{p.id}"][0], p.center)
        assert not inside(parts["body"][0], p.center)  # the pocket holds the bead
    # the centre of the socket floor (M origin) is the cylinder's z = -L/2 end on its axis
    F_from_M = np.linalg.inv(np.asarray(f.frames["mount_from_fiducial"]))
    floor = (F_from_M @ [0.0, 0.0, 0.0, 1.0])[:3]
    assert floor == pytest.approx([0.0, 0.0, -S.design_of("ftrac_2005").half_length], abs=1e-9)
    assert inside(parts["mount"][0], floor - [0.0, 0.0, 0.5])  # acetal below the floor
    assert not inside(parts["mount"][0], floor + [0.0, 0.0, 0.5])  # the socket above it
