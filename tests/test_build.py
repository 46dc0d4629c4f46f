"""``build`` as a whole: every file written and hashed in the manifest, the profile changing
cut sizes only, the design-rule gate with ``--force``, and atomic output."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

import cad_support as S
from ftrac_design.cad.build import OUTPUT_FILES
from ftrac_design.cad.profiles import cut_sizes
from ftrac_design.cli.main import main
from ftrac_design.fileio import sha256_file

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
    assert m["beads"]["count"] == len(S.design_of(preset).lines and
                                      [b for ln in S.design_of(preset).lines for b in ln.beads_z]
                                      or S.design_of(preset).beads)
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
