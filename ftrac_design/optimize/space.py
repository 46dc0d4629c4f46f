"""The search space of ``ftrac-design optimize``: which design parameters vary, within what.

A space maps a point ``x`` of the unit cube ``[0, 1]ⁿ`` (what the optimisers see) to a
candidate design: the start design's TOML data with some values replaced. Keys name a
design value by feature id (lengths mm, angles degrees as in the design file):

- ``ellipses.<id>.tilt_deg`` / ``.tilt_azimuth_deg`` / ``.z_center`` — as in the design file
- ``lines.<id>.azimuth_deg`` / ``.z_start`` / ``.z_end`` — as in the design file
- ``lines.<id>.beads`` — the line's movable beads as ordered fractions (below)
- ``body.outer_diameter`` / ``.length`` / ``.bore_diameter`` — absolute, feature positions
  unchanged
- ``body.scale`` — the body and every axial position × this factor (bought parts and seating
  unchanged; axial parameters are then in the start design's mm and scaled too)
- ``wire.diameter`` / ``bead.diameter`` — ``{choices = [...]}``: stock sizes (seating keeps the
  start's cover)

When the body's diameter varies (``body.scale``, ``body.outer_diameter``) the mount block
grows with it (its width follows the socket and the hole pattern that must clear it), and
the connector's ``axis_height`` follows the mount: it rises by half of the block's growth,
so the mount keeps the start design's clearance above the template's top edge
(``connector.template_clearance``) instead of running into the template at a size where
the mount's hole pattern steps up.

A stock size other than the start's is read from the image with another precision: a
smaller ball's shadow has less contrast and less edge. The candidate's ``[analysis]``
``bead_error_factor`` / ``wire_error_factor`` are set to the start's times the ratio of the
pixel-level Cramér–Rao σ of the new size to the start's
(:func:`ftrac_design.xray.localization.size_error_factors`, at the design's nominal depth,
default camera and imaging), so a smaller part is charged for its noisier image and not
only credited with the room it frees; ``analyze`` of the written design uses the same.

Bead positions are *ordered fractions* so that the schema rarely refuses a candidate: the
n beads of a line sit at ``z_i = z_start + i·g + s_i·(z_end − z_start − (n−1)·g)`` with g
one bead diameter (plus 1 µm) and ``s`` sorted, so beads never swap or overlap and stay on
the line however its ends move; a bead that sits on an end of its line in the start design
stays pinned there (s = 0 or 1). Each movable bead is one parameter (``lines.L1.beads[0]``
…) with the table's bounds (within [0, 1]). A line whose extent varies keeps its beads'
start fractions when ``lines.<id>.beads`` is not in the space.

A space file (``--space SPACE.toml``) is::

    [parameters]
    "ellipses.E1.tilt_deg" = [15.0, 45.0]      # [low, high]
    "lines.L1.beads" = [0.0, 1.0]
    "wire.diameter" = {choices = [0.25, 0.3, 0.4]}

    [search]                                   # optional; the command line wins
    poses = 2000                               # fixed (seeded) workspace sample of the search
    sigma0 = 0.1                               # CMA-ES step size in the unit cube
    popsize = 12                               # CMA-ES λ / NSGA-II population
    verify_poses = 20000                       # fresh poses that re-score the winner
    solver_images = 1000                       # Monte-Carlo images solved for start and winner
    check_images = 200                         # rendered radiographs of both tracked end to end

Without ``--space`` :func:`default_space` varies the layout within the body's envelope
(see there); ``ftrac-design optimize DESIGN --print-space`` prints it as a file to edit.
Bad spaces raise :class:`~ftrac_design.errors.InputError` naming the file and the key.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from ..design.presets import known_spaces, resolve_space
from ..design.schema import Analysis, Design
from ..errors import InputError

#: axial keys that body.scale multiplies
_AXIAL = {"ellipses": ("z_center",), "lines": ("z_start", "z_end")}
_ELLIPSE_KEYS = ("tilt_deg", "tilt_azimuth_deg", "z_center")
_LINE_KEYS = ("azimuth_deg", "z_start", "z_end")
_BODY_KEYS = ("outer_diameter", "length", "bore_diameter", "scale")
_STOCK_KEYS = ("wire.diameter", "bead.diameter")
#: extra spacing between neighbouring beads beyond one diameter (the schema wants "more than")
BEAD_GAP_MM = 1e-3
SEARCH_KEYS = {
    "poses": int,
    "sigma0": float,
    "popsize": int,
    "verify_poses": int,
    "solver_images": int,
    "check_images": int,
}
KNOWN = (
    "ellipses.<id>.tilt_deg|tilt_azimuth_deg|z_center, lines.<id>.azimuth_deg|z_start|z_end|beads, "
    "body.outer_diameter|length|bore_diameter|scale, wire.diameter, bead.diameter"
)


@dataclass(frozen=True)
class Parameter:
    """One coordinate of the unit cube: a design value between ``low`` and ``high`` (its
    file units), or one of ``choices`` (stock sizes)."""

    key: str
    low: float
    high: float
    start: float
    choices: tuple[float, ...] | None = None

    def value(self, u: float) -> float:
        """The design value at unit coordinate ``u`` ∈ [0, 1]."""
        u = min(max(float(u), 0.0), 1.0)
        if self.choices is not None:
            return self.choices[min(int(u * len(self.choices)), len(self.choices) - 1)]
        return self.low + u * (self.high - self.low)

    def unit(self, v: float) -> float:
        """The unit coordinate of design value ``v`` (clipped into the bounds)."""
        if self.choices is not None:
            k = int(np.argmin([abs(c - v) for c in self.choices]))
            return (k + 0.5) / len(self.choices)
        return min(max((v - self.low) / (self.high - self.low), 0.0), 1.0)


@dataclass(frozen=True)
class SearchSpace:
    """The start design's data and the parameters that vary (see the module doc)."""

    base: dict
    parameters: tuple[Parameter, ...]
    search: dict = field(default_factory=dict)
    source: str = "<default space>"

    @property
    def dim(self) -> int:
        return len(self.parameters)

    @property
    def keys(self) -> list[str]:
        return [p.key for p in self.parameters]

    def start_unit(self) -> np.ndarray:
        """The start design as a point of the unit cube (clipped into the bounds)."""
        return np.array([p.unit(p.start) for p in self.parameters])

    def values(self, x: np.ndarray) -> dict[str, float]:
        """Design values of unit point ``x``, by parameter key."""
        return {p.key: p.value(u) for p, u in zip(self.parameters, np.asarray(x, float))}

    def candidate(self, x: np.ndarray) -> dict:
        """The candidate design's TOML data at unit point ``x``."""
        return apply_values(self.base, self.values(x))

    def to_toml(self) -> str:
        """The space as an editable ``--space`` file (start values as comments)."""
        lines = ["# ftrac-design optimize search space (ftrac_design/optimize/space.py)", "[parameters]"]
        groups: dict[str, list[Parameter]] = {}
        for p in self.parameters:
            groups.setdefault(re.sub(r"\[\d+\]$", "", p.key), []).append(p)
        for root, ps in groups.items():
            p = ps[0]
            if p.choices is not None:
                lines.append(f'"{root}" = {{choices = [{", ".join(f"{c:g}" for c in p.choices)}]}}')
            else:
                start = ", ".join(f"{q.start:.4g}" for q in ps)
                lines.append(f'"{root}" = [{p.low:g}, {p.high:g}]   # start {start}')
        if self.search:
            lines += ["", "[search]"] + [f"{k} = {v}" for k, v in self.search.items()]
        return "\n".join(lines) + "\n"


