"""The image path's settings are decided once, in :class:`~ftrac_design.segment.TrackOptions`,
and each stage takes only the small record of those it reads: every field of ``TrackOptions``
belongs to a stage's record, each record carries ``TrackOptions``' values, and the fields a
record holds are exactly those that the code of ``segment`` and ``tracking`` reads from it
(a new setting must be given to the stage that reads it, and a stage reads no setting it
was not given)."""

from __future__ import annotations

import ast
import re
from dataclasses import fields, is_dataclass, replace
from pathlib import Path

from ftrac_design.segment import options
from ftrac_design.segment.options import TrackOptions

ROOT = Path(__file__).resolve().parents[1] / "ftrac_design"
#: the stages' records, as ``TrackOptions`` hands them out
STAGES = {"finding": options.FindOptions, "search": options.SearchOptions}
STAGES |= {"labelling": options.LabellingOptions, "acceptance": options.AcceptanceOptions}
#: the records inside a record
NESTED = {"contour": options.ContourOptions, "noise": options.NoiseOptions}
RECORDS = {cls.__name__: cls for cls in [*STAGES.values(), *NESTED.values()]}


def _settings(cls) -> set[str]:
    """A record's own settings (the records it holds left out)."""
    return {f.name for f in fields(cls)} - set(NESTED)


def _records_of(opts: TrackOptions) -> list:
    out = [getattr(opts, name) for name in STAGES]
    return out + [getattr(opts.labelling, name) for name in NESTED]


def test_every_setting_belongs_to_a_stage_and_carries_its_value():
    everything = {f.name for f in fields(TrackOptions)}
    held = set().union(*(_settings(cls) for cls in RECORDS.values()))
    assert held == everything, (everything - held, held - everything)
    # every setting changed at once: each record carries the changed value
    changed = replace(
        TrackOptions(),
        **{
            f.name: (not f.default) if isinstance(f.default, bool) else f.default * 2
            for f in fields(TrackOptions)
            if isinstance(f.default, (int, float, tuple))
        },
    )
    for record in _records_of(changed):
        for name in _settings(type(record)):
            assert getattr(record, name) == getattr(changed, name), (type(record).__name__, name)
    assert all(not is_dataclass(f.default) for f in fields(TrackOptions))


def _typed(expr: ast.AST, env: dict[str, str]) -> str | None:
    """The options class (by name) an expression holds, where it can be told."""
    if isinstance(expr, ast.Name):
        return env.get(expr.id)
    if isinstance(expr, ast.Attribute):
        owner = _typed(expr.value, env)
        if owner == "TrackOptions" and expr.attr in STAGES:
            return STAGES[expr.attr].__name__
        if owner == "LabellingOptions" and expr.attr in NESTED:
            return NESTED[expr.attr].__name__
    if isinstance(expr, ast.Call) and ast.unparse(expr.func) == "replace" and expr.args:
        return _typed(expr.args[0], env)
    if isinstance(expr, ast.BoolOp):
        return next((t for t in (_typed(v, env) for v in expr.values) if t), None)
    return None


def _reads() -> dict[str, set[str]]:
    """Per options class, the attributes the code of ``segment`` and ``tracking`` reads from it
    (parameters by their annotation; locals by what they are assigned)."""
    names = [*RECORDS, "TrackOptions"]
    out: dict[str, set[str]] = {n: set() for n in names}
    for path in [*(ROOT / "segment").glob("*.py"), *(ROOT / "tracking").glob("*.py")]:
        if path.name == "options.py":
            continue
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            env = {}
            for a in [*fn.args.posonlyargs, *fn.args.args, *fn.args.kwonlyargs]:
                ann = ast.unparse(a.annotation) if a.annotation is not None else ""
                env |= {a.arg: n for n in names if re.search(rf"\b{n}\b", ann)}
            for node in ast.walk(fn):
                if isinstance(node, ast.Assign) and len(node.targets) == 1:
                    t, v = node.targets[0], node.value
                    pairs = zip(t.elts, v.elts) if isinstance(t, ast.Tuple) and isinstance(v, ast.Tuple) else [(t, v)]
                    for target, value in pairs:
                        kind = _typed(value, env)
                        if isinstance(target, ast.Name) and kind:
                            env[target.id] = kind
            for node in ast.walk(fn):
                if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
                    kind = _typed(node.value, env)
                    if kind:
                        out[kind].add(node.attr)
    return out


def test_each_stage_record_holds_exactly_what_its_stage_reads():
    reads = _reads()
    for name, cls in RECORDS.items():
        held = {f.name for f in fields(cls)}
        assert reads[name] == held, (name, "not read:", held - reads[name], "read, not held:", reads[name] - held)
    # the whole is only split into its stages' records where the user's settings come in
    assert reads["TrackOptions"] <= set(STAGES), reads["TrackOptions"] - set(STAGES)
