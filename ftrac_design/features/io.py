"""``features.json`` (SPEC §2): write from :class:`Features`, read back with validation.

Readers ignore keys they do not know (SPEC §2); anything malformed raises
:class:`~ftrac_design.errors.InputError` naming the file, the key and what was expected.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..design.loader import design_body, design_file_named, parse_body
from ..design.schema import Body
from ..errors import InputError
from ..fileio import write_json_atomic
from .model import EllipseFeature, Features, LineFeature, PointFeature

FORMAT = "ftrac-features"
VERSION = 1

#: tolerance on |axis| = 1 and major·minor = 0 when reading (files carry 17 digits)
_ORTHO_TOL = 1e-6
#: largest |coordinate| or size accepted, mm: a fiducial is centimetres across and its
#: frames reach across an operating table; 1e300 would overflow every product downstream
LIMIT_MM = 1e4
#: smallest semi-axis or line length accepted, mm (a feature below a micron is no feature)
MIN_SIZE_MM = 1e-3


def _vec(v: np.ndarray) -> list[float]:
    return [float(x) for x in v]


def features_to_dict(f: Features) -> dict[str, Any]:
    """The SPEC §2 JSON object for ``f``."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "units": "mm",
        "design": {"name": f.name, "source": f.source, "sha256": f.sha256},
        "nominal_beam_direction": _vec(f.nominal_beam_direction),
        "points": [
            {"id": p.id, "center": _vec(p.center), "diameter": p.diameter, **({"line": p.line} if p.line else {})}
            for p in f.points
        ],
        "lines": [
            {"id": ln.id, "start": _vec(ln.start), "end": _vec(ln.end), "wire_diameter": ln.wire_diameter}
            for ln in f.lines
        ],
        "ellipses": [
            {
                "id": e.id,
                "center": _vec(e.center),
                "major_axis": _vec(e.major_axis),
                "minor_axis": _vec(e.minor_axis),
                "semi_major": e.semi_major,
                "semi_minor": e.semi_minor,
                "wire_diameter": e.wire_diameter,
            }
            for e in f.ellipses
        ],
        "frames": {k: [_vec(row) for row in T] for k, T in f.frames.items()},
    }


def write_features(path: str | Path, f: Features) -> Path:
    """Write ``features.json`` atomically."""
    return write_json_atomic(path, features_to_dict(f))


class _Reader:
    """Typed access to a parsed JSON object that reports the failing key path."""

    def __init__(self, file: str | Path | None):
        self.file = file

    def fail(self, key: str, expected: str) -> InputError:
        return InputError(self.file, key, expected)

    def get(self, obj: dict, key: str, where: str, default: Any = ...) -> Any:
        if not isinstance(obj, dict):
            raise self.fail(where or "(top level)", "a JSON object")
        if key not in obj:
            if default is not ...:
                return default
            raise self.fail(f"{where}.{key}" if where else key, "a value (the key is required)")
        return obj[key]

    def number(self, v: Any, key: str, positive: bool = False, minimum: float | None = None) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.fail(key, f"a finite number, got {v!r}")
        if positive and not v > 0:
            raise self.fail(key, f"a positive number, got {v!r}")
        if abs(v) > LIMIT_MM:
            raise self.fail(key, f"a number within ±{LIMIT_MM:g} (mm), got {v!r}")
        if minimum is not None and not v >= minimum:
            raise self.fail(key, f"a value of at least {minimum:g} (mm), got {v!r}")
        return float(v)

    def vector(self, v: Any, key: str, n: int = 3) -> np.ndarray:
        if not isinstance(v, list) or len(v) != n:
            raise self.fail(key, f"a list of {n} numbers, got {v!r}")
        return np.array([self.number(x, f"{key}[{i}]") for i, x in enumerate(v)])

    def string(self, v: Any, key: str) -> str:
        if not isinstance(v, str) or not v:
            raise self.fail(key, f"a non-empty string, got {v!r}")
        return v

    def items(self, obj: dict, key: str) -> list:
        v = self.get(obj, key, "", [])
        if not isinstance(v, list):
            raise self.fail(key, "a list")
        return v


