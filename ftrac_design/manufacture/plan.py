"""Where the body is cut: the grooves and pockets as plain numbers (no CadQuery here).

Every cut is derived from the *seated* features of :mod:`ftrac_design.features` and the
profile's cut sizes, so the cut that holds a wire and the centre-line the solver uses cannot
drift apart:

- **Groove floor** = seated centre-line minus one wire radius (radially inward): the wire
  rests on the floor and its centre lies exactly on the centre-line.
- **Groove walls** are parallel to the surface normal at the centre-line, half a groove
  width to either side (what a radial end mill on a 4-axis mill cuts); they run from the
  floor up through the outer surface and on by :attr:`BodyPlan.overshoot` so that the
  boolean never has to cut along a coincident surface.
- **Pocket**: a flat-bottomed radial hole on the bead's radial line, floor one ball radius
  below the bead centre, open to the surface.

Line wires sit deeper than ellipse wires (the design validator guarantees a radial step of
at least one wire diameter), so where a line crosses an ellipse the line wire passes under
the ellipse wire: the ellipse groove's floor is above the line wire's top, and the ellipse
wire bridges the line groove.

All lengths mm, frame F (SPEC §1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..design.schema import Design
from ..features.model import EllipseFeature, Features, LineFeature, PointFeature
from .profiles import CutSizes

#: how far every cutting tool reaches beyond the outer surface, as a fraction of the outer
#: radius, with a floor (mm). Only keeps the booleans away from coincident faces.
OVERSHOOT_FRACTION = 0.02
OVERSHOOT_MIN = 0.2


def radial_unit(p: np.ndarray) -> np.ndarray:
    """Unit vector from the body axis (z) toward point ``p`` (F)."""
    u = np.array([p[0], p[1], 0.0], float)
    n = float(np.linalg.norm(u))
    if n < 1e-12:
        raise ValueError(f"point {p} lies on the body axis; it has no radial direction")
    return u / n


def seat_radius(p: np.ndarray) -> float:
    """Distance of ``p`` from the body axis, mm."""
    return float(math.hypot(p[0], p[1]))


@dataclass(frozen=True)
class EllipseGroove:
    """A rectangular groove swept along an ellipse centre-line with the surface-normal frame.

    In the plane normal to the wire the section spans ``[-floor_depth, top_height]`` along
    the outward surface normal and ``±width/2`` across.
    """

    feature: EllipseFeature
    seat_radius: float
    width: float
    floor_depth: float
    top_height: float


@dataclass(frozen=True)
class LineGroove:
    """A straight slot along a line wire (parallel to z) with walls parallel to its radial plane."""

    feature: LineFeature
    radial: np.ndarray
    tangential: np.ndarray
    floor_radius: float
    top_radius: float
    width: float
    z0: float
    z1: float


@dataclass(frozen=True)
class Pocket:
    """A flat-bottomed radial hole for one bead: cylinder from ``floor`` along ``axis``."""

    feature: PointFeature
    axis: np.ndarray
    floor: np.ndarray
    diameter: float
    depth: float


@dataclass(frozen=True)
class BodyPlan:
    """The body blank and every cut, ready for :func:`ftrac_design.cad.body.build_body`."""

    outer_radius: float
    bore_radius: float
    half_length: float
    overshoot: float
    ellipse_grooves: tuple[EllipseGroove, ...]
    line_grooves: tuple[LineGroove, ...]
    pockets: tuple[Pocket, ...]

    @property
    def n_cuts(self) -> int:
        """Grooves and pockets in all."""
        return len(self.ellipse_grooves) + len(self.line_grooves) + len(self.pockets)


def plan_body(design: Design, features: Features, cuts: CutSizes) -> BodyPlan:
    """All cuts of ``design``'s body for the cut sizes of one manufacturing profile."""
    R = design.outer_radius
    over = max(OVERSHOOT_MIN, OVERSHOOT_FRACTION * R)
    ell = []
    for e in features.ellipses:
        if abs(e.minor_axis[2]) > 1e-12 or np.linalg.norm(e.center[:2]) > 1e-12:
            raise ValueError(f"ellipse {e.id} does not lie on a cylinder about the body axis")
        rs = e.semi_minor  # the seated ellipse lies on the cylinder of radius b about z
        ell.append(EllipseGroove(e, rs, cuts.groove_width, e.wire_diameter / 2, R - rs + over))
    lines = []
    for ln in features.lines:
        u = radial_unit(ln.start)
        rs = seat_radius(ln.start)
        lines.append(
            LineGroove(
                ln,
                u,
                np.cross([0.0, 0.0, 1.0], u),
                rs - ln.wire_diameter / 2,
                R + over,
                cuts.groove_width,
                float(ln.start[2]),
                float(ln.end[2]),
            )
        )
    pockets = []
    for p in features.points:
        u = radial_unit(p.center)
        floor = p.center - u * (p.diameter / 2)
        depth = R + over - seat_radius(floor)
        pockets.append(Pocket(p, u, floor, cuts.pocket_diameter, depth))
    return BodyPlan(R, design.bore_radius, design.half_length, over, tuple(ell), tuple(lines), tuple(pockets))


#: absolute chord tolerance (mm) and angular tolerance (rad) of the mount's and connector's STLs
FIXTURE_STL_TOLERANCE = (0.01, 0.1)
#: an STL's enclosed volume must agree with the exact B-rep volume to this fraction
STL_VOLUME_TOLERANCE = 0.005


def stl_tolerances(cuts: CutSizes, design: Design) -> tuple[float, float]:
    """(chord tolerance mm, angular tolerance rad) for the body's STL.

    The chord tolerance is 1/40 of the narrowest cut (0.012 mm for a 0.48 mm groove,
    0.007 mm for 0.28 mm), capped at 0.01 mm, so the groove walls and floor are resolved
    to a few per cent of the groove width; the angular tolerance 0.1 rad keeps small arcs
    (the pockets) to at least 63 segments per turn.
    """
    sizes = [s for s in (cuts.groove_width, cuts.pocket_diameter) if s > 0]
    narrowest = min(sizes) if sizes else design.body.outer_diameter
    return min(0.01, narrowest / 40.0), 0.1
