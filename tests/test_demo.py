"""The demo with fewer extras: a step that needs an optional extra which is not installed is
skipped with one line naming the extra, a step that needs a skipped one is skipped too, and
the demo goes on to exit 0 with the list of what it skipped."""

from __future__ import annotations

import sys

import pytest

from ftrac_design.demo import build, optimize
from ftrac_design.demo.run import Step, main, run_steps
from ftrac_design.errors import MissingDependencyError, require


def _needs(module: str, extra: str) -> str:
    require(module, extra, "a demo step")
    return f"{module} ran"


def test_a_step_without_its_extra_is_skipped_with_one_line_and_the_demo_goes_on(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pymoo", None)  # as if `pip install ftrac_design` without [optimize]
    steps = [
        Step("first", lambda: "first ran"),
        Step("the design search", lambda: _needs("pymoo", "optimize")),
        Step("after it", lambda: "after it ran", ("the design search",)),
        Step("last", lambda: _needs("json", "none")),
    ]
    assert main(steps=steps) == 0
    out = capsys.readouterr().out
    skips = [line for line in out.splitlines() if line.startswith("skipped ")]
    assert skips == [
        "skipped the design search: the 'optimize' extra is not installed (pymoo): "
        "pip install 'ftrac_design[optimize]'",
        "skipped after it: it needs the design search, which was skipped",
    ]
    assert "first ran" in out and "json ran" in out and "after it ran" not in out
    assert out.rstrip().splitlines()[-1] == (
        "demo: 2 steps ran, 2 skipped: the design search (the 'optimize' extra); "
        "after it (needs the design search, which was skipped)"
    )


def test_every_step_ran_prints_no_skip_list(capsys):
    done = run_steps([Step("a", lambda: "A"), Step("b", lambda: "B")])
    assert done.ran == ["a", "b"] and not done.skipped
    assert capsys.readouterr().out == "A\n\nB\n"


def test_other_errors_still_stop_the_demo(capsys):
    from ftrac_design.errors import GoalError, InputError

    def bad_input():
        raise InputError("x.toml", "name", "a name")

    def failed():
        raise GoalError("no pose")

    assert main(steps=[Step("a", bad_input)]) == 2
    assert main(steps=[Step("a", failed)]) == 1
    assert "error: x.toml: name: a name" in capsys.readouterr().err


def test_the_build_step_without_cad_still_writes_the_features(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "cadquery", None)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(MissingDependencyError) as info:
        build.demo_step(tmp_path / "built")
    assert info.value.extra == "cad"
    assert (tmp_path / "built" / "features.json").is_file()
    assert [p.name for p in (tmp_path / "built").iterdir()] == ["features.json"]


def test_the_search_step_without_pymoo_names_the_optimize_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pymoo", None)
    with pytest.raises(MissingDependencyError) as info:
        optimize.demo_step(tmp_path / "search")
    assert info.value.extra == "optimize" and info.value.module == "pymoo"


def test_the_report_step_needs_the_build(tmp_path):
    from ftrac_design.demo.run import demo_steps

    names = [s.name for s in demo_steps(tmp_path)]
    assert names[0] == "the build" and names[-1] == "the report" and len(names) == len(set(names)) == 12
    assert {s.name: s.needs for s in demo_steps(tmp_path)}["the report"] == ("the build",)