def _header(r: _Reader, d: Any) -> tuple[dict, np.ndarray]:
    """The format, version and units checked; the ``design`` block and the unit beam direction."""
    if not isinstance(d, dict):
        raise r.fail("(top level)", "a JSON object")
    if r.get(d, "format", "") != FORMAT:
        raise r.fail("format", f'"{FORMAT}"')
    version = r.get(d, "version", "")
    if version != VERSION:
        raise r.fail("version", f"{VERSION} (this reader's format version), got {version!r}")
    units = r.get(d, "units", "", "mm")
    if units != "mm":
        raise r.fail("units", f'"mm", got {units!r}')
    design = r.get(d, "design", "", {})
    if not isinstance(design, dict):
        raise r.fail("design", "a JSON object")
    for key in ("name", "source", "sha256"):
        if design.get(key) is not None and not isinstance(design[key], str):
            raise r.fail(f"design.{key}", f"a string, got {design[key]!r}")
    beam = r.vector(r.get(d, "nominal_beam_direction", ""), "nominal_beam_direction")
    if np.linalg.norm(beam) < 1e-9:
        raise r.fail("nominal_beam_direction", "a non-zero vector")
    return design, beam / np.linalg.norm(beam)


def _new_id(r: _Reader, ids: set[str], obj: dict, where: str) -> str:
    """A feature's id, checked to be a non-empty string used once in the file (added to ``ids``)."""
    ident = r.string(r.get(obj, "id", where), f"{where}.id")
    if ident in ids:
        raise r.fail(f"{where}.id", f'a unique id ("{ident}" is used twice)')
    ids.add(ident)
    return ident


def _entries(r: _Reader, d: dict, key: str, ids: set[str]) -> Iterator[tuple[dict, str, str]]:
    """Each object of the list ``key``: the object, where it is (``lines[3]``) and its id,
    checked unique (:func:`_new_id`)."""
    for i, o in enumerate(r.items(d, key)):
        w = f"{key}[{i}]"
        yield o, w, _new_id(r, ids, o, w)


def _field_vector(r: _Reader, o: dict, key: str, where: str) -> np.ndarray:
    """The 3-vector ``key`` of the object at ``where`` (required)."""
    return r.vector(r.get(o, key, where), f"{where}.{key}")


def _wire_diameter(r: _Reader, o: dict, where: str) -> float:
    """A line's or an ellipse's ``wire_diameter``, mm (0 when not given)."""
    return r.number(r.get(o, "wire_diameter", where, 0.0), f"{where}.wire_diameter", minimum=0.0)


def _lines(r: _Reader, d: dict, ids: set[str]) -> list[LineFeature]:
    lines = []
    for o, w, ident in _entries(r, d, "lines", ids):
        s = _field_vector(r, o, "start", w)
        e = _field_vector(r, o, "end", w)
        if np.linalg.norm(e - s) < MIN_SIZE_MM:
            raise r.fail(f"{w}.end", f"an end-point at least {MIN_SIZE_MM:g} mm from start")
        lines.append(LineFeature(ident, s, e, _wire_diameter(r, o, w)))
    return lines


def _points(r: _Reader, d: dict, ids: set[str], line_ids: set[str]) -> list[PointFeature]:
    points = []
    for o, w, ident in _entries(r, d, "points", ids):
        line = r.get(o, "line", w, None)
        if line is not None and (not isinstance(line, str) or line not in line_ids):
            raise r.fail(f"{w}.line", f"the id of a line in this file, got {line!r}")
        points.append(
            PointFeature(
                ident,
                _field_vector(r, o, "center", w),
                r.number(r.get(o, "diameter", w, 0.0), f"{w}.diameter", minimum=0.0),
                line,
            )
        )
    return points


