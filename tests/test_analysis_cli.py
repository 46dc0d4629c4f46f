"""``ftrac-design analyze`` and ``compare``: files, verdicts, thresholds from the design file
and the command line, bad input (exit 2, one line, nothing written), and no CadQuery."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import MODELS

from ftrac_design.cli.main import main
from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.features.io import write_features

FAST = ["--poses", "500", "--atlas-step-deg", "10", "--score-images", "0", "--image-atlas-step-deg", "0"]


@pytest.fixture(scope="module")
def features_json(tmp_path_factory):
    path = tmp_path_factory.mktemp("feat") / "features.json"
    write_features(path, compute_features(load_design(MODELS / "ftrac_2005.toml")))
    return path


def test_analyze_features_json_writes_json_and_plots(tmp_path, capsys, features_json):
    out = tmp_path / "an"
    assert main(["analyze", str(features_json), "-o", str(out), *FAST]) == 0
    doc = json.loads((out / "analysis.json").read_text())
    assert doc["format"] == "ftrac-analysis" and doc["version"] == 1
    assert doc["design"]["name"] == "ftrac_2005" and doc["passed"] is True
    assert doc["settings"]["poses"] == 500
    assert {c["figure"] for c in doc["checks"]} == {"worst translation", "worst rotation", "worst condition"}
    assert set(doc["groups"]) == {"points", "lines", "ellipses"}
    assert [f["id"] for f in doc["features"]] == [f"B{i}" for i in range(1, 10)] + ["L1", "L2", "L3", "E1", "E2"]
    assert doc["atlas"]["worst_directions"] and doc["worst_poses"]
    for name in doc["files"]:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in out.iterdir()) == sorted(["analysis.json", *doc["files"]])
    text = capsys.readouterr().out
    assert "translation" in text and "worst view directions" in text


def test_analyze_fails_a_threshold_with_exit_1(tmp_path, capsys, features_json):
    out = tmp_path / "an"
    assert (
        main(["analyze", str(features_json), "-o", str(out), *FAST, "--max-translation-mm", "0.1", "--no-plots"]) == 1
    )
    doc = json.loads((out / "analysis.json").read_text())
    assert doc["passed"] is False and doc["thresholds"]["max_translation_mm"] == 0.1
    assert doc["files"] == []
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "worst translation" in err[0]


def test_design_file_thresholds_and_command_line_override(tmp_path):
    out = tmp_path / "mini"
    # ftrac_mini.toml sets max_translation = 1.5 (it would fail the default 1.0)
    assert main(["analyze", str(MODELS / "ftrac_mini.toml"), "-o", str(out), *FAST, "--no-plots"]) == 0
    assert json.loads((out / "analysis.json").read_text())["thresholds"]["max_translation_mm"] == 1.5
    assert (
        main(
            [
                "analyze",
                str(MODELS / "ftrac_mini.toml"),
                "-o",
                str(out),
                *FAST,
                "--no-plots",
                "--max-translation-mm",
                "1.0",
            ]
        )
        == 1
    )


BAD = [
    ("missing file", ["analyze", "{tmp}/nope.toml"], "nope.toml"),
    ("wrong kind of file", ["analyze", "{tmp}/x.txt"], "a design file (.toml), a features file (.json) or a preset"),
    (
        "unknown preset",
        ["analyze", "ftrac_2006"],
        "or a preset (ftrac_2005, ftrac_mini, ftrac_mini_imgopt, ftrac_mini_opt,",
    ),
    ("unknown preset file", ["analyze", "ftrac_2006.toml"], "file not found (nor a preset: ftrac_2005, ftrac_mini,"),
    ("bad features", ["analyze", "{tmp}/bad.json"], "bad.json"),
    ("bad analysis key", ["analyze", "{tmp}/bad.toml"], "analysis.cone_deg"),
    ("zero poses", ["analyze", "{models}/ftrac_2005.toml", "--poses", "0"], "--poses"),
    (
        "negative error",
        ["analyze", "{models}/ftrac_2005.toml", "--segmentation-error-mm", "-1"],
        "--segmentation-error-mm",
    ),
    ("compare non-png", ["compare", "{models}/ftrac_2005.toml", "-o", "{tmp}/c.pdf", "--poses", "100"], ".png"),
]


@pytest.mark.parametrize("case,argv,needle", BAD, ids=[b[0] for b in BAD])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, case, argv, needle):
    (tmp_path / "x.txt").write_text("hello")
    (tmp_path / "bad.json").write_text('{"format": "ftrac-features", "version": 1, "points": "many"}')
    (tmp_path / "bad.toml").write_text((MODELS / "ftrac_2005.toml").read_text() + "\n[analysis]\ncone_deg = 0.0\n")
    before = set(tmp_path.iterdir())
    out = tmp_path / "out"
    args = [a.format(tmp=tmp_path, models=MODELS) for a in argv]
    if args[0] == "analyze":
        args += ["-o", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert "Traceback" not in err[0]
    assert set(tmp_path.iterdir()) == before


def test_analyze_refuses_to_replace_a_foreign_directory(tmp_path, capsys, features_json):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    assert main(["analyze", str(features_json), "-o", str(out), *FAST]) == 2
    assert (out / "thesis.tex").read_text() == "precious"
    assert "--output" in capsys.readouterr().err


def test_compare_prints_a_table_and_draws_overlays(tmp_path, capsys):
    out = tmp_path / "cmp.png"
    assert (
        main(
            [
                "compare",
                str(MODELS / "ftrac_2005.toml"),
                str(MODELS / "nine_bead.toml"),
                "--poses",
                "400",
                "--score-images",
                "0",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    rows = {line.split()[0]: line.split() for line in text.splitlines() if line.split()}
    assert rows["ftrac_2005"][-1] == "PASS" and rows["nine_bead"][-1] == "FAIL"
    # the paper's point (Fig. 8): the FTRAC fiducial beats nine beads in the same envelope
    assert float(rows["ftrac_2005"][1]) < float(rows["nine_bead"][1])
    assert out.read_bytes()[:4] == b"\x89PNG"
    doc = json.loads(out.with_suffix(".json").read_text())
    assert [d["design"] for d in doc["designs"]] == ["ftrac_2005", "nine_bead"]


def test_analysis_never_imports_cadquery(tmp_path):
    code = (
        "import sys\n"
        "from ftrac_design.cli.main import main\n"
        f"rc = main(['analyze', r'{MODELS / 'ftrac_2005.toml'}', '-o', r'{tmp_path / 'a'}', '--poses', '200',"
        " '--score-images', '2', '--workers', '0', '--atlas-step-deg', '15', '--image-atlas-step-deg', '45'])\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('cadquery', 'OCP', 'pyvista', 'trimesh')]\n"
        "assert rc == 0 and not bad, (rc, bad)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)
