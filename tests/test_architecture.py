"""The house's rules: rooms import one way (import-linter's contracts in pyproject.toml), only
``cad`` imports CadQuery/OCP, no private name crosses from one room into another, no import
circle inside a room, no function longer than 80 lines, and ``ruff check`` and ``ruff format
--check`` (their settings in pyproject.toml) find nothing."""

from __future__ import annotations

import ast
import importlib.util
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


#: the longest a function may be: its ``def`` line to its last line, docstring included
MAX_FUNCTION_LINES = 80
#: functions still longer, each to be split by concern; empty: the list may only shrink, and
#: nothing may join it
LONG_FUNCTIONS_ALLOWED: set[str] = set()


def long_functions(path: Path, root: Path = ROOT, limit: int = MAX_FUNCTION_LINES) -> dict[str, int]:
    """``{"<file>:<Class.>function": lines}`` of every function (methods and nested ones too) in
    ``path`` longer than ``limit`` lines, counted from its ``def`` line to its last line."""
    found: dict[str, int] = {}

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = child.end_lineno - child.lineno + 1
                if n > limit:
                    found[f"{path.relative_to(root).as_posix()}:{prefix}{child.name}"] = n
                walk(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                walk(child, f"{prefix}{child.name}.")

    walk(ast.parse(path.read_text(encoding="utf-8")), "")
    return found


def test_no_function_is_longer_than_80_lines():
    found: dict[str, int] = {}
    for f in sorted(PACKAGE.rglob("*.py")):
        found.update(long_functions(f))
    new = {k: v for k, v in found.items() if k not in LONG_FUNCTIONS_ALLOWED}
    assert not new, f"split these by concern (at most {MAX_FUNCTION_LINES} lines): {new}"
    done = sorted(LONG_FUNCTIONS_ALLOWED - set(found))
    assert not done, (
        f"no longer over {MAX_FUNCTION_LINES} lines (or gone): take them off LONG_FUNCTIONS_ALLOWED: {done}"
    )


def test_the_length_check_finds_a_long_method(tmp_path):
    body = "\n".join(f"        x{i} = {i}" for i in range(80))
    (tmp_path / "m.py").write_text(f"class A:\n    def long(self):\n{body}\n\n    def short(self):\n        pass\n")
    assert long_functions(tmp_path / "m.py", tmp_path) == {"m.py:A.long": 81}


def circles_inside_rooms(package: str) -> list[list[str]]:
    """The import circles among the modules of each room (sub-package) of ``package``, imports
    inside functions included (grimp's graph): each circle's modules, sorted."""
    import grimp

    graph = grimp.build_graph(package, cache_dir=None)

    def room(module: str) -> str:
        return module.split(".")[1] if "." in module else ""

    edges = {
        m: {i for i in graph.find_modules_directly_imported_by(m) if i != m and room(i) == room(m) and room(m)}
        for m in graph.modules
        if m.startswith(package + ".")
    }
    # Tarjan's strongly connected components, iteratively
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles = []
    for root_module in sorted(edges):
        if root_module in index:
            continue
        work = [(root_module, iter(sorted(edges[root_module])))]
        index[root_module] = low[root_module] = len(index)
        stack.append(root_module)
        on_stack.add(root_module)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(edges.get(w, ())))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    circles.append(sorted(component))
    return circles


needs_grimp = pytest.mark.skipif(
    importlib.util.find_spec("grimp") is None, reason="grimp (import-linter's) is not installed"
)


@needs_grimp
def test_no_import_circle_inside_a_room():
    assert circles_inside_rooms("ftrac_design") == []


@needs_grimp
def test_the_circle_check_finds_one(tmp_path, monkeypatch):
    pkg = tmp_path / "house_circle"
    (pkg / "room").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "room" / "__init__.py").write_text("")
    (pkg / "room" / "a.py").write_text("def f():\n    from .b import g\n")
    (pkg / "room" / "b.py").write_text("from .a import f\n")
    (pkg / "room" / "c.py").write_text("from .a import f\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert circles_inside_rooms("house_circle") == [["house_circle.room.a", "house_circle.room.b"]]
