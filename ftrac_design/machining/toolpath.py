"""The 4-axis program for a body's grooves and pockets, as a list of blocks.

**Machine convention** (what the program assumes; docs/guide/machining.md):

- The body lies along machine **X** on the rotary **A** axis: F's ``+z`` is machine ``+X``,
  with the ``z = −L/2`` end (datum B, the mount end) toward ``−X``. Work offset **G54**:
  ``X0`` at F's origin (mid-length, L/2 from datum B), ``Y0`` and ``Z0`` on the A axis.
- The tool points down machine ``−Z``; with tool-length offset ``G43 H<n>`` a programmed
  ``Z`` is the tool tip's distance from the A axis.
- ``A = θ`` (degrees) puts the body's azimuth θ (F, about ``+z`` from ``+x``) under the
  spindle; ``A0``: F's ``+x`` points up, toward the spindle. Positive A turns the tool about
  the work right-handed about ``+X`` (ISO 841): on the machine the top of the part moves
  toward ``+Y``. At any A, machine ``+Y`` is F's ``−e_θ(A)``. A is not wrapped: a wrapped
  groove winds on through several turns.
- Wrap milling (the ellipse grooves) keeps ``Y = 0``, the tool on a radius; the slots and
  pockets are cut at a fixed A, and their side passes and circles move in Y, because an
  A offset would tilt a slot's wall away from the CAD's plane.

**Cuts.** Every groove is cut in levels of at most ``step_down``, entered on a ramp of
``ramp_angle`` along the groove (a closed ellipse ramps down along its own path, then goes
once round at depth, which also recuts the ramp); grooves wider than the tool get side
passes offset across the groove (in the unrolled surface at the seat radius for an
ellipse, in Y for a slot). A pocket is a helix of ``ramp_angle`` at radius ``(D − d)/2``
about its axis, then one flat circle at the floor. Moves that turn A are fed in inverse
time (``G93``: F = 1 / minutes), timed so that the outer surface passes the tool at the
tool's feed; the rest in mm/min (``G94``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .model import CutPlan, EllipseCut, Machine, PocketCut, SlotCut, Tool, Tooling

#: angular step of the wrapped ellipse polylines, rad (chord error A·Δφ²/8: 0.08 µm on ftrac_2005)
ELLIPSE_STEP = math.radians(0.5)

#: side passes overlap by at least this fraction of the tool diameter
STEPOVER = 0.8

FeedMode = Literal["inverse_time", "per_minute"]


@dataclass(frozen=True)
class Move:
    """One motion block, in machine units: X, Y, Z mm, A degrees (absolute).

    ``kind``: ``rapid`` (G0), ``feed`` (G1) or ``arc`` (G2/G3 in the XY plane, helical in Z,
    centre ``centre`` = absolute (X, Y), counter-clockwise seen from +Z when ``ccw``).
    ``f``: mm/min (``per_minute``) or 1/min (``inverse_time``); 0 for rapids.
    """

    kind: Literal["rapid", "feed", "arc"]
    end: tuple[float, float, float, float]
    feed_mode: FeedMode = "per_minute"
    f: float = 0.0
    centre: tuple[float, float] | None = None
    ccw: bool = True


@dataclass(frozen=True)
class Comment:
    text: str


@dataclass(frozen=True)
class ToolChange:
    tool: Tool


@dataclass(frozen=True)
class Spindle:
    rpm: float  # 0: stop


@dataclass(frozen=True)
class Clamp:
    """The A-axis brake: on while cutting at a fixed A, off for wrap milling (posts that have one)."""

    on: bool


Block = Move | Comment | ToolChange | Spindle | Clamp


@dataclass
class Program:
    """A program: its blocks, the stock it is cut from and a title."""

    title: str
    stock_radius: float
    safe_z: float
    blocks: list[Block] = field(default_factory=list)

    @property
    def moves(self) -> list[Move]:
        return [b for b in self.blocks if isinstance(b, Move)]


class _Writer:
    """Appends blocks and tracks the position; fills in inverse-time feeds."""

    def __init__(self, program: Program, machine: Machine):
        self.p = program
        self.m = machine
        self.pos = [0.0, 0.0, program.stock_radius + machine.clearance, 0.0]
        self.safe = program.stock_radius + machine.clearance
        self.surface = program.stock_radius
        self.retract_feed = 100.0

    def add(self, b: Block) -> None:
        self.p.blocks.append(b)

    def _target(self, x, y, z, a) -> tuple[float, float, float, float]:
        cur = self.pos
        return tuple(float(v) if v is not None else cur[i] for i, v in enumerate((x, y, z, a)))

    def rapid(self, x=None, y=None, z=None, a=None) -> None:
        t = self._target(x, y, z, a)
        if t != tuple(self.pos):
            self.add(Move("rapid", t))
            self.pos = list(t)

    def feed(self, feed: float, x=None, y=None, z=None, a=None) -> None:
        t = self._target(x, y, z, a)
        if t == tuple(self.pos):
            return
        d = np.subtract(t, self.pos)
        if abs(d[3]) > 1e-12:  # A turns: time the outer surface past the tool at `feed`
            length = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2 + (self.surface * math.radians(d[3])) ** 2)
            self.add(Move("feed", t, "inverse_time", feed / length))
        else:
            self.add(Move("feed", t, "per_minute", feed))
        self.pos = list(t)

    def helix(self, feed: float, centre: tuple[float, float], z_end: float) -> None:
        """One full counter-clockwise turn about ``centre`` ending at ``z_end``."""
        self.add(
            Move(
                "arc",
                (self.pos[0], self.pos[1], float(z_end), self.pos[3]),
                "per_minute",
                feed,
                (float(centre[0]), float(centre[1])),
                True,
            )
        )
        self.pos[2] = float(z_end)

    def to_safe(self) -> None:
        if self.pos[2] < self.surface + self.m.approach - 1e-9:
            self.feed(self.retract_feed, z=self.surface + self.m.approach)
        self.rapid(z=self.safe)

    def index(self, a_deg: float) -> float:
        """The A nearest the current one that shows azimuth ``a_deg``."""
        return a_deg + 360.0 * round((self.pos[3] - a_deg) / 360.0)


def levels(top: float, bottom: float, step: float) -> np.ndarray:
    """Tool-tip heights from just below ``top`` down to ``bottom`` in equal steps ≤ ``step``."""
    n = max(1, math.ceil((top - bottom) / step - 1e-9))
    return top - (top - bottom) * np.arange(1, n + 1) / n


def side_offsets(width: float, tool: float) -> np.ndarray:
    """Offsets of the side passes across a groove ``width`` wide for a ``tool`` end mill."""
    d = (width - tool) / 2
    if d < -1e-9:
        raise ValueError(f"a {width:.3f} mm groove is narrower than the {tool:g} mm end mill")
    if d < 1e-9:
        return np.zeros(1)
    return np.linspace(-d, d, math.ceil(2 * d / (STEPOVER * tool)) + 1)


def ellipse_pass(cut: EllipseCut, offset: float, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A degrees, X) of a pass ``offset`` across the groove at centre-line azimuths ``phi``.

    The offset is taken in the unrolled seat cylinder (arc length ``b φ``, ``z``), along
    ``B`` = (z', −b)/m, so the pass stays ``offset`` from the centre-line at the seat radius.
    """
    b = cut.seat_radius
    d1 = cut.dz(phi)
    m = np.hypot(b, d1)
    return np.degrees(phi + offset * d1 / (m * b)), cut.z(phi) - offset * b / m


