"""A reader for the RS-274 subset the posts write, and the cycle time of what it read.

Read: ``G0 G1 G2 G3`` (arcs in G17, helical in Z, centre by I/J relative to the start),
``G20/G21``, ``G90/G91``, ``G93/G94``, ``G17``, ``G40 G49 G80 G54 G91.1``, ``G43 H``,
``X Y Z A I J F S T N O``, ``M2 M3 M5 M6 M30 M10 M11``, comments in parentheses or after
``;``, ``%`` lines. Anything else is refused (:class:`~ftrac_design.errors.InputError`
naming the line), so a program that the simulator checked cannot hide a word it ignored.
A comment ``FEATURE <id> …`` names the feature of the moves up to ``END FEATURE``.

Faults that a control would also reject, or that break the part, are collected rather than
raised: a cutting move with the spindle stopped or no tool, an A move with the A brake on.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .model import Machine

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_G_OK = {"0", "1", "2", "3", "17", "20", "21", "40", "43", "49", "54", "80", "90", "91", "91.1", "93", "94"}
_M_OK = {"2", "3", "5", "6", "10", "11", "30"}


@dataclass(frozen=True)
class ParsedMove:
    """One motion as the control would run it: machine X, Y, Z mm and A degrees, absolute.

    ``start`` holds NaN for an axis not yet programmed. ``f``: mm/min or 1/min (G93).
    """

    line: int
    kind: str  # rapid | feed | arc
    start: tuple[float, float, float, float]
    end: tuple[float, float, float, float]
    feed_mode: str = "per_minute"
    f: float = 0.0
    centre: tuple[float, float] | None = None
    ccw: bool = True
    tool: int | None = None
    spindle_rpm: float = 0.0
    feature: str | None = None

    @property
    def sweep(self) -> float:
        """Arc angle swept (rad, positive); 0 for straight moves. Equal ends: a full turn."""
        if self.kind != "arc":
            return 0.0
        cx, cy = self.centre
        a0 = math.atan2(self.start[1] - cy, self.start[0] - cx)
        a1 = math.atan2(self.end[1] - cy, self.end[0] - cx)
        s = (a1 - a0) % (2 * math.pi) if self.ccw else (a0 - a1) % (2 * math.pi)
        return s if s > 1e-9 else 2 * math.pi

    @property
    def radius(self) -> float:
        return math.hypot(self.start[0] - self.centre[0], self.start[1] - self.centre[1]) if self.centre else 0.0

    def length(self) -> float:
        """Tool-tip path length, mm (X, Y, Z only; A contributes none)."""
        if self.kind == "arc":
            return math.hypot(self.radius * self.sweep, self.end[2] - self.start[2])
        d = np.subtract(self.end[:3], self.start[:3])
        return float(np.sqrt(np.nansum(d * d)))


@dataclass
class ParsedProgram:
    """What :func:`parse_gcode` read."""

    moves: list[ParsedMove] = field(default_factory=list)
    tools: dict[int, float] = field(default_factory=dict)  # tool → diameter from its comment, if stated
    tool_changes: list[int] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)


def _tool_diameters(comment: str, tools: dict[int, float]) -> None:
    m = re.match(r"\s*T(\d+):\s*([0-9.]+)\s*MM", comment.upper())
    if m:
        tools[int(m.group(1))] = float(m.group(2))


def _known(codes: set[str]) -> str:
    return ", ".join(sorted(codes, key=float))


def parse_gcode(text: str, source: str | Path = "<program>") -> ParsedProgram:
    """Read a program into moves with their modal state.

    Parameters
    ----------
    text : str
        The program (RS-274; the subset in the module docstring).
    source : str or path
        What the error messages name (the file).

    Returns
    -------
    ParsedProgram
        Moves in machine coordinates (X, Y, Z mm, A degrees, absolute; inches converted),
        tool changes, the tool diameters the comments state, and faults.

    Raises :class:`InputError` (naming ``source`` and the line) on a word or code outside the subset.
    """
    out = ParsedProgram()
    st = _Modal()
    for n, raw in enumerate(text.splitlines(), start=1):
        where = f"line {n}"
        code = _code_of(raw, st, out, source, where)
        if not code or code == "%":
            continue
        rest = _WORD.sub(" ", code).strip()
        if rest:
            raise InputError(source, where, f"G-code words (letter and number), got {rest!r}")
        words = _WORD.findall(code)
        axes, ij, m_codes = _read_words(words, st, source, where)
        _apply_m_codes(m_codes, st, out, source, where)
        if not axes:
            continue
        mv = _move(n, axes, ij, "F" in dict(words), st, source, where)
        if mv is None:
            continue
        if mv.kind != "rapid" and (not st.spindle or st.tool is None):
            out.faults.append(f"line {n}: a cutting move with the spindle stopped or no tool")
        if st.clamped and abs(mv.end[3] - mv.start[3]) > 0 and not math.isnan(mv.start[3]):
            out.faults.append(f"line {n}: A moves while the A brake is on (M10)")
        out.moves.append(mv)
        st.pos = list(mv.end)
    return out


@dataclass
class _Modal:
    """The reader's modal state between lines: the position, the motion and distance modes, the
    feed mode and units, feed, speed, spindle, tool, brake and the feature being cut."""

    pos: list[float] = field(default_factory=lambda: [math.nan] * 4)
    motion: str | None = None
    absolute: bool = True
    inverse: bool = False
    scale: float = 1.0
    feed: float = 0.0
    rpm: float = 0.0
    spindle: bool = False
    tool: int | None = None
    pending: int | None = None
    clamped: bool = False
    feature: str | None = None


def _code_of(raw: str, st: _Modal, out: ParsedProgram, source, where: str) -> str:
    """A line's code, upper case, without its comments; the comments name the feature being cut
    and the tools' diameters."""
    comments = re.findall(r"\(([^)]*)\)", raw)
    code = re.sub(r"\([^)]*\)", " ", raw).split(";")[0].strip().upper()
    for c in comments:
        cu = c.strip().upper()
        if cu.startswith("FEATURE "):
            st.feature = c.strip().split()[1]
        elif cu.startswith("END FEATURE"):
            st.feature = None
        _tool_diameters(c, out.tools)
    if "(" in code or ")" in code:
        raise InputError(source, where, f"balanced parentheses, got {raw.strip()!r}")
    return code


