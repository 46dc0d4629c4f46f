"""The acetal mount (paper §II.A.3) as a CadQuery solid, in its own frame M.

The mount is a square block (vertical edges chamfered so it seats in the connector's
pocket past the end mill's corner radii) with

- a **socket** for the cylinder's ``z = −L/2`` end, from the top face down to the socket
  floor at ``z = 0`` of M, cut at the profile's press-fit diameter
  (:attr:`~ftrac_design.manufacture.profiles.CutSizes.socket_diameter`);
- a **key** — a tongue across the socket floor — that engages a slot across the
  cylinder's end face (:func:`key_slot_tool`), fixing the cylinder's azimuth positively;
- **three mutually orthogonal sets of through holes** for socket-head cap screws
  (ISO 4762; clearance holes per ISO 273, counterbores for the head), one set along each of
  M's axes, counterbored on the set's ``+`` face, to bolt the mount to a rotary table with
  the fiducial axis vertical or horizontal in two directions.

Where everything sits comes from :func:`ftrac_design.features.mounting.mount_layout`; the
profile only changes how big each hole is cut. The parameter class (:class:`MountPart`)
keeps derived sizes as attributes and has a closed-form volume that the tests compare with
the B-rep.
"""

from __future__ import annotations

import math

import cadquery as cq
import numpy as np

from ..design.schema import Design
from ..features.mounting import Hole, MountLayout, mount_from_fiducial, mount_layout
from ..igt.frames import rigid_inverse
from ..manufacture.profiles import CutSizes, Profile, cut_sizes
from .body import single_solid
from .placement import placed

#: how far a cutting tool reaches past the faces it opens (only keeps the booleans off
#: coincident faces), mm
OVERSHOOT = 0.5


def _v(p) -> cq.Vector:
    return cq.Vector(float(p[0]), float(p[1]), float(p[2]))


def strip_area(radius: float, width: float) -> float:
    """Area of the strip ``|y| ≤ width/2`` inside a circle of ``radius``."""
    h = min(width / 2, radius)
    return 2 * (h * math.sqrt(radius * radius - h * h) + radius * radius * math.asin(h / radius))


class MountPart:
    """The mount of one design under one profile.

    Args:
        layout: nominal geometry in M (:func:`~ftrac_design.features.mounting.mount_layout`).
        cuts: the profile's cut sizes (:func:`~ftrac_design.manufacture.profiles.cut_sizes`).

    Attributes:
        socket_diameter: socket as cut (CNC: cylinder Ø − interference; FDM: Ø + press allowance).
        hole_diameters: each hole's cut diameter, by hole name (nominal + the FDM allowance).
        counterbore_diameters: each counterbore's cut diameter, by hole name.
        key_length: the tongue spans the socket as cut.
    """

    def __init__(self, layout: MountLayout, cuts: CutSizes):
        self.layout = layout
        self.cuts = cuts
        self.socket_diameter = cuts.socket_diameter
        self.hole_diameters = {h.name: cuts.hole(h.diameter) for h in layout.holes}
        self.counterbore_diameters = {
            h.name: cuts.hole(h.counterbore_diameter) for h in layout.holes if h.counterbore_diameter
        }
        self.key_length = cuts.socket_diameter

    @classmethod
    def of(cls, design: Design, profile: Profile = "cnc") -> "MountPart":
        return cls(mount_layout(design), cut_sizes(design, profile))

    # ---- closed forms ---------------------------------------------------------------------
    def nominal_volume(self) -> float:
        """Volume (mm³) in closed form, valid when no two cuts meet (the default layouts):
        block − chamfers − socket + key − holes − counterbores."""
        m = self.layout
        vol = m.width**2 * m.height - 4 * (m.chamfer**2 / 2) * m.height
        rs = self.socket_diameter / 2
        vol -= math.pi * rs * rs * m.socket_depth
        if m.key.height > 0:
            vol += strip_area(rs, m.key.width) * m.key.height
        for h in m.holes:
            r = self.hole_diameters[h.name] / 2
            vol -= math.pi * r * r * h.length
            if h.counterbore_diameter:
                rc = self.counterbore_diameters[h.name] / 2
                vol -= math.pi * (rc * rc - r * r) * h.counterbore_depth
        return vol

    # ---- solids ---------------------------------------------------------------------------
    def hole_tools(self) -> list[cq.Solid]:
        """Every hole and counterbore as a cylinder reaching past the faces."""
        tools = []
        for h in self.layout.holes:
            tools.append(self._cyl(h, self.hole_diameters[h.name] / 2, h.lo - OVERSHOOT, h.hi + OVERSHOOT))
            if h.counterbore_diameter:
                tools.append(
                    self._cyl(h, self.counterbore_diameters[h.name] / 2, h.hi - h.counterbore_depth, h.hi + OVERSHOOT)
                )
        return tools

    @staticmethod
    def _cyl(h: Hole, r: float, a: float, b: float) -> cq.Solid:
        p = np.array(h.center, float)
        p[h.axis] = a
        return cq.Solid.makeCylinder(r, b - a, _v(p), _v(h.direction))

    def key_solid(self) -> cq.Solid | None:
        """The tongue on the socket floor (M), or None when ``key_height`` is 0."""
        k = self.layout.key
        if k.height <= 0:
            return None
        bar = cq.Solid.makeBox(self.key_length, k.width, k.height, cq.Vector(-self.key_length / 2, -k.width / 2, 0))
        ang = math.degrees(math.atan2(k.direction[1], k.direction[0]))
        return bar.rotate(cq.Vector(0, 0, 0), cq.Vector(0, 0, 1), ang)

    def build(self) -> cq.Solid:
        """The mount as one solid in frame M."""
        m = self.layout
        blk = (
            cq.Workplane("XY")
            .box(m.width, m.width, m.height, centered=(True, True, False))
            .translate((0, 0, -m.base_height))
            .edges("|Z")
            .chamfer(m.chamfer)
            .val()
        )
        socket = cq.Solid.makeCylinder(self.socket_diameter / 2, m.socket_depth + OVERSHOOT, cq.Vector(0, 0, 0))
        solid = blk.cut(socket)
        key = self.key_solid()
        if key is not None:
            solid = solid.fuse(key).clean()
        solid = solid.cut(*self.hole_tools())
        return single_solid(solid, "mount")


def key_slot_tool(design: Design, profile: Profile = "cnc", layout: MountLayout | None = None) -> cq.Solid | None:
    """The slot across the cylinder's ``z = −L/2`` end face that takes the mount's key, as a
    cutting tool in F (None without a key). Built in M and placed by
    ``inverse(mount_from_fiducial)``; width = key + the profile's sliding clearance each side,
    depth = key height + :data:`~ftrac_design.design.schema.KEY_GAP`."""
    layout = layout or mount_layout(design)
    k = layout.key
    if k.height <= 0:
        return None
    cuts = cut_sizes(design, profile)
    width = cuts.slide(k.width)
    length = 2 * design.outer_radius + 2 * OVERSHOOT
    box = cq.Solid.makeBox(length, width, k.slot_depth + OVERSHOOT, cq.Vector(-length / 2, -width / 2, -OVERSHOOT))
    ang = math.degrees(math.atan2(k.direction[1], k.direction[0]))
    box = box.rotate(cq.Vector(0, 0, 0), cq.Vector(0, 0, 1), ang)
    return placed(box, rigid_inverse(mount_from_fiducial(design)))


def build_mount(design: Design, profile: Profile = "cnc") -> cq.Solid:
    """The mount of ``design`` under ``profile``, in frame M."""
    return MountPart.of(design, profile).build()