def _ellipse(w: _Writer, cut: EllipseCut, tool: Tool, tooling: Tooling) -> None:
    offsets = side_offsets(cut.width, tool.diameter)
    floor = cut.seat_radius - cut.floor_depth
    zs = levels(w.surface, floor, tooling.step_down)
    w.add(
        Comment(
            f"FEATURE {cut.id} ellipse groove: width {cut.width:.4f}, tip at Z{floor:.4f}, "
            f"{len(zs)} levels x {len(offsets)} passes, wrapped (Y0)"
        )
    )
    w.add(Clamp(False))
    n_loop = round(2 * math.pi / ELLIPSE_STEP)
    step = 2 * math.pi / n_loop
    phi0 = math.radians(w.index(0.0))
    a0, x0 = ellipse_pass(cut, offsets[0], np.array([phi0]))
    w.rapid(z=w.safe)
    w.rapid(x=x0[0], y=0.0, a=a0[0])
    w.rapid(z=w.surface + w.m.approach)
    w.feed(tool.plunge_feed, z=w.surface)
    j, k_off, z_cur = 0, 0, w.surface
    for z_level in zs:
        # ramp along the current pass down to the level, then once round at the level
        ramp_len = (z_cur - z_level) / math.tan(tooling.ramp_angle)
        run, n_ramp = 0.0, 0
        phis = phi0 + step * np.arange(j, j + n_loop + 1)
        a, x = ellipse_pass(cut, offsets[k_off], phis)
        seg = np.hypot(w.surface * np.radians(np.diff(a)), np.diff(x))
        while run < ramp_len and n_ramp < n_loop:
            run += seg[n_ramp]
            n_ramp += 1
        cum = np.concatenate([[0.0], np.cumsum(seg[:n_ramp])])
        for i in range(1, n_ramp + 1):
            w.feed(tool.plunge_feed, x=x[i], a=a[i], z=z_cur - (z_cur - z_level) * cum[i] / cum[-1])
        j += n_ramp
        z_cur = float(z_level)
        for k in range(len(offsets)):
            if k:
                k_off = (k_off + 1) % len(offsets)
            phis = phi0 + step * np.arange(j, j + n_loop + 1)
            a, x = ellipse_pass(cut, offsets[k_off], phis)
            for i in range(n_loop + 1):
                w.feed(tool.feed, x=x[i], a=a[i], z=z_cur)
            j += n_loop
    w.to_safe()
    w.add(Comment(f"END FEATURE {cut.id}"))