def _ellipses(r: _Reader, d: dict, ids: set[str]) -> list[EllipseFeature]:
    ellipses = []
    for o, w, ident in _entries(r, d, "ellipses", ids):
        c = _field_vector(r, o, "center", w)
        u = _field_vector(r, o, "major_axis", w)
        v = _field_vector(r, o, "minor_axis", w)
        for key, ax in (("major_axis", u), ("minor_axis", v)):
            if abs(np.linalg.norm(ax) - 1.0) > _ORTHO_TOL:
                raise r.fail(f"{w}.{key}", f"a unit vector, |{key}| = {np.linalg.norm(ax):.9g}")
        if abs(float(u @ v)) > _ORTHO_TOL:
            raise r.fail(f"{w}.minor_axis", f"a vector orthogonal to major_axis (dot = {float(u @ v):.3g})")
        a = r.number(r.get(o, "semi_major", w), f"{w}.semi_major", minimum=MIN_SIZE_MM)
        b = r.number(r.get(o, "semi_minor", w), f"{w}.semi_minor", minimum=MIN_SIZE_MM)
        if b > a * (1 + 1e-12):
            raise r.fail(f"{w}.semi_minor", f"a value not above semi_major ({a}), got {b}")
        ellipses.append(EllipseFeature(ident, c, u, v, a, b, _wire_diameter(r, o, w)))
    return ellipses


def _frames(r: _Reader, d: dict) -> dict[str, np.ndarray]:
    frames = {}
    fr = r.get(d, "frames", "", {})
    if not isinstance(fr, dict):
        raise r.fail("frames", "a JSON object of 4x4 matrices")
    for k, m in fr.items():
        if not (isinstance(m, list) and len(m) == 4):
            raise r.fail(f"frames.{k}", "a 4x4 matrix (list of 4 rows)")
        frames[k] = np.array([r.vector(row, f"frames.{k}[{i}]", 4) for i, row in enumerate(m)])
    return frames


def body_of(d: dict, file: str | Path | None = None) -> Body | None:
    """The body a parsed ``features.json`` names: its ``body`` key (our extension: the
    design's ``[body]`` table as an object), else the ``[body]`` of the design file its
    ``design.source`` names (:func:`~ftrac_design.design.design_file_named`: as written,
    beside ``file``, or the shipped preset of that file name).

    Parameters
    ----------
    d : the parsed JSON object.
    file : the features file (its folder is where a relative source is also looked for).

    Returns
    -------
    Body, or None when the file has no ``body`` key and names no design file that can be found.
    A ``body`` key that is not a valid body, or a design file found whose ``[body]`` cannot be
    read, is bad input: :class:`InputError` naming ``file``, the key and what was expected.
    """
    if "body" in d:
        return parse_body(d["body"], file)
    source = (d.get("design") or {}).get("source")
    if not source:
        return None
    near = Path(file).parent if file is not None else None
    path = design_file_named(source, near)
    if path is None:
        return None
    try:
        return design_body(path)
    except InputError as exc:
        raise InputError(file, "design.source", f"a design file whose [body] can be read ({exc})") from None


def features_from_dict(d: Any, file: str | Path | None = None) -> Features:
    """Validate a parsed ``features.json`` object and build :class:`Features`, its body
    included (:func:`body_of`)."""
    r = _Reader(file)
    design, beam = _header(r, d)
    ids: set[str] = set()
    lines = _lines(r, d, ids)
    points = _points(r, d, ids, {ln.id for ln in lines})
    ellipses = _ellipses(r, d, ids)
    frames = _frames(r, d)
    if not (points or lines or ellipses):
        raise r.fail("points", "at least one point, line or ellipse")
    return Features(
        name=str(design.get("name") or "unnamed"),
        source=design.get("source"),
        sha256=design.get("sha256"),
        nominal_beam_direction=beam,
        points=tuple(points),
        lines=tuple(lines),
        ellipses=tuple(ellipses),
        frames=frames,
        body=body_of(d, file),
    )


def load_features(path: str | Path) -> Features:
    """Read and validate ``features.json``, its body included (:func:`body_of`); bad input raises
    :class:`InputError`."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, None, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, None, f"a readable UTF-8 file ({exc})") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(path, None, f"valid JSON ({exc.msg} at line {exc.lineno})") from None
    return features_from_dict(d, path)
