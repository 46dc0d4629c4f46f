"""The house's rules: rooms import one way (import-linter's contracts in pyproject.toml), only
``cad`` imports CadQuery/OCP, no private name crosses from one room into another, and ``ruff
check`` and ``ruff format --check`` (their settings in pyproject.toml) find nothing."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "ftrac_design"
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")
RUFF = Path(sys.executable).with_name("ruff")

needs_lint_imports = pytest.mark.skipif(
    not LINT_IMPORTS.exists(), reason="import-linter is not installed (make installs it)"
)


def _lint(cwd: Path, env_path: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(env_path))
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache"], cwd=cwd, env=env, capture_output=True, text=True, timeout=120
    )


@needs_lint_imports
def test_rooms_import_one_way_and_only_cad_imports_cadquery():
    res = _lint(ROOT, ROOT)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert "2 kept, 0 broken" in res.stdout


@needs_lint_imports
def test_the_layers_contract_catches_an_upward_import(tmp_path):
    # the same kind of contract on a two-room package whose lower room imports the upper one
    pkg = tmp_path / "house"
    for room, body in (("low", "from ..high import x\n"), ("high", "x = 1\n")):
        (pkg / room).mkdir(parents=True)
        (pkg / room / "__init__.py").write_text(body)
    (pkg / "__init__.py").write_text("")
    (tmp_path / "pyproject.toml").write_text(
        textwrap.dedent("""
        [tool.importlinter]
        root_package = "house"
        [[tool.importlinter.contracts]]
        name = "one way"
        type = "layers"
        containers = ["house"]
        layers = ["high", "low"]
    """)
    )
    res = _lint(tmp_path, tmp_path)
    assert res.returncode != 0 and "house.low is not allowed to import house.high" in res.stdout


def private_names_across_rooms(path: Path, package: Path = PACKAGE) -> list[str]:
    """``from <another room> import _name`` in the file ``path`` of ``package`` (dunders allowed)."""
    rel = path.relative_to(package)
    room = rel.parts[0] if len(rel.parts) > 1 else None
    here = [package.name, *rel.with_suffix("").parts[:-1]]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            mod = here[: len(here) - node.level + 1] + (node.module.split(".") if node.module else [])
        elif node.module and node.module.split(".")[0] == package.name:
            mod = node.module.split(".")
        else:
            continue
        target = mod[1] if len(mod) > 1 and (package / mod[1]).is_dir() else None
        if target == room:
            continue
        for alias in node.names:
            if alias.name.startswith("_") and not alias.name.endswith("__"):
                found.append(f"{path.relative_to(package.parent)}:{node.lineno} {'.'.join(mod)}.{alias.name}")
    return found


def test_no_private_name_crosses_a_room():
    bad = [hit for f in sorted(PACKAGE.rglob("*.py")) for hit in private_names_across_rooms(f)]
    assert not bad, "\n".join(bad)


def test_the_private_name_check_finds_one(tmp_path):
    pkg = tmp_path / "house"
    (pkg / "low").mkdir(parents=True)
    (pkg / "high").mkdir()
    (pkg / "high" / "a.py").write_text("from ..low.b import _hidden, __version__, shown\nfrom .c import _ok\n")
    hits = private_names_across_rooms(pkg / "high" / "a.py", pkg)
    assert len(hits) == 1 and hits[0].endswith("house.low.b._hidden")


@pytest.mark.skipif(not RUFF.exists(), reason="ruff is not installed (make installs it)")
def test_ruff_finds_nothing():
    res = subprocess.run([str(RUFF), "check", "--no-cache", "."], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]


@pytest.mark.skipif(not RUFF.exists(), reason="ruff is not installed (make installs it)")
def test_the_code_is_as_ruff_formats_it():
    res = subprocess.run(
        [str(RUFF), "format", "--check", "--no-cache", "."], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, "run `ruff format .`:\n" + res.stdout[-3000:] + res.stderr[-2000:]