def _g_code(val: str, st: _Modal, source, where: str) -> None:
    g = val.lstrip("0") or "0"
    g = g[:-2] if g.endswith(".0") else g
    if g not in _G_OK:
        raise InputError(source, where, f"a G code this reader knows ({_known(_G_OK)}), got G{val}")
    if g in ("0", "1", "2", "3"):
        st.motion = g
    elif g == "20":
        st.scale = 25.4
    elif g == "21":
        st.scale = 1.0
    elif g in ("90", "91"):
        st.absolute = g == "90"
    elif g in ("93", "94"):
        st.inverse = g == "93"


def _read_words(words, st: _Modal, source, where: str) -> tuple[dict[str, float], dict[str, float], list[str]]:
    """One line's words: the modal codes and values set on ``st``; the axis words, the arc
    centre's I and J, and the M codes returned."""
    axes: dict[str, float] = {}
    ij: dict[str, float] = {}
    m_codes = []
    for letter, val in words:
        if letter == "G":
            _g_code(val, st, source, where)
        elif letter == "M":
            m = val.lstrip("0") or "0"
            if m not in _M_OK:
                raise InputError(source, where, f"an M code this reader knows ({_known(_M_OK)}), got M{val}")
            m_codes.append(m)
        elif letter in "XYZA":
            axes[letter] = float(val)
        elif letter in "IJ":
            ij[letter] = float(val)
        elif letter == "F":
            st.feed = float(val)
        elif letter == "S":
            st.rpm = float(val)
        elif letter == "T":
            st.pending = int(float(val))
        elif letter in "NOH":
            continue
        else:
            raise InputError(source, where, f"a word this reader knows (G M X Y Z A I J F S T N O H), got {letter}")
    return axes, ij, m_codes