def design_hash(data: dict) -> str:
    """sha256 of a design's data (canonical JSON): the same candidate, the same hash."""
    return hashlib.sha256(json.dumps(data, sort_keys=True, allow_nan=False).encode()).hexdigest()


def _find(items: list[dict], ident: str) -> dict | None:
    return next((it for it in items if it.get("id") == ident), None)


def _line_geometry(base: dict) -> dict[str, dict]:
    """Per line: its bead count, pinned ends and the start fractions of its movable beads."""
    bead_d = float(base.get("bead", {}).get("diameter", 0.0))
    g = bead_d + BEAD_GAP_MM
    out = {}
    for line in base.get("lines", []):
        zs = sorted(float(z) for z in line.get("beads_z", []))
        a, b = float(line["z_start"]), float(line["z_end"])
        n = len(zs)
        pin_a = n > 0 and abs(zs[0] - a) < 1e-9
        pin_b = n > 1 and abs(zs[-1] - b) < 1e-9
        free = (b - a) - (n - 1) * g
        s = [(z - a - i * g) / free if free > 0 else 0.5 for i, z in enumerate(zs)]
        movable = [min(max(v, 0.0), 1.0) for i, v in enumerate(s) if not ((i == 0 and pin_a) or (i == n - 1 and pin_b))]
        out[line["id"]] = {"n": n, "pin_a": pin_a, "pin_b": pin_b, "fractions": movable}
    return out


