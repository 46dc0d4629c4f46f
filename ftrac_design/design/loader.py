"""Read a design file and turn every problem into one :class:`InputError` line."""

from __future__ import annotations

import hashlib
import tomllib
from pathlib import Path
from typing import Any

from pydantic import TypeAdapter, ValidationError

from ..errors import InputError
from .presets import PRESETS_DIR, known_presets, resolve_design
from .schema import Body, Design
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
    # a dataclass's (the body's) words for the same
    "unexpected_keyword_argument": "no such key (unknown key; check its spelling)",
    "greater_than": "a value greater than {gt}",
    "greater_than_equal": "a value of at least {ge}",
    "less_than": "a value less than {lt}",
    "string_pattern_mismatch": "an identifier (letters, digits, _; starting with a letter)",
    "model_type": "a table",
    "dataclass_type": "a table",
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
        if with_input and err["type"] not in ("missing", "extra_forbidden", "unexpected_keyword_argument"):
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


def parse_body(data: Any, file: str | Path | None, key: str = "body") -> Body:
    """Validate a body table (a design file's ``[body]``, features.json's ``body``).

    Parameters
    ----------
    data : the parsed table (a mapping of ``outer_diameter``, ``length``, ``bore_diameter`` in mm
        and ``material``).
    file : the file it came from, named in errors.
    key : where the table sits in that file.

    Returns
    -------
    Body. Raises :class:`InputError` naming the file, ``key.<field>`` and what was expected.
    """
    try:
        return TypeAdapter(Body).validate_python(data)
    except ValidationError as exc:
        sub, expected = describe_schema_error(exc.errors(include_url=False)[0])
        raise InputError(file, f"{key}.{sub}" if sub else key, expected) from None


def design_file_named(source: str, near: Path | None = None) -> Path | None:
    """The design file a features file's ``design.source`` names, where it can be found: as
    written (relative to the working directory), relative to ``near`` (the features file's
    folder), or the shipped preset of that file name (a source ``models/ftrac_2005.toml`` from
    another machine's checkout finds the shipped ``ftrac_2005``).

    Parameters
    ----------
    source : the path as the features file gives it.
    near : the folder a relative path is also looked for in, or None.

    Returns
    -------
    pathlib.Path of the first file found, or None when there is none.
    """
    p = Path(source)
    candidates = [p]
    if not p.is_absolute() and near is not None:
        candidates.append(near / p)
    candidates.append(PRESETS_DIR / p.name)
    return next((c for c in candidates if c.is_file()), None)


def design_body(path: str | Path) -> Body:
    """The ``[body]`` table of the design file ``path`` (the rest of the file is not validated).

    Parameters
    ----------
    path : a design file (TOML).

    Returns
    -------
    Body. Raises :class:`InputError` naming the file when it cannot be read, is not TOML or has
    no valid ``[body]``.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text("utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, None, f"a readable UTF-8 design file ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, None, f"valid TOML ({exc})") from None
    if "body" not in data:
        raise InputError(path, "body", "a [body] table (the key is required)")
    return parse_body(data["body"], path)