def _slot(w: _Writer, cut: SlotCut, tool: Tool, tooling: Tooling) -> None:
    offsets = side_offsets(cut.width, tool.diameter)
    zs = levels(w.surface, cut.floor_radius, tooling.step_down)
    length = cut.z1 - cut.z0
    w.add(
        Comment(
            f"FEATURE {cut.id} axial slot: width {cut.width:.4f}, floor Z{cut.floor_radius:.4f}, "
            f"X{cut.z0:.4f} to X{cut.z1:.4f}, {len(zs)} levels x {len(offsets)} passes"
        )
    )
    w.rapid(z=w.safe)
    w.add(Clamp(False))
    w.rapid(x=cut.z0, y=offsets[0], a=w.index(math.degrees(cut.azimuth)))
    w.add(Clamp(True))
    w.rapid(z=w.surface + w.m.approach)
    w.feed(tool.plunge_feed, z=w.surface)
    ends = (cut.z0, cut.z1)
    at_end, z_cur, k_off = 0, w.surface, 0
    for z_level in zs:
        legs = max(1, math.ceil((z_cur - z_level) / (length * math.tan(tooling.ramp_angle)) - 1e-9))
        for leg in range(1, legs + 1):  # zig-zag ramp along the slot
            at_end = 1 - at_end
            w.feed(tool.plunge_feed, x=ends[at_end], z=z_cur - (z_cur - z_level) * leg / legs)
        z_cur = float(z_level)
        at_end = 1 - at_end
        w.feed(tool.feed, x=ends[at_end])  # recut the ramp at the level
        for k in range(1, len(offsets)):
            k_off = (k_off + 1) % len(offsets)
            w.feed(tool.feed, y=offsets[k_off])
            at_end = 1 - at_end
            w.feed(tool.feed, x=ends[at_end])
    w.to_safe()
    w.add(Comment(f"END FEATURE {cut.id}"))


def _pocket(w: _Writer, cut: PocketCut, tool: Tool, tooling: Tooling) -> None:
    rc = (cut.diameter - tool.diameter) / 2
    if rc < -1e-9:
        raise ValueError(f"pocket {cut.id}: the {tool.diameter:g} mm end mill is wider than the pocket")
    rc = max(rc, 0.0)
    depth = w.surface - cut.floor_radius
    pitch = 2 * math.pi * rc * math.tan(tooling.ramp_angle)
    turns = math.ceil(depth / pitch - 1e-9) if pitch > 0 else 0
    w.add(
        Comment(
            f"FEATURE {cut.id} pocket: diameter {cut.diameter:.4f}, floor Z{cut.floor_radius:.4f}, "
            + (f"helix radius {rc:.4f}, {turns} turns" if turns else "plunge")
        )
    )
    w.rapid(z=w.safe)
    w.add(Clamp(False))
    w.rapid(x=cut.z + rc, y=0.0, a=w.index(math.degrees(cut.azimuth)))
    w.add(Clamp(True))
    w.rapid(z=w.surface + w.m.approach)
    w.feed(tool.plunge_feed, z=w.surface)
    if turns:
        for t in range(1, turns + 1):
            w.helix(tool.plunge_feed, (cut.z, 0.0), w.surface - depth * t / turns)
        w.helix(tool.feed, (cut.z, 0.0), cut.floor_radius)  # the floor, flat
    else:
        w.feed(tool.plunge_feed, z=cut.floor_radius)
    w.to_safe()
    w.add(Comment(f"END FEATURE {cut.id}"))


def plan_program(plan: CutPlan, tools: Tooling, machine: Machine = Machine(), title: str | None = None) -> Program:
    """The program that cuts every groove and pocket of ``plan`` (ellipses, then slots with the
    groove end mill; then pockets with the pocket end mill: one tool change per tool).

    Parameters
    ----------
    plan : CutPlan
        Stock and cuts in frame F (mm, rad).
    tools : Tooling
        End mills, their speeds and feeds, step-down (mm) and ramp angle (rad).
    machine : Machine
        Safe and approach heights above the stock (mm).
    title : str, optional
        The program's name (default the plan's).

    Returns
    -------
    Program
        Blocks in machine coordinates (X, Y, Z mm, A degrees; convention in the module docstring).

    Raises ``ValueError`` when a groove is narrower than the groove end mill or a pocket than
    the pocket end mill.
    """
    prog = Program(title or plan.name, plan.stock.outer_radius, plan.stock.outer_radius + machine.clearance)
    w = _Writer(prog, machine)
    jobs: list[tuple[Tool, list]] = [(tools.groove, [*plan.ellipses, *plan.slots])]
    if tools.pocket is tools.groove:
        jobs[0][1].extend(plan.pockets)
    else:
        jobs.append((tools.pocket, list(plan.pockets)))
    for tool, cuts in jobs:
        if not cuts:
            continue
        w.rapid(z=w.safe)
        w.add(ToolChange(tool))
        w.add(Spindle(tool.rpm))
        w.retract_feed = tool.plunge_feed
        for cut in cuts:
            if isinstance(cut, EllipseCut):
                _ellipse(w, cut, tool, tools)
            elif isinstance(cut, SlotCut):
                _slot(w, cut, tool, tools)
            else:
                _pocket(w, cut, tool, tools)
        w.add(Spindle(0.0))
    w.add(Clamp(False))
    return prog