def place_beads(
    z_start: float, z_end: float, n: int, pin_a: bool, pin_b: bool, fractions: list[float], bead_diameter: float
) -> list[float]:
    """Axial bead centres (mm) of a line from ordered fractions (see the module doc)."""
    g = bead_diameter + BEAD_GAP_MM
    s = sorted(min(max(f, 0.0), 1.0) for f in fractions)
    s = ([0.0] if pin_a else []) + s + ([1.0] if pin_b else [])
    free = (z_end - z_start) - (n - 1) * g
    zs = [z_start + i * g + si * free for i, si in enumerate(s)]
    if pin_b and n:
        zs[-1] = z_end  # exactly on the end, whatever the rounding
    return zs


def apply_values(base: dict, values: dict[str, float]) -> dict:
    """``base`` design data with ``values`` (by space key) put in; pure."""
    data = copy.deepcopy(base)
    geo = _line_geometry(base)
    scale = values.get("body.scale")
    if scale is not None:
        for k in ("outer_diameter", "length", "bore_diameter"):
            data["body"][k] = float(base["body"][k]) * scale
        for table, keys in _AXIAL.items():
            for item in data.get(table, []):
                for k in keys:
                    item[k] = float(item[k]) * scale
        for b in data.get("beads", []):
            b["z"] = float(b["z"]) * scale
    for key in ("wire.diameter", "bead.diameter"):
        if key in values:
            part = key.split(".")[0]
            old = float(base[part]["diameter"])
            data[part]["diameter"] = values[key]
            seat = data.setdefault("seating", {})
            # keep the start design's cover above each part: depth of centre = radius + cover
            for depth_key, owner in (("ellipse_wire_depth", "wire"), ("line_wire_depth", "bead")):
                if owner == part and depth_key in base.get("seating", {}):
                    seat[depth_key] = float(base["seating"][depth_key]) + (values[key] - old) / 2
    if any(k in values for k in _STOCK_KEYS):
        _set_error_factors(base, data)
    fracs: dict[str, dict[int, float]] = {}
    for key, v in values.items():
        parts = key.split(".")
        if parts[0] == "body" and parts[1] != "scale":
            data["body"][parts[1]] = v
        elif parts[0] in ("ellipses", "lines"):
            item = _find(data[parts[0]], parts[1])
            m = re.fullmatch(r"beads\[(\d+)\]", parts[2])
            if m:
                fracs.setdefault(parts[1], {})[int(m.group(1))] = v
            elif scale is not None and parts[2] in ("z_center", "z_start", "z_end"):
                item[parts[2]] = v * scale  # axial values are in the start design's mm, scaled
            else:
                item[parts[2]] = v
    if scale is not None or "body.outer_diameter" in values:
        _connector_follows_mount(base, data)
    bead_d = float(data.get("bead", {}).get("diameter", 0.0))
    for line in data.get("lines", []):
        g = geo[line["id"]]
        moved = (
            line["id"] in fracs
            or any(f"lines.{line['id']}.{k}" in values for k in ("z_start", "z_end"))
            or scale is not None
            or "bead.diameter" in values
        )
        if g["n"] and moved:
            f = list(g["fractions"])
            for i, v in fracs.get(line["id"], {}).items():
                f[i] = v
            line["beads_z"] = place_beads(
                float(line["z_start"]), float(line["z_end"]), g["n"], g["pin_a"], g["pin_b"], f, bead_d
            )
    return data


@functools.lru_cache(maxsize=64)
def _factors(
    bead: float | None, wire: float | None, ref_bead: float | None, ref_wire: float | None, depth: float
) -> tuple[float, float]:
    from ..xray.localization import size_error_factors

    return size_error_factors(bead, wire, ref_bead, ref_wire, depth)


def _set_error_factors(base: dict, data: dict) -> None:
    """Write into ``data``'s [analysis] the start's error factors times the pixel-bound ratio of
    its stock sizes to the start's (see the module doc)."""

    def size(d: dict, part: str) -> float | None:
        v = d.get(part, {}).get("diameter")
        return float(v) if v is not None else None

    a0 = base.get("analysis", {})
    depth = float(a0.get("depth", Analysis().depth))
    kb, kw = _factors(size(data, "bead"), size(data, "wire"), size(base, "bead"), size(base, "wire"), depth)
    a = data.setdefault("analysis", {})
    for key, k in (("bead_error_factor", kb), ("wire_error_factor", kw)):
        a[key] = float(a0.get(key, 1.0)) * k
        if a[key] == 1.0 and key not in a0:
            del a[key]


