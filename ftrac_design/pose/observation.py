"""``observation.json`` (SPEC §3): what was segmented in one image.

Parsing validates everything a solver relies on and raises
:class:`~ftrac_design.errors.InputError` naming the file (and line, for JSON Lines), the
key and what was expected. Keys are feature ids; checking them against ``features.json``
is the solver's job (:func:`ftrac_design.pose.problem.compile_problem`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..errors import InputError
from ..fileio import json_lines, parse_json, read_text_input
from .camera import Camera

FORMAT = "ftrac-observation"
VERSION = 1

#: largest |pixel coordinate| accepted (points, contours, principal point, curve positions).
#: Detectors are ~10^3–10^4 px across; a coordinate beyond this is a unit or export error,
#: and squaring it (conic fits use u⁴) would overflow double precision long before 1e300.
PIXEL_LIMIT = 1e6
#: accepted focal length in pixels, f / s (a C-arm has ~2,000–5,000)
FOCAL_PX_RANGE = (1.0, 1e8)


@dataclass
class CurveObservation:
    """A segmented line or ellipse: contour ``points`` (n, 2) px, or fitted coefficients
    (line ``A u + B v + C = 0``; conic ``A u² + B uv + C v² + D u + E v + F = 0``)."""

    points: np.ndarray | None = None
    coefficients: np.ndarray | None = None


@dataclass
class Observation:
    """One image: its camera and the features found in it, keyed by feature id."""

    camera: Camera
    points: dict[str, np.ndarray] = field(default_factory=dict)
    lines: dict[str, CurveObservation] = field(default_factory=dict)
    ellipses: dict[str, CurveObservation] = field(default_factory=dict)
    #: where it came from, for error messages: "obs.json" or "batch.jsonl:17"
    origin: str = "<observation>"

    def to_dict(self) -> dict[str, Any]:
        """The SPEC §3 JSON object."""

        def curve(c: CurveObservation, coef_key: str) -> dict[str, Any]:
            if c.points is not None:
                return {"points": np.asarray(c.points).tolist()}
            return {coef_key: np.asarray(c.coefficients).tolist()}

        return {
            "format": FORMAT,
            "version": VERSION,
            "camera": self.camera.to_dict(),
            "points": {k: [float(v[0]), float(v[1])] for k, v in self.points.items()},
            "lines": {k: curve(c, "coefficients") for k, c in self.lines.items()},
            "ellipses": {k: curve(c, "conic") for k, c in self.ellipses.items()},
        }

    @property
    def structure(self) -> tuple:
        """What was observed and how — observations with equal structure solve as one batch."""

        def kind(c: CurveObservation) -> str:
            return "p" if c.points is not None else "c"

        return (
            tuple(sorted(self.points)),
            tuple(sorted((k, kind(c)) for k, c in self.lines.items())),
            tuple(sorted((k, kind(c)) for k, c in self.ellipses.items())),
        )


def _num(v: Any, origin: str, key: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(origin, key, f"a number, got {v!r}")
    if not math.isfinite(v):
        raise InputError(origin, key, f"a finite number, got {v!r}")
    return float(v)


def _vec(v: Any, n: int, origin: str, key: str) -> np.ndarray:
    if not isinstance(v, list) or len(v) != n:
        raise InputError(origin, key, f"a list of {n} numbers, got {_short(v)}")
    return np.array([_num(x, origin, f"{key}[{i}]") for i, x in enumerate(v)])


def _pixel(v: Any, origin: str, key: str) -> np.ndarray:
    """A [u, v] pixel position within ±PIXEL_LIMIT."""
    uv = _vec(v, 2, origin, key)
    if np.abs(uv).max() > PIXEL_LIMIT:
        raise InputError(origin, key, f"pixel coordinates within ±{PIXEL_LIMIT:.0e} px, got {_short(v)}")
    return uv


def _scaled(c: np.ndarray, origin: str, key: str) -> np.ndarray:
    """Homogeneous coefficients scaled to max |c| = 1 (the same curve; no overflow later)."""
    m = np.abs(c).max()
    if not m > 0:
        raise InputError(origin, key, "coefficients that are not all zero")
    return c / m


def _short(v: Any) -> str:
    s = json.dumps(v) if not isinstance(v, float) else repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def _pts(v: Any, origin: str, key: str, minimum: int) -> np.ndarray:
    if not isinstance(v, list):
        raise InputError(origin, key, f"a list of [u, v] pixel pairs, got {_short(v)}")
    if len(v) < minimum:
        raise InputError(origin, key, f"at least {minimum} contour points to fit, got {len(v)}")
    return np.array([_pixel(p, origin, f"{key}[{i}]") for i, p in enumerate(v)])


def _curve(v: Any, origin: str, key: str, coef_key: str, ncoef: int, minimum: int) -> CurveObservation:
    if not isinstance(v, dict):
        raise InputError(origin, key, f'an object with "points" or "{coef_key}"')
    has_p, has_c = "points" in v, coef_key in v
    if has_p == has_c:
        raise InputError(origin, key, f'exactly one of "points" or "{coef_key}"')
    if has_p:
        pts = _pts(v["points"], origin, f"{key}.points", minimum)
        spread = np.ptp(pts, axis=0).max() if len(pts) else 0.0
        if spread <= 0:
            raise InputError(origin, f"{key}.points", "contour points that are not all the same pixel")
        return CurveObservation(points=pts)
    where = f"{key}.{coef_key}"
    c = _scaled(_vec(v[coef_key], ncoef, origin, where), origin, where)
    if coef_key == "coefficients":
        # |C| / |(A, B)| is the line's distance from pixel (0, 0); scaled, |(A, B)| ≤ 1e-12
        # means a line beyond 1e12 px or no line at all
        ab = math.hypot(c[0], c[1])
        if not ab > 1e-12 or abs(c[2]) / ab > 2 * PIXEL_LIMIT:
            raise InputError(
                origin, where, f"a line (A, B not both zero) passing within {2 * PIXEL_LIMIT:.0e} px of pixel (0, 0)"
            )
        c = c / ab
    if coef_key == "conic":
        _check_ellipse(c, origin, where)
    return CurveObservation(coefficients=c)


def _check_ellipse(c: np.ndarray, origin: str, key: str) -> None:
    """A real, non-degenerate ellipse whose centre and size are pixel-sized (c scaled)."""
    A, B, C, D, E, F = c
    det2 = 4 * A * C - B * B
    if not det2 > 0:
        raise InputError(origin, key, "the coefficients of an ellipse (4AC − B² > 0)")
    # centre: the gradient vanishes; value there F0; real points iff F0 has A's opposite sign
    u0 = (B * E - 2 * C * D) / det2
    v0 = (B * D - 2 * A * E) / det2
    F0 = F + (D * u0 + E * v0) / 2
    if not (F0 * A < 0):
        raise InputError(origin, key, "the coefficients of an ellipse with real points (it is empty or one point)")
    ev = np.linalg.eigvalsh(np.array([[A, B / 2], [B / 2, C]]))
    semi = np.sqrt(-F0 / ev) if A > 0 else np.sqrt(F0 / -ev)
    if max(abs(u0), abs(v0), semi.max()) > PIXEL_LIMIT or not semi.min() > 0:
        raise InputError(
            origin,
            key,
            f"an ellipse within ±{PIXEL_LIMIT:.0e} px (centre ({u0:.3g}, {v0:.3g}), "
            f"semi-axes {semi.max():.3g}, {semi.min():.3g} px)",
        )


def camera_from_dict(cam: Any, origin: str | Path, key: str = "camera") -> Camera:
    """Validate a SPEC §3 ``camera`` object (the one parser of it: observations, ``--camera``
    files, pose and point lines). ``key`` names it in errors."""
    origin = str(origin)
    if not isinstance(cam, dict):
        raise InputError(origin, key, "an object with focal_length_mm, pixel_size_mm, principal_point_px")
    for k in ("focal_length_mm", "pixel_size_mm", "principal_point_px"):
        if k not in cam:
            raise InputError(origin, f"{key}.{k}", "a value (the key is required)")
    f = _num(cam["focal_length_mm"], origin, f"{key}.focal_length_mm")
    px = _vec(cam["pixel_size_mm"], 2, origin, f"{key}.pixel_size_mm")
    pp = _pixel(cam["principal_point_px"], origin, f"{key}.principal_point_px")
    if f <= 0:
        raise InputError(origin, f"{key}.focal_length_mm", f"a positive number, got {f}")
    if px.min() <= 0:
        raise InputError(origin, f"{key}.pixel_size_mm", f"positive numbers, got {px.tolist()}")
    lo, hi = FOCAL_PX_RANGE
    if not lo <= f / px.max() <= f / px.min() <= hi:
        raise InputError(
            origin,
            key,
            f"focal_length_mm / pixel_size_mm (the focal length in pixels) "
            f"between {lo:g} and {hi:g}, got {f / px.max():.3g}–{f / px.min():.3g}",
        )
    return Camera(f, (float(px[0]), float(px[1])), (float(pp[0]), float(pp[1])))


def read_camera(path: str | Path) -> Camera:
    """``--camera C.json``: a SPEC §3 camera object, bare or under ``"camera"`` (an
    observation.json or truth.json holding one)."""
    d = parse_json(read_text_input(path), path)
    if isinstance(d, dict) and "camera" in d:
        return camera_from_dict(d["camera"], path)
    return camera_from_dict(d, path)


def observation_from_dict(d: Any, origin: str = "<observation>") -> Observation:
    """Validate a parsed SPEC §3 object. ``origin`` names the file (and line) in errors."""
    if not isinstance(d, dict):
        raise InputError(origin, None, "a JSON object (an ftrac-observation)")
    fmt = d.get("format", FORMAT)
    if fmt != FORMAT:
        raise InputError(origin, "format", f'"{FORMAT}", got {_short(fmt)}')
    ver = d.get("version", VERSION)
    if ver != VERSION:
        raise InputError(origin, "version", f"{VERSION}, got {_short(ver)}")
    camera = camera_from_dict(d.get("camera"), origin)

    def section(name: str) -> dict:
        v = d.get(name, {})
        if not isinstance(v, dict):
            raise InputError(origin, name, "an object keyed by feature id")
        return v

    points = {k: _pixel(v, origin, f"points.{k}") for k, v in section("points").items()}
    lines = {k: _curve(v, origin, f"lines.{k}", "coefficients", 3, 2) for k, v in section("lines").items()}
    ellipses = {k: _curve(v, origin, f"ellipses.{k}", "conic", 6, 5) for k, v in section("ellipses").items()}
    for sec, keys, earlier in (("lines", lines, set(points)), ("ellipses", ellipses, set(points) | set(lines))):
        dup = sorted(set(keys) & earlier)
        if dup:
            raise InputError(origin, f"{sec}.{dup[0]}", "an id used in only one of points, lines, ellipses")
    if not (points or lines or ellipses):
        raise InputError(origin, "points", "at least one observed point, line or ellipse")
    return Observation(camera, points, lines, ellipses, origin)


def read_observations(path: str | Path) -> Iterator[Observation]:
    """Observations from a ``.json`` file (one) or ``.jsonl`` file (one per non-blank line)."""
    path = Path(path)
    text = read_text_input(path)
    if path.suffix.lower() == ".jsonl":
        found = False
        for origin, d in json_lines(path, text):
            found = True
            yield observation_from_dict(d, origin)
        if not found:
            raise InputError(path, None, "at least one observation (the file is empty)")
    else:
        yield observation_from_dict(parse_json(text, path), str(path))
