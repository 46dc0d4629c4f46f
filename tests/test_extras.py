"""Optional extras: each room's optional packages are declared, imported lazily, and a missing one
stops the command with one line naming the package and the extra that installs it."""

from __future__ import annotations

import ast
import importlib.metadata
import re
import sys
import tomllib
from pathlib import Path

import pytest

from ftrac_design.cli.main import main
from ftrac_design.errors import MissingDependencyError, require

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "ftrac_design"


def _dist_name(requirement: str) -> str:
    return re.split(r"[\s<>=!~\[;]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def _declared() -> tuple[set[str], dict[str, set[str]]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {_dist_name(r) for r in project["dependencies"]}
    extras = {name: {_dist_name(r) for r in reqs} for name, reqs in project["optional-dependencies"].items()}
    return core, extras


def _imports(tree: ast.Module) -> list[tuple[str, bool]]:
    """(top-level module, imported at module level?) for every absolute import in ``tree``."""
    top_level = {id(n) for n in tree.body}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name.split(".")[0], id(node) in top_level) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module.split(".")[0], id(node) in top_level))
    return found


def _required(tree: ast.Module) -> set[tuple[str, str]]:
    """(module, extra) of every ``require("module", "extra", …)`` call in ``tree``."""
    out = set()
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and getattr(node.func, "id", None) == "require"
            and len(node.args) >= 2
            and all(isinstance(a, ast.Constant) for a in node.args[:2])
        ):
            out.add((node.args[0].value.split(".")[0], node.args[1].value))
    return out


def test_every_third_party_import_is_declared_and_optional_ones_are_guarded():
    core, extras = _declared()
    dists = importlib.metadata.packages_distributions()
    trees = {p: ast.parse(p.read_text(), str(p)) for p in PACKAGE.rglob("*.py")}
    guarded = set().union(*(_required(t) for t in trees.values()))
    problems = []
    for path, tree in trees.items():
        room = path.relative_to(PACKAGE).parts[0]
        for module, at_top in _imports(tree):
            if module in sys.stdlib_module_names or module in ("ftrac_design", "__future__"):
                continue
            names = {d.lower().replace("_", "-") for d in dists.get(module, [module])}
            if names & core:
                continue
            in_extras = {e for e, reqs in extras.items() if names & reqs and e not in ("all", "test", "bench")}
            where = f"{path.relative_to(ROOT)}: {module}"
            if not in_extras:
                problems.append(f"{where} is in no dependency list of pyproject.toml")
            elif not any((module, e) in guarded for e in in_extras):
                problems.append(f"{where} (extra {sorted(in_extras)}) has no require({module!r}, …) guarding it")
            elif at_top and room != "cad":
                problems.append(f"{where} (optional) is imported at module level outside the cad room")
    assert not problems, "\n".join(problems)


def test_all_extra_holds_every_user_extra():
    _, extras = _declared()
    # `train` (PyTorch, to train the detector again) is the developers', like `test` and `docs`:
    # `all` would otherwise pull several GB of a CUDA build into every user's install
    users = set(extras) - {"all", "test", "bench", "docs", "train"}
    text = (ROOT / "pyproject.toml").read_text()
    listed = re.search(r'all = \[\s*"ftrac_design\[([^\]]*)\]"', text).group(1).split(",")
    assert users <= {e.strip() for e in listed}


def test_require_returns_the_module():
    assert require("json", "none", "a test") is sys.modules["json"]


def test_require_names_the_package_and_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "cma", None)
    with pytest.raises(MissingDependencyError) as info:
        require("cma", "optimize", "the CMA-ES design search")
    msg = info.value.for_command_line()
    assert "'cma'" in msg and "pip install 'ftrac_design[optimize]'" in msg and "CMA-ES" in msg


def test_require_does_not_hide_a_broken_package(tmp_path, monkeypatch):
    (tmp_path / "brokenpkg_for_test").mkdir()
    (tmp_path / "brokenpkg_for_test" / "__init__.py").write_text("import a_module_that_does_not_exist_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError):
        require("brokenpkg_for_test", "none", "a test")


@pytest.mark.parametrize(
    "blocked, extra, argv",
    [
        ("cma", "optimize", ["optimize", "ftrac_mini", "--evaluations", "4"]),
        ("pymoo", "optimize", ["optimize", "ftrac_mini", "--evaluations", "4"]),
        ("cadquery", "cad", ["build", "ftrac_mini"]),
    ],
)
def test_command_stops_with_one_line_and_writes_nothing(blocked, extra, argv, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, blocked, None)
    out = tmp_path / "out"
    assert main([*argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"ftrac_design[{extra}]" in err and repr(blocked) in err
    assert not out.exists()