def _mount_width(data: dict) -> float | None:
    """The mount block's side (mm) of design data, or None where the schema refuses it."""
    from ..features.mounting import mount_layout

    try:
        return float(mount_layout(Design.model_validate(data)).width)
    except (ValidationError, ValueError):
        return None


def _connector_follows_mount(base: dict, data: dict) -> None:
    """Raise (or lower) ``data``'s connector axis by half of its mount's growth over
    ``base``'s, so the mount keeps ``base``'s clearance above the template (in place)."""
    w0, w = _mount_width(base), _mount_width(data)
    if w0 is None or w is None or w == w0:
        return
    from ..design.schema import Connector

    con = data.setdefault("connector", {})
    h0 = float(base.get("connector", {}).get("axis_height", Connector.model_fields["axis_height"].default))
    con["axis_height"] = h0 + (w - w0) / 2


def _schema_problem(data: dict) -> str | None:
    """The design schema's complaint about ``data`` (field types and ranges only), or None."""
    from ..design.loader import describe_schema_error

    try:
        Design.model_validate(data)
    except ValidationError as exc:
        key, expected = describe_schema_error(exc.errors(include_url=False)[0], with_input=False)
        return f"{key} must be {expected}"
    return None


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _parameter(base: dict, key: str, spec: Any, file: str) -> list[Parameter]:
    where = f"parameters.{key}"
    parts = key.split(".")
    start: float | list[float]
    if key in _STOCK_KEYS:
        owner = base.get(parts[0])
        if owner is None:
            raise InputError(file, where, f"a design with a [{parts[0]}] table")
        ch = spec.get("choices") if isinstance(spec, dict) else None
        if (
            not isinstance(spec, dict)
            or set(spec) != {"choices"}
            or not isinstance(ch, list)
            or not ch
            or not all(_number(c) and c > 0 for c in ch)
        ):
            raise InputError(file, where, "{choices = [sizes, mm]}: a non-empty list of positive stock sizes")
        return [Parameter(key, min(ch), max(ch), float(owner["diameter"]), tuple(float(c) for c in ch))]
    if len(parts) == 2 and parts[0] == "body" and parts[1] in _BODY_KEYS:
        start = 1.0 if parts[1] == "scale" else float(base["body"][parts[1]])
    elif len(parts) == 3 and parts[0] in ("ellipses", "lines"):
        item = _find(base.get(parts[0], []), parts[1])
        allowed = _ELLIPSE_KEYS if parts[0] == "ellipses" else _LINE_KEYS + ("beads",)
        if item is None or parts[2] not in allowed:
            raise InputError(file, where, f"a known parameter ({KNOWN}; ids from the design)")
        start = float(item[parts[2]]) if parts[2] != "beads" else _line_geometry(base)[parts[1]]["fractions"]
    else:
        raise InputError(file, where, f"a known parameter ({KNOWN}; ids from the design)")
    if not (isinstance(spec, list) and len(spec) == 2 and all(_number(v) for v in spec)):
        raise InputError(file, where, f"a range [low, high] of two numbers, got {spec!r}")
    lo, hi = float(spec[0]), float(spec[1])
    if not lo < hi:
        raise InputError(file, where, f"a range [low, high] with low < high, got {spec!r}")
    if isinstance(start, list):
        if lo < 0.0 or hi > 1.0:
            raise InputError(file, where, f"fractions of the line within [0, 1], got {spec!r}")
        if not start:
            raise InputError(file, where, "a line with movable beads (every bead of it sits on an end)")
        return [Parameter(f"{key}[{i}]", lo, hi, s) for i, s in enumerate(start)]
    if key == "body.scale" and lo <= 0:
        raise InputError(file, where, f"a positive scale range, got {spec!r}")
    return [Parameter(key, lo, hi, start)]


