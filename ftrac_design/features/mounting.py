"""Mount and template-connector layout, and the frames they define (numpy only).

This is the one place where the mount's and the connector's dimensions, hole positions and
the transforms ``mount_from_fiducial`` / ``template_from_fiducial`` are computed. The CAD
(:mod:`ftrac_design.cad.mount`, :mod:`ftrac_design.cad.connector`) builds its solids from
these layouts and places them in the assembly by these transforms; the design rules
(:mod:`ftrac_design.manufacture.rules`) measure the same layouts. A layout holds *nominal* sizes;
a manufacturing profile (:func:`ftrac_design.manufacture.profiles.cut_sizes`) only changes how big
each hole is cut, never where it is.

Frames (all mm):

- **F**, the fiducial (SPEC §1): origin on the cylinder axis at mid-length, ``+z`` along
  the axis, ``+y`` toward the X-ray source in the nominal (AP) view.
- **M**, the mount: origin at the centre of the socket floor, where the cylinder's
  ``z = −L/2`` end face rests; axes parallel to F. ``P_M = P_F + (0, 0, L/2)``.
  The block spans ``x, y ∈ ±W/2``, ``z ∈ [−base_height, socket_depth]``.
- **T**, the brachytherapy template: origin at the centre of the reference grid hole on
  the template's front (operator-side) face; ``+x`` along the grid rows, ``+y`` up the grid
  columns (anterior), ``+z`` along needle insertion. The connector plate spans
  ``z ∈ [−thickness, 0]``; the mount's bottom face sits on its pocket floor at
  ``z = −pocket_depth``, centred on ``(axis_x, axis_height)``. With the X-ray source
  posterior (under the table) M and F are turned 180° about z relative to T.

``template_from_fiducial = template_from_mount · mount_from_fiducial`` (paper §IV:
``P_U = F_TU · F_FT · P_F``; this module gives ``F_FT``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Literal

import numpy as np

from ..design.schema import KEY_GAP, Design, HoleSet

#: a hole's centre sits at least this many hole diameters from a face (the hole wall is then
#: one diameter from the edge; the ``*.hole_edge`` rules check it)
EDGE_FACTOR = 1.5
#: ligament (mm) the derived block sizes aim for between cuts and between a counterbore and a
#: face: above the CNC recommendation (1.5 mm) and the FDM one (1.2–1.6 mm)
DESIGN_WALL = 2.0
#: extra room (mm) in derived sizes so that FDM's enlarged holes still meet the rules
SIZE_MARGIN = 0.25
#: the pocket that locates the mount is cut with a Ø3 mm end mill: its corners keep this radius
POCKET_CORNER_RADIUS = 1.5
#: chamfer on the block's four vertical edges, so that it seats in the pocket past those
#: corner radii (a 45° chamfer c clears a radius r when c ≥ (2 − √2) r = 0.88 mm)
BLOCK_CHAMFER = 1.0

_AXES = "xyz"


@dataclass(frozen=True)
class Hole:
    """A straight through hole along one axis of its part's frame, optionally counterbored
    at its ``+`` end.

    ``center`` is a point on the hole's axis (its coordinate along the axis is the middle of
    ``[lo, hi]``); ``lo``/``hi`` are where the hole enters and leaves the part. Sizes are
    nominal (before a profile's allowance).
    """

    name: str
    axis: int
    center: np.ndarray
    lo: float
    hi: float
    diameter: float
    counterbore_diameter: float = 0.0
    counterbore_depth: float = 0.0
    kind: Literal["clearance", "pin", "tapped"] = "clearance"

    @property
    def direction(self) -> np.ndarray:
        d = np.zeros(3)
        d[self.axis] = 1.0
        return d

    @property
    def start(self) -> np.ndarray:
        """Axis point where the hole enters (the ``−`` face)."""
        p = np.array(self.center, float)
        p[self.axis] = self.lo
        return p

    @property
    def length(self) -> float:
        return self.hi - self.lo


def pattern_offsets(pattern: str, pitch: float) -> list[tuple[float, float]]:
    """Hole offsets ``(du, dv)`` of a pattern in its set's two spreading axes."""
    h = pitch / 2.0
    if pattern == "single":
        return [(0.0, 0.0)]
    if pattern == "pair":
        return [(-h, 0.0), (h, 0.0)]
    if pattern == "square":
        return [(-h, -h), (h, -h), (-h, h), (h, h)]
    raise ValueError(f"unknown hole pattern {pattern!r}")


def spread_axes(axis: int) -> tuple[int, int]:
    """(u, v): the axes a hole set along ``axis`` spreads along — x→(y, z), y→(z, x), z→(x, y)."""
    return (axis + 1) % 3, (axis + 2) % 3


@dataclass(frozen=True)
class Key:
    """The anti-rotation tongue across the socket floor (M) and the slot it engages in the
    cylinder's end face (F). ``direction`` is a unit vector in the xy plane."""

    width: float
    height: float
    length: float
    direction: np.ndarray

    @property
    def slot_depth(self) -> float:
        """Depth of the slot in the cylinder's end face (nominal), mm."""
        return self.height + KEY_GAP if self.height > 0 else 0.0


@dataclass(frozen=True)
class MountLayout:
    """The mount block in its own frame M (nominal sizes, mm)."""

    width: float
    base_height: float
    socket_depth: float
    socket_diameter: float
    hole_group_z: float
    pitches: dict[str, float]
    holes: tuple[Hole, ...]
    key: Key
    chamfer: float = BLOCK_CHAMFER

    @property
    def height(self) -> float:
        return self.base_height + self.socket_depth

    @property
    def lo(self) -> np.ndarray:
        return np.array([-self.width / 2, -self.width / 2, -self.base_height])

    @property
    def hi(self) -> np.ndarray:
        return np.array([self.width / 2, self.width / 2, self.socket_depth])

    def set(self, axis: str) -> tuple[Hole, ...]:
        """The holes of one set (``"x"``, ``"y"`` or ``"z"``)."""
        return tuple(h for h in self.holes if h.name[0] == axis)


def _hole_sets(design: Design) -> dict[str, HoleSet]:
    m = design.mount
    return {"x": m.holes_x, "y": m.holes_y, "z": m.holes_z}


def _edge_need(hs: HoleSet) -> float:
    """Distance a hole centre keeps from a face in the derived sizes, mm."""
    need = EDGE_FACTOR * hs.diameter
    if hs.counterbore_diameter:
        need = max(need, hs.counterbore_diameter / 2 + DESIGN_WALL)
    return need + SIZE_MARGIN


def _z_pitch(design: Design, hs: HoleSet) -> float:
    """Smallest multiple of the grid whose z holes (and counterbores) clear the socket."""
    grid = design.mount.grid_pitch
    r_out = max(hs.diameter, hs.counterbore_diameter) / 2
    need = design.outer_radius + DESIGN_WALL + SIZE_MARGIN + r_out
    for k in range(1, 1000):
        p = k * grid
        offs = pattern_offsets(hs.pattern, p)
        if min(math.hypot(du, dv) for du, dv in offs) >= need:
            return p
    return grid  # a single hole on the axis never clears; the rules report it


def _xy_hole_heights(sets: dict[str, HoleSet], pitches: dict[str, float]) -> Iterator[tuple[HoleSet, float]]:
    """Each hole of the x and y sets with its height above the sets' common centre, mm."""
    for a in "xy":
        u, _ = spread_axes(_AXES.index(a))
        hs = sets[a]
        for du, dv in pattern_offsets(hs.pattern, pitches[a]):
            yield hs, du if u == 2 else dv


def mount_layout(design: Design) -> MountLayout:
    """The mount of ``design``: block size, socket, key and the three hole sets (M, mm)."""
    m = design.mount
    sets = _hole_sets(design)
    pitches = {
        a: (hs.pitch if hs.pitch is not None else (_z_pitch(design, hs) if a == "z" else m.grid_pitch))
        for a, hs in sets.items()
    }

    # height of the x/y hole group: as high as the socket floor (z = 0) and the top face allow
    z_limits = []
    for hs, dz in _xy_hole_heights(sets, pitches):
        z_limits.append(-(dz + hs.diameter / 2 + DESIGN_WALL + SIZE_MARGIN))  # under the socket floor
        z_limits.append(m.socket_depth - (dz + _edge_need(hs)))  # below the top face
        if hs.counterbore_diameter:
            z_limits.append(m.socket_depth - (dz + hs.counterbore_diameter / 2 + DESIGN_WALL + SIZE_MARGIN))
    zc = min(z_limits)

    if m.base_height is not None:
        base = m.base_height
    else:
        lowest = 0.0
        for hs, dz in _xy_hole_heights(sets, pitches):
            lowest = min(lowest, zc + dz - _edge_need(hs))
        base = float(math.ceil(-lowest - 1e-9))

    centers = {"x": np.array([0.0, 0.0, zc]), "y": np.array([0.0, 0.0, zc]), "z": np.zeros(3)}
    if m.width is not None:
        width = m.width
    else:
        half = design.outer_radius + DESIGN_WALL + SIZE_MARGIN
        for a, hs in sets.items():
            axis = _AXES.index(a)
            u, v = spread_axes(axis)
            for du, dv in pattern_offsets(hs.pattern, pitches[a]):
                c = centers[a].copy()
                c[u] += du
                c[v] += dv
                for k in (u, v):
                    if k < 2:
                        half = max(half, abs(c[k]) + _edge_need(hs))
        width = float(math.ceil(2 * half - 1e-9))

    lo = np.array([-width / 2, -width / 2, -base])
    hi = np.array([width / 2, width / 2, m.socket_depth])
    holes = []
    for a, hs in sets.items():
        axis = _AXES.index(a)
        u, v = spread_axes(axis)
        for i, (du, dv) in enumerate(pattern_offsets(hs.pattern, pitches[a]), start=1):
            c = centers[a].copy()
            c[u] += du
            c[v] += dv
            c[axis] = (lo[axis] + hi[axis]) / 2
            holes.append(
                Hole(
                    f"{a}{i}",
                    axis,
                    c,
                    float(lo[axis]),
                    float(hi[axis]),
                    hs.diameter,
                    hs.counterbore_diameter,
                    hs.counterbore_depth if hs.counterbore_diameter else 0.0,
                )
            )
    phi = m.key_azimuth_rad
    key = Key(m.key_width, m.key_height, design.body.outer_diameter, np.array([math.cos(phi), math.sin(phi), 0.0]))
    return MountLayout(width, base, m.socket_depth, design.body.outer_diameter, zc, pitches, tuple(holes), key)


@dataclass(frozen=True)
class Pin:
    """A dowel pin of the connector: its grid node, axis point on the template face (T) and size."""

    node: tuple[int, int]
    center: np.ndarray
    diameter: float
    length: float
    engagement: float

    @property
    def tip(self) -> np.ndarray:
        """The pin's end inside the template (T)."""
        return self.center + np.array([0.0, 0.0, self.engagement])

    @property
    def base(self) -> np.ndarray:
        """The pin's end inside the connector plate (T)."""
        return self.tip - np.array([0.0, 0.0, self.length])


@dataclass(frozen=True)
class ConnectorLayout:
    """The connector plate in the template frame T (nominal sizes, mm)."""

    lo: np.ndarray
    hi: np.ndarray
    pocket_center: np.ndarray
    pocket_size: float
    pocket_depth: float
    pocket_corner_radius: float
    pins: tuple[Pin, ...]
    holes: tuple[Hole, ...]
    template_from_mount: np.ndarray

    @property
    def size(self) -> np.ndarray:
        return self.hi - self.lo

    @property
    def pocket_lo(self) -> np.ndarray:
        return self.pocket_center[:2] - self.pocket_size / 2

    @property
    def pocket_hi(self) -> np.ndarray:
        return self.pocket_center[:2] + self.pocket_size / 2


def template_rotation(design: Design) -> np.ndarray:
    """Rotation of M (and F) in T: 180° about z for a posterior source, else identity."""
    if design.connector.source_side == "posterior":
        return np.diag([-1.0, -1.0, 1.0])
    return np.eye(3)


def mount_from_fiducial(design: Design) -> np.ndarray:
    """4×4 F → M: the cylinder's ``z = −L/2`` end face rests on the socket floor, axes parallel."""
    T = np.eye(4)
    T[2, 3] = design.half_length
    return T


def template_from_mount(design: Design, layout: MountLayout | None = None) -> np.ndarray:
    """4×4 M → T: the mount's bottom face on the connector's pocket floor (``z_T = −pocket_depth``),
    its axis at ``(axis_x, axis_height)``, turned by :func:`template_rotation`."""
    layout = layout or mount_layout(design)
    c = design.connector
    T = np.eye(4)
    T[:3, :3] = template_rotation(design)
    T[:3, 3] = [c.axis_x, c.axis_height, layout.base_height - c.pocket_depth]
    return T


def template_from_fiducial(design: Design) -> np.ndarray:
    """4×4 F → T: ``template_from_mount · mount_from_fiducial``."""
    return template_from_mount(design) @ mount_from_fiducial(design)


def connector_layout(design: Design, mount: MountLayout | None = None) -> ConnectorLayout:
    """The connector of ``design`` in T: plate, pocket, dowel pins and the tapped holes that
    take the screws of the mount's z hole set."""
    mount = mount or mount_layout(design)
    c = design.connector
    T_TM = template_from_mount(design, mount)
    pocket_c = np.array([c.axis_x, c.axis_height, -c.pocket_depth])
    pins = tuple(
        Pin(
            (int(i), int(j)),
            np.array([i * c.grid_pitch, j * c.grid_pitch, 0.0]),
            c.pin_diameter,
            c.pin_length,
            c.pin_engagement,
        )
        for i, j in c.pins
    )
    holes = []
    for k, p in enumerate(pins, start=1):
        holes.append(
            Hole(
                f"pin{k}",
                2,
                np.array([p.center[0], p.center[1], -c.thickness / 2]),
                -c.thickness,
                0.0,
                c.pin_diameter,
                kind="pin",
            )
        )
    for k, h in enumerate(mount.set("z"), start=1):
        q = T_TM @ np.array([h.center[0], h.center[1], 0.0, 1.0])
        holes.append(
            Hole(f"tap{k}", 2, np.array([q[0], q[1], -c.thickness / 2]), -c.thickness, 0.0, c.tap_drill, kind="tapped")
        )
    half = mount.width / 2 + c.pocket_wall
    xs = [p.center[0] for p in pins]
    ys = [p.center[1] for p in pins]
    lo = np.array(
        [
            min(min(xs) - c.edge_margin, c.axis_x - half),
            min(min(ys) - c.edge_margin, c.axis_height - half),
            -c.thickness,
        ]
    )
    hi = np.array(
        [max(max(xs) + c.edge_margin, c.axis_x + half), max(max(ys) + c.edge_margin, c.axis_height + half), 0.0]
    )
    return ConnectorLayout(
        lo, hi, pocket_c, mount.width, c.pocket_depth, POCKET_CORNER_RADIUS, pins, tuple(holes), T_TM
    )


def transform_points(T: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply a 4×4 homogeneous transform to points (n, 3) or (3,)."""
    p = np.asarray(pts, float)
    return p @ T[:3, :3].T + T[:3, 3]