def _apply_m_codes(m_codes: list[str], st: _Modal, out: ParsedProgram, source, where: str) -> None:
    for m in m_codes:
        if m == "6":
            if st.pending is None:
                raise InputError(source, where, "a T word before M6")
            st.tool = st.pending
            out.tool_changes.append(st.tool)
        elif m == "3":
            st.spindle = True
        elif m == "5":
            st.spindle = False
        elif m == "10":
            st.clamped = True
        elif m == "11":
            st.clamped = False


def _end_point(axes: dict[str, float], st: _Modal, source, where: str) -> list[float]:
    """Where the axis words take the tool (absolute or incremental; inches converted)."""
    end = list(st.pos)
    for i, ax in enumerate("XYZA"):
        if ax in axes:
            v = axes[ax] * (st.scale if ax != "A" else 1.0)
            if st.absolute:
                end[i] = v
            elif math.isnan(st.pos[i]):
                raise InputError(source, where, f"an absolute {ax} before incremental moves (G91)")
            else:
                end[i] = st.pos[i] + v
    return end


def _move(n: int, axes, ij, has_f: bool, st: _Modal, source, where: str) -> ParsedMove | None:
    """The move a line with axis words makes (None: it does not move)."""
    if st.motion is None:
        raise InputError(source, where, "a motion code (G0, G1, G2, G3) before the first axis word")
    pos, end = st.pos, _end_point(axes, st, source, where)
    kind = {"0": "rapid", "1": "feed", "2": "arc", "3": "arc"}[st.motion]
    if kind != "rapid" and st.feed <= 0:
        raise InputError(source, where, "a feed (F) before the first cutting move")
    if st.inverse and kind != "rapid" and not has_f:
        raise InputError(source, where, "an F word on every cutting move in inverse-time mode (G93)")
    centre = None
    if kind == "arc":
        if "I" not in ij and "J" not in ij:
            raise InputError(source, where, "I and/or J on an arc")
        centre = (pos[0] + ij.get("I", 0.0) * st.scale, pos[1] + ij.get("J", 0.0) * st.scale)
        r0 = math.hypot(pos[0] - centre[0], pos[1] - centre[1])
        r1 = math.hypot(end[0] - centre[0], end[1] - centre[1])
        if abs(r0 - r1) > 1e-3 or abs(end[3] - pos[3]) > 0:
            raise InputError(source, where, "an arc whose start and end lie on one circle, with A fixed")
    if kind != "arc" and all((a == b) or (math.isnan(a) and math.isnan(b)) for a, b in zip(pos, end)):
        return None
    f = st.feed if st.inverse else st.feed * st.scale
    return ParsedMove(
        n,
        kind,
        tuple(pos),
        tuple(end),
        "inverse_time" if st.inverse else "per_minute",
        f if kind != "rapid" else 0.0,
        centre,
        st.motion == "3",
        st.tool,
        st.rpm if st.spindle else 0.0,
        st.feature,
    )


def move_time(m: ParsedMove, machine: Machine) -> float:
    """Seconds for one move: rapids at the machine's rapid rates (slowest axis), G93 feeds
    take 1/F minutes, G94 feeds length/F (A degrees when only A turns)."""
    if m.kind == "rapid":
        d = np.subtract(m.end, m.start)
        d = np.where(np.isfinite(d), d, 0.0)
        return 60.0 * max(float(np.linalg.norm(d[:3])) / machine.rapid_linear, abs(float(d[3])) / machine.rapid_a)
    if m.feed_mode == "inverse_time":
        return 60.0 / m.f
    length = m.length()
    if length < 1e-12:
        length = abs(m.end[3] - m.start[3])
    return 60.0 * length / m.f


def cycle_time(prog: ParsedProgram, machine: Machine = Machine()) -> dict[str, float]:
    """Cycle time (s): cutting feeds, rapids, tool changes and their total (acceleration ignored)."""
    feed = sum(move_time(m, machine) for m in prog.moves if m.kind != "rapid")
    rapid = sum(move_time(m, machine) for m in prog.moves if m.kind == "rapid")
    tc = machine.tool_change_s * len(prog.tool_changes)
    return {"feed_s": feed, "rapid_s": rapid, "tool_change_s": tc, "total_s": feed + rapid + tc}