def parse_space(base: dict, data: dict, file: str | Path = "<space>") -> SearchSpace:
    """Validate a space mapping (a parsed ``--space`` file) against the start design data."""
    file = str(file)
    unknown = set(data) - {"parameters", "search"}
    if unknown:
        raise InputError(file, sorted(unknown)[0], "no such table (a space file has [parameters] and [search])")
    params = data.get("parameters")
    if not isinstance(params, dict) or not params:
        raise InputError(file, "parameters", "a [parameters] table naming at least one parameter")
    out: list[Parameter] = []
    for key, spec in params.items():
        out += _parameter(base, key, spec, file)
    keys = {p.key for p in out}
    if "body.scale" in keys and keys & {"body.outer_diameter", "body.length", "body.bore_diameter"}:
        raise InputError(file, "parameters.body.scale", "either body.scale or absolute body sizes, not both")
    # a bound the schema itself refuses (a field's type or range), each bound alone
    for p in out:
        for v in (p.low, p.high) if p.choices is None else p.choices:
            vals = {q.key: (v if q.key == p.key else q.start) for q in out}
            problem = _schema_problem(apply_values(base, vals))
            if problem:
                root = re.sub(r"\[\d+\]$", "", p.key)
                raise InputError(
                    file, f"parameters.{root}", f"bounds the design schema accepts ({p.key} = {v:g}: {problem})"
                )
    search = data.get("search", {})
    if not isinstance(search, dict):
        raise InputError(file, "search", "a table")
    for k, v in search.items():
        typ = SEARCH_KEYS.get(k)
        if typ is None:
            raise InputError(file, f"search.{k}", f"no such key (one of {', '.join(SEARCH_KEYS)})")
        ok = (isinstance(v, int) and not isinstance(v, bool) and v > 0) if typ is int else (_number(v) and v > 0)
        if not ok:
            raise InputError(file, f"search.{k}", f"a positive {'integer' if typ is int else 'number'}, got {v!r}")
    if "sigma0" in search and search["sigma0"] > 1:
        raise InputError(file, "search.sigma0", f"a step in the unit cube, at most 1, got {search['sigma0']!r}")
    if "poses" in search and search["poses"] < 100:
        raise InputError(file, "search.poses", f"at least 100 poses, got {search['poses']!r}")
    return SearchSpace(base, tuple(out), dict(search), file)


def load_space(base: dict, path: str | Path) -> SearchSpace:
    """Read and validate a ``--space`` TOML file, or a shipped space given by name.

    Parameters
    ----------
    base : dict
        The start design's TOML data.
    path : str or pathlib.Path
        A space file, or a shipped space's name (``"ftrac_mini_layout"``; see
        :func:`~ftrac_design.design.presets.resolve_space`).

    Returns
    -------
    SearchSpace
        The validated space. Raises :class:`InputError` naming the file, the key and what was
        expected (a missing file: the shipped space names too).
    """
    path = resolve_space(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, None, f"file not found (nor a shipped space: {known_spaces()})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, None, f"a readable UTF-8 file ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, None, f"valid TOML ({exc})") from None
    return parse_space(base, data, path)


def default_space(base: dict) -> SearchSpace:
    """The layout within the start design's envelope (body, wire and beads unchanged):

    - each ellipse: tilt ±20° of its start (within 5–70°), tilt azimuth ±60°, centre ±25 % of
      the half-length;
    - each line: azimuth ±60°; its start anywhere from the body's end (less a bead radius)
      to 10 % of the half-length before the middle, its end likewise; its movable beads
      anywhere along it (fractions 0–1).
    """
    half = float(base["body"]["length"]) / 2
    reach = max(float(base.get("wire", {}).get("diameter", 0)), float(base.get("bead", {}).get("diameter", 0))) / 2
    params: dict[str, Any] = {}

    def rng(key: str, lo: float, hi: float) -> None:
        params[key] = [round(lo, 3), round(hi, 3)]

    for e in base.get("ellipses", []):
        t, a, z = float(e["tilt_deg"]), float(e["tilt_azimuth_deg"]), float(e["z_center"])
        rng(f"ellipses.{e['id']}.tilt_deg", max(5.0, t - 20), min(70.0, t + 20))
        rng(f"ellipses.{e['id']}.tilt_azimuth_deg", a - 60, a + 60)
        rng(f"ellipses.{e['id']}.z_center", z - 0.25 * half, z + 0.25 * half)
    geo = _line_geometry(base)
    for line in base.get("lines", []):
        a, z0, z1 = float(line["azimuth_deg"]), float(line["z_start"]), float(line["z_end"])
        rng(f"lines.{line['id']}.azimuth_deg", a - 60, a + 60)
        end = half - reach - 1e-3
        rng(f"lines.{line['id']}.z_start", min(-end, z0), max(-0.1 * half, z0))
        rng(f"lines.{line['id']}.z_end", min(0.1 * half, z1), max(end, z1))
        if geo[line["id"]]["fractions"]:
            params[f"lines.{line['id']}.beads"] = [0.0, 1.0]
    return parse_space(base, {"parameters": params}, "<default space>")
