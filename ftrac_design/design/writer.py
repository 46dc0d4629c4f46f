"""Design data as TOML in the design files' own layout.

:func:`to_toml` writes a design mapping (as :func:`~.loader.parse_design` takes it) with
``[table]``s, ``[[ellipses]]`` arrays of tables and one-line arrays, the layout of the preset
design files, which a generic writer such as tomli-w does not keep; :func:`round_values` rounds
its floats to 1e-4 (0.1 µm, 0.0001°) for files people read.
"""

from __future__ import annotations

import json


def round_values(v):
    """``v`` with every float (in lists and dicts too) rounded to 4 decimals (−0.0 made 0.0)."""
    if isinstance(v, float):
        return round(v, 4) + 0.0
    if isinstance(v, list):
        return [round_values(x) for x in v]
    if isinstance(v, dict):
        return {k: round_values(x) for k, x in v.items()}
    return v


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def _toml_table(data: dict, path: str, out: list[str]) -> None:
    scalars = {
        k: v
        for k, v in data.items()
        if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))
    }
    if path and (scalars or not data):
        out.append(f"\n[{path}]")
    out += [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    for k, v in data.items():
        sub = f"{path}.{k}" if path else k
        if isinstance(v, dict):
            _toml_table(v, sub, out)
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                out.append(f"\n[[{sub}]]")
                out += [f"{kk} = {_toml_value(vv)}" for kk, vv in item.items()]


def to_toml(data: dict) -> str:
    """Design data as TOML in the design files' own layout (``[table]``s, ``[[ellipses]]``,
    one-line arrays), which a generic writer such as tomli-w does not keep."""
    out: list[str] = []
    _toml_table(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"
