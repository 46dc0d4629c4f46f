"""Design files: the presets load, derived values are computed, and every kind of bad design
stops ``build`` and ``check`` with exit 2, one line naming the file and the key, and no
output directory (validation runs before CadQuery is imported). A preset's name works where a
design file does, and ``ftrac-design presets`` lists them."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from ftrac_design.cli.main import main
from ftrac_design.design import load_design
from ftrac_design.design.presets import PRESETS_DIR, SPACES_DIR, resolve_design, resolve_space

MODELS = PRESETS_DIR
SOURCE = (MODELS / "ftrac_2005.toml").read_text()


def test_presets_load_with_derived_values():
    d = load_design(MODELS / "ftrac_2005.toml")
    assert (d.outer_radius, d.half_length) == (15.0, 25.0)
    assert len(d.sha256) == 64 and d.source.endswith("ftrac_2005.toml")
    assert [len(ln.beads_z) for ln in d.lines] == [4, 3, 2]
    for e in d.ellipses:
        assert e.tilt_rad == pytest.approx(math.radians(30.0))
    mini = load_design(MODELS / "ftrac_mini.toml")
    assert (mini.outer_radius, mini.half_length) == (5.0, 10.0)
    nine = load_design(MODELS / "nine_bead.toml")
    assert not nine.lines and not nine.ellipses and len(nine.beads) == 9


def _sub(old: str, new: str) -> str:
    assert old in SOURCE, old
    return SOURCE.replace(old, new, 1)


BEADS_L1 = re.search(r"beads_z = \[[^\]]*\]", SOURCE).group(0)

# (case, design text, the key the message must name, a phrase of what was expected)
BAD = [
    ("negative size", _sub("outer_diameter = 30.0", "outer_diameter = -30.0"), "body.outer_diameter", "greater than 0"),
    ("zero wire", _sub("[wire]\ndiameter = 0.5", "[wire]\ndiameter = 0.0"), "wire.diameter", "greater than 0"),
    (
        "bore too big",
        _sub("bore_diameter = 20.0", "bore_diameter = 32.0"),
        "body.bore_diameter",
        "smaller than outer_diameter",
    ),
    ("string for a number", _sub("length = 50.0", 'length = "fifty"'), "body.length", "a number"),
    ("unknown key", _sub("[wire]\n", '[wire]\ncolour = "red"\n'), "wire.colour", "no such key"),
    (
        "bead off its line",
        _sub(BEADS_L1, "beads_z = [-16.0, -1.5, 10.0, 17.0]"),
        "lines[0].beads_z[3]",
        "a bead on its line",
    ),
    (
        "ellipses crossing",
        _sub("z_center = -12.5", "z_center = 8.0"),
        "ellipses[1].z_center",
        "ellipses that do not cross",
    ),
    ("not TOML", "name = \n", "", "TOML"),
]


@pytest.mark.parametrize("case,text,key,expected", BAD, ids=[b[0] for b in BAD])
@pytest.mark.parametrize("command", ["build", "check"])
def test_bad_design_exits_2_with_one_line(tmp_path, capsys, case, text, key, expected, command):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "out"
    args = [command, str(path)] + (["-o", str(out)] if command == "build" else [])
    assert main(args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "bad.toml" in err and key in err and expected in err, err
    assert "Traceback" not in err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_missing_design_file(tmp_path, capsys):
    assert main(["build", str(tmp_path / "nope.toml"), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "nope.toml" in err and "not found" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_bad_profile_is_a_usage_error(capsys):
    assert main(["build", str(MODELS / "ftrac_2005.toml"), "--profile", "laser"]) == 2
    err = capsys.readouterr().err
    assert "laser" in err and len(err.strip().splitlines()) == 1


def test_to_toml_round_trips_every_preset():
    """The design writer's TOML reads back to the same mapping and the same design."""
    import tomllib

    from ftrac_design.design import parse_design
    from ftrac_design.design.presets import PRESETS_DIR
    from ftrac_design.design.writer import round_values, to_toml

    for path in sorted(PRESETS_DIR.glob("*.toml")):
        data = tomllib.loads(path.read_text("utf-8"))
        text = to_toml(data)
        assert tomllib.loads(text) == data, path.name
        assert parse_design(tomllib.loads(text)) == parse_design(data)
        assert round_values({"a": [0.123456, -0.0], "b": 2}) == {"a": [0.1235, 0.0], "b": 2}


ALL_PRESETS = ("ftrac_2005", "ftrac_mini", "ftrac_mini_imgopt", "ftrac_mini_opt", "ftrac_mini_stock", "nine_bead")


def test_a_preset_name_resolves_to_its_shipped_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ALL_PRESETS:
        assert resolve_design(name) == resolve_design(f"{name}.toml") == MODELS / f"{name}.toml"
        assert load_design(name).name == name
    assert resolve_space("ftrac_mini_layout") == SPACES_DIR / "ftrac_mini_layout.toml"
    # a path with a directory part is never a preset, an unknown name stays as given
    assert resolve_design("sub/ftrac_2005") == Path("sub/ftrac_2005")
    assert resolve_design("ftrac_2006") == Path("ftrac_2006")
    # a folder of that name (a build) does not hide the preset; a file of that name wins
    (tmp_path / "ftrac_2005").mkdir()
    assert resolve_design("ftrac_2005") == MODELS / "ftrac_2005.toml"
    (tmp_path / "ftrac_2005.toml").write_text(SOURCE.replace('name = "ftrac_2005"', 'name = "local_copy"'))
    assert resolve_design("ftrac_2005.toml") == Path("ftrac_2005.toml")
    assert load_design("ftrac_2005.toml").name == "local_copy"


@pytest.mark.parametrize("command", ["build", "check"])
def test_unknown_preset_exits_2_with_one_line_listing_the_presets(tmp_path, capsys, command):
    argv = [command, "ftrac_2006"] + (["-o", str(tmp_path / "out")] if command == "build" else [])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ftrac_2006: file not found (nor a preset: ")
    assert all(name in err[0] for name in ALL_PRESETS) and "Traceback" not in err[0]
    assert not (tmp_path / "out").exists()


def test_check_takes_a_preset_name(capsys):
    assert main(["check", "nine_bead"]) == 0
    assert capsys.readouterr().out.splitlines()[0].startswith("check nine_bead (cnc):")


def test_presets_command_lists_every_preset_and_space(capsys):
    assert main(["presets"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for name in ALL_PRESETS:
        line = next(x for x in lines if x.split()[:1] == [name])
        assert load_design(name).description[:40] in line
    spaces = sorted(p.stem for p in SPACES_DIR.glob("*.toml"))
    assert len(spaces) == 6 and all(any(x.split()[:1] == [s] and len(x.split()) > 3 for x in lines) for s in spaces)
    assert main(["presets", "--paths"]) == 0
    assert str(MODELS / "nine_bead.toml") in capsys.readouterr().out


def test_presets_command_bad_argument_exits_2_with_one_line(capsys):
    assert main(["presets", "--colour"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--colour" in err[0] and "Traceback" not in err[0]
