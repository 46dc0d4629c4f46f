"""Shared pieces of the fuzz tests (``tests/test_fuzz_*.py``): Hypothesis profiles, the
number of generated cases per input kind, an in-process runner for the real command line,
the exit-code/stderr/output properties every run must keep, and value mutators.

Profiles (``FTRAC_FUZZ_PROFILE``):

- ``ci`` (default): a bounded, derandomised number of cases per input kind (the same cases
  every run, so CI never flakes), no deadline — ``make test`` stays fast on 2 cores;
- ``long``: ×20 the cases, random (Hypothesis' example database keeps what failed), for a
  local run: ``FTRAC_FUZZ_PROFILE=long .venv/bin/python -m pytest tests/test_fuzz_*.py``.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import tempfile
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

from hypothesis import HealthCheck, currently_in_test_context, event, settings
from hypothesis import strategies as st

from ftrac_design.cli.main import main
from ftrac_design.design.presets import PRESETS_DIR

MODELS = PRESETS_DIR
PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")

PROFILE = os.environ.get("FTRAC_FUZZ_PROFILE", "ci")
_SCALE = {"ci": 1, "long": 20}
if PROFILE not in _SCALE:
    raise RuntimeError(f"FTRAC_FUZZ_PROFILE={PROFILE!r}: expected one of {sorted(_SCALE)}")

# filter_too_much: the tiny optimize runs keep only the mutated spaces that validate
_QUIET = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]
settings.register_profile(
    "ci", deadline=None, derandomize=True, database=None, print_blob=True, suppress_health_check=_QUIET
)
settings.register_profile("long", deadline=None, print_blob=True, suppress_health_check=_QUIET)
settings.load_profile(PROFILE)

#: generated cases per input kind under the ``ci`` profile (docs/reference/errors.md: *Fuzzing*); ``long`` ×20
CASES = {
    "design_check": 120,  # mutated design TOML → `check`
    "design_build": 8,  # mutated design TOML that must fail validation → `build` (exit 2 before CAD)
    "design_analyze": 15,  # mutated design TOML → `analyze` (100 poses, 15° atlas, no plots)
    "features_solve": 80,  # mutated features.json → `solve`
    "features_analyze": 25,  # mutated features.json → `analyze`
    "observation_solve": 150,  # mutated observation.json / .jsonl → `solve`
    "scrambled_solve": 40,  # simulated observation with swapped ids / moved beads → solver
    "image_track": 40,  # broken image files → `track`
    "image_read": 300,  # broken and lying image files → ftrac_design.images readers
    "radiograph_track": 12,  # a simulated radiograph damaged (NaN, dtype, crop, scale, …) → `track`
    "space_optimize": 40,  # mutated search-space TOML → `optimize --print-space` (validation only)
    "space_optimize_run": 2,  # mutated spaces that validate → one tiny in-process `optimize` run
    "report": 20,  # a build's manifest.json or analysis.json mutated → `report BUILD_DIR`
}


def cases(kind: str) -> settings:
    """Hypothesis settings for ``kind``: its number of cases under the active profile."""
    return settings(max_examples=CASES[kind] * _SCALE[PROFILE])


# ------------------------------------------------------------------------- running the CLI
@dataclass
class Run:
    """One in-process run of ``ftrac-design``: exit code, stdout, stderr, and the traceback
    of an exception that escaped ``main`` (a crash), if any."""

    args: list[str]
    code: int | None
    out: str
    err: str
    crash: str | None

    def describe(self) -> str:
        return (
            f"ftrac-design {' '.join(self.args)}\nexit {self.code}\n--- stdout\n{self.out[-2000:]}"
            f"\n--- stderr\n{self.err[-2000:]}\n--- crash\n{self.crash or '-'}"
        )


def run_cli(args: list[str | Path]) -> Run:
    """Run ``ftrac_design.cli.main.main(args)`` in this process, capturing its output."""
    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    crash = None
    code = None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # main() returns codes; a SystemExit escaping it is a bug too
            crash = f"SystemExit({exc.code!r})"
        except BaseException:  # noqa: BLE001 — anything escaping main() is what we look for
            crash = traceback.format_exc()
    return Run(argv, code, out.getvalue(), err.getvalue(), crash)


_TMP_NAME = re.compile(r"(^\..*\.tmp$)|(^\..*\.old-\d+$)")


def leftovers(folder: Path) -> list[str]:
    """Temporary files or directories (``.name.XXXX.tmp``, ``.name.old-PID``) under ``folder``."""
    return [str(p) for p in folder.rglob(".*") if _TMP_NAME.match(p.name) or p.name.endswith(".tmp")]


def assert_clean(run: Run, inputs: list[Path], out_dir: Path) -> None:
    """The property every fuzzed run keeps (SPEC §5): exit 0, 1 or 2; no traceback; exit 2
    says in one to three stderr lines which file, which key and what was expected; nothing
    half-written under ``out_dir``."""
    assert run.crash is None, "crash\n" + run.describe()
    if currently_in_test_context():
        event(f"exit {run.code}")
    assert run.code in (0, 1, 2), "exit code\n" + run.describe()
    assert "Traceback" not in run.out + run.err, "traceback printed\n" + run.describe()
    left = leftovers(out_dir)
    assert not left, f"half-written output {left}\n" + run.describe()
    if run.code == 2:
        lines = [ln for ln in run.err.splitlines() if ln.strip()]
        assert 1 <= len(lines) <= 3, "exit 2 must print one to three lines\n" + run.describe()
        text = " ".join(lines)
        names = [str(p) for p in inputs] + [p.name for p in inputs]
        assert any(n in text for n in names) or "see --help" in text, "exit 2 must name the file\n" + run.describe()
        # file: key: expected — at least a colon after the file name and some words
        assert re.search(r":\s*\S.*\S", text), "exit 2 must say what was expected\n" + run.describe()


@contextlib.contextmanager
def scratch() -> Iterator[Path]:
    """A fresh temporary directory per generated case (pytest's tmp_path is per test)."""
    with tempfile.TemporaryDirectory(prefix="ftrac-fuzz-") as d:
        yield Path(d)


# ------------------------------------------------------------------------- TOML writing
def _toml_key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def to_toml(d: dict[str, Any], prefix: str = "") -> str:
    """TOML text for a nested mapping (tables as ``[a.b]``, lists of tables as ``[[a]]``)."""
    lines = [
        f"{_toml_key(k)} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, dict) and not _is_table_array(v)
    ]
    for k, v in d.items():
        name = f"{prefix}{_toml_key(k)}"
        if isinstance(v, dict):
            lines.append(f"\n[{name}]")
            lines.append(to_toml(v, name + "."))
        elif _is_table_array(v):
            for item in v:
                lines.append(f"\n[[{name}]]")
                # sub-tables of array items are written inline, which TOML allows
                lines.extend(f"{_toml_key(a)} = {_toml_value(b)}" for a, b in item.items())
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------- mutations


def key_paths(obj: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path (tables, arrays and leaves) of a parsed TOML/JSON document."""
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += key_paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += key_paths(v, prefix + (i,))
    return out


def get_at(obj: Any, path: tuple) -> Any:
    for p in path:
        obj = obj[p]
    return obj


def set_at(obj: Any, path: tuple, value: Any) -> None:
    get_at(obj, path[:-1])[path[-1]] = value


def delete_at(obj: Any, path: tuple) -> None:
    parent = get_at(obj, path[:-1])
    del parent[path[-1]]


#: numbers at the edges: signs, zero, tiny, huge, non-finite
EDGE_FLOATS = st.sampled_from(
    [
        0.0,
        -0.0,
        -1.0,
        1e-300,
        -1e-300,
        5e-324,
        1e-9,
        1e300,
        -1e300,
        1e12,
        float("inf"),
        float("-inf"),
        float("nan"),
        0.1,
        1e6,
        -1e6,
    ]
)


def scalars(toml: bool = True) -> st.SearchStrategy:
    """Any scalar a file may hold in a wrong place."""
    return st.one_of(
        EDGE_FLOATS,
        st.floats(allow_nan=toml, allow_infinity=toml, width=64),
        st.integers(min_value=-(2**63), max_value=2**63 - 1),
        st.booleans(),
        st.text(max_size=8),
    )


def any_values(toml: bool = True) -> st.SearchStrategy:
    """Scalars, lists and tables (a wrong type for almost any key)."""
    return st.recursive(
        scalars(toml),
        lambda inner: st.one_of(
            st.lists(inner, max_size=4), st.dictionaries(st.text(min_size=1, max_size=6), inner, max_size=3)
        ),
        max_leaves=6,
    )


@st.composite
def mutated(draw, doc: Any, toml: bool = True, max_mutations: int = 3) -> tuple[Any, list[str]]:
    """A copy of ``doc`` with 1–``max_mutations`` mutations; returns it and what was done.

    Each mutation picks any key path and deletes it, replaces it by a value of another type,
    flips its sign or scales it by a power of ten, or — for lists — duplicates, drops or
    empties items (arrays of tables added/removed), or adds an unknown key to a table."""
    doc = json.loads(json.dumps(doc))
    done: list[str] = []
    for _ in range(draw(st.integers(1, max_mutations))):
        paths = key_paths(doc)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        cur = get_at(doc, path)
        ops = ["delete", "replace", "edge"]
        if isinstance(cur, (int, float)) and not isinstance(cur, bool):
            ops += ["negate", "scale", "zero"]
        if isinstance(cur, list):
            ops += ["dup", "drop", "empty"]
        if isinstance(cur, dict):
            ops += ["unknown"]
        op = draw(st.sampled_from(ops))
        if op == "delete":
            delete_at(doc, path)
        elif op == "replace":
            set_at(doc, path, draw(any_values(toml)))
        elif op == "edge":
            set_at(doc, path, draw(EDGE_FLOATS if toml else EDGE_FLOATS.filter(math.isfinite)))
        elif op == "negate":
            set_at(doc, path, -cur)
        elif op == "zero":
            set_at(doc, path, 0 * cur)
        elif op == "scale":
            k = draw(st.sampled_from([-300, -12, -6, -3, -1, 1, 3, 6, 12, 300]))
            try:
                v = cur * 10.0**k
            except OverflowError:
                v = math.copysign(1e308, cur)
            set_at(doc, path, v if toml or math.isfinite(v) else 1e308)
        elif op == "dup" and cur:
            i = draw(st.integers(0, len(cur) - 1))
            cur.insert(i, json.loads(json.dumps(cur[i])))
        elif op == "drop" and cur:
            del cur[draw(st.integers(0, len(cur) - 1))]
        elif op == "empty":
            cur.clear()
        elif op == "unknown":
            cur[draw(st.sampled_from(["extra", "Id", "units", "zz"]))] = draw(scalars(toml))
        done.append(f"{op} {'.'.join(map(str, path))}")
    return doc, done


def damage(draw, data: bytes) -> tuple[str, bytes]:
    """The file's bytes as written (half the time), cut short at a drawn length, or with 1–8
    drawn bits flipped: ``(what was done, bytes)``. ``draw`` is a Hypothesis draw function."""
    cut = draw(st.sampled_from(["none", "none", "truncate", "flip"]))
    if cut == "truncate" and data:
        data = data[: draw(st.integers(0, len(data) - 1))]
    elif cut == "flip" and data:
        b = bytearray(data)
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, len(b) - 1))
            b[i] ^= 1 << draw(st.integers(0, 7))
        data = bytes(b)
    return cut, data
