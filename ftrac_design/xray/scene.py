"""Where the simulator finds the fiducial's body: features.json, the design file, or the user.

``features.json`` (SPEC §2) does not have to carry the body. This module reads, in order,
an optional ``body`` key of features.json (our addition: ``{"outer_diameter", "length",
"bore_diameter", "material"}``, mm; readers that do not know it ignore it, SPEC §2), or the
``[body]`` table of the design file named in its ``design.source`` (as written, relative to
the working directory, to the features file's folder, or the shipped preset of that file
name, :mod:`ftrac_design.design.presets`: a source ``models/ftrac_2005.toml`` from another
machine's checkout finds the shipped ``ftrac_2005``).
"""

from __future__ import annotations

import json
import tomllib
from functools import lru_cache
from pathlib import Path

from ..design.presets import PRESETS_DIR
from ..errors import InputError
from .model import Body


def _candidates(source: str, near: Path | None) -> list[Path]:
    p = Path(source)
    out = [p]
    if not p.is_absolute():
        if near is not None:
            out.append(near / p)
    out.append(PRESETS_DIR / p.name)
    return out


@lru_cache(maxsize=32)
def _body_from_toml(path: str) -> Body | None:
    try:
        data = tomllib.loads(Path(path).read_text("utf-8"))
        return Body.from_dict(data["body"])
    except (OSError, KeyError, ValueError, TypeError, tomllib.TOMLDecodeError):
        return None


def body_from_source(source: str | None, near: Path | None = None) -> Body | None:
    """The ``[body]`` of the design file ``source`` (see module for where it is looked for), or None."""
    if not source:
        return None
    for p in _candidates(source, near):
        if p.is_file():
            b = _body_from_toml(str(p.resolve()))
            if b is not None:
                return b
    return None


def body_from_design_file(path: str | Path) -> Body:
    """The body of a design TOML (validated by the design loader); InputError if bad."""
    from ..design import load_design

    return Body.from_design(load_design(path))


def body_from_features_file(path: str | Path) -> Body | None:
    """The body for a features.json: its optional ``body`` key, else its design file, else None.

    InputError if the ``body`` key is present but malformed.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text("utf-8"))
    except (OSError, ValueError):
        return None  # load_features reports the file's own problems
    if isinstance(data, dict) and "body" in data:
        try:
            return Body.from_dict(data["body"])
        except (KeyError, ValueError, TypeError) as exc:
            raise InputError(
                path, "body", f"an object with outer_diameter > bore_diameter ≥ 0 and length > 0 (mm) ({exc})"
            ) from None
    source = (data.get("design") or {}).get("source") if isinstance(data, dict) else None
    return body_from_source(source, path.parent)
