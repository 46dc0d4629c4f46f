"""Read a design file and turn every problem into one :class:`InputError` line."""

from __future__ import annotations

import hashlib
import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..errors import InputError
from .presets import known_presets, resolve_design
from .schema import Design
from .validate import geometry_errors


def _loc(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


_EXPECT = {
    "float_type": "a number",
    "int_type": "an integer",
    "string_type": "a string",
    "list_type": "a list",
    "tuple_type": "a list of 3 numbers",
    "missing": "a value (the key is required)",
    "extra_forbidden": "no such key (unknown key; check its spelling)",
    "greater_than": "a value greater than {gt}",
    "greater_than_equal": "a value of at least {ge}",
    "less_than": "a value less than {lt}",
    "string_pattern_mismatch": "an identifier (letters, digits, _; starting with a letter)",
    "model_type": "a table",
    "too_short": "at least {min_length} items",
    "too_long": "at most {max_length} items",
    "finite_number": "a finite number",
    "bool_type": "true or false",
    "literal_error": "one of {expected}",
}


def describe_schema_error(err: dict[str, Any], with_input: bool = True) -> tuple[str, str]:
    """One error of the design schema's validation in words.

    Parameters
    ----------
    err : dict
        One item of pydantic's ``ValidationError.errors()``.
    with_input : bool
        Append ", got <value>" where the value is known (not for missing or unknown keys).

    Returns
    -------
    (key, expected) : tuple of str
        The dotted key (``"wires.diameter"``, ``"beads[2].z"``; "" for the whole file) and
        what was expected (``"a number, got 'x'"``).
    """
    key = _loc(err["loc"])
    template = _EXPECT.get(err["type"])
    if template:
        expected = template.format(**(err.get("ctx") or {}))
        if with_input and err["type"] not in ("missing", "extra_forbidden"):
            expected += f", got {err.get('input')!r}"
    else:
        expected = err["msg"].removeprefix("Value error, ")
    return key, expected


def parse_design(data: dict[str, Any], file: str | Path | None = None) -> Design:
    """Validate an already-parsed design mapping; raise :class:`InputError` on the first problem."""
    try:
        design = Design.model_validate(data)
    except ValidationError as exc:
        key, expected = describe_schema_error(exc.errors(include_url=False)[0])
        raise InputError(file, key or None, expected) from None
    problems = geometry_errors(design)
    if problems:
        key, expected = problems[0]
        raise InputError(file, key, expected)
    return design


def load_design(path: str | Path) -> Design:
    """Load and validate a design file (TOML), or a preset given by name.

    Parameters
    ----------
    path : str or pathlib.Path
        A design file, or a preset's name (``"ftrac_2005"``; see
        :func:`~ftrac_design.design.presets.resolve_design`).

    Returns
    -------
    Design
        The validated parameters; its ``source`` is the file read. Raises :class:`InputError`
        naming the file, the key and what was expected (a missing file: the preset names too).
    """
    path = resolve_design(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(path, None, f"file not found (nor a preset: {known_presets()})") from None
    except IsADirectoryError:
        raise InputError(path, None, "a design file, not a directory") from None
    except OSError as exc:
        raise InputError(path, None, f"a readable file ({exc.strerror})") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise InputError(path, None, "UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, None, f"valid TOML ({exc})") from None
    design = parse_design(data, path)
    design._source = str(path)
    design._sha256 = hashlib.sha256(raw).hexdigest()
    return design
