"""The template connector (paper §IV, Fig. 10a) as a CadQuery solid, in the template frame T.

A plate that lies on the template's front face (``z ∈ [−thickness, 0]`` of T):

- two **dowel-pin holes** on grid nodes of the template (``connector.pins``), through the
  plate, cut at the profile's press-fit size; the pins (ISO 2338, m6) stand
  ``pin_engagement`` proud of the ``z = 0`` face and enter the template's grid holes;
- a **pocket** in the ``z = 0`` face above the template's top edge that takes the mount's
  block with a sliding fit (positive location in x, y and rotation; its floor locates z),
  corners rounded by the Ø3 end mill (the mount's chamfered edges clear them);
- **tapped holes** (M4, tap drill 3.3 mm — ISO 2306 / DIN 336) under the pocket, one per
  hole of the mount's z set, for the screws that hold the mount down.

Positions come from :func:`ftrac_design.features.mounting.connector_layout`; the profile
changes only the cut sizes.
"""

from __future__ import annotations

import math

import cadquery as cq
import numpy as np

from ..design.schema import Design
from ..features.mounting import ConnectorLayout, Pin, connector_layout
from ..manufacture.profiles import CutSizes, Profile, cut_sizes
from .body import single_solid

OVERSHOOT = 0.5


def _v(p) -> cq.Vector:
    return cq.Vector(float(p[0]), float(p[1]), float(p[2]))


class ConnectorPart:
    """The connector of one design under one profile.

    Args:
        layout: nominal geometry in T (:func:`~ftrac_design.features.mounting.connector_layout`).
        cuts: the profile's cut sizes.

    Attributes:
        pin_hole_diameter: dowel-pin holes as cut (CNC: pin − interference; FDM: pin + press allowance).
        tap_hole_diameter: tap drill as cut (nominal + the FDM hole allowance).
        pocket_size: the pocket's side as cut (mount width + sliding clearance each side).
    """

    def __init__(self, layout: ConnectorLayout, cuts: CutSizes):
        self.layout = layout
        self.cuts = cuts
        self.pin_hole_diameter = cuts.pin_hole_diameter
        taps = [h for h in layout.holes if h.kind == "tapped"]
        self.tap_hole_diameter = cuts.hole(taps[0].diameter) if taps else 0.0
        self.pocket_size = cuts.slide(layout.pocket_size)

    @classmethod
    def of(cls, design: Design, profile: Profile = "cnc") -> "ConnectorPart":
        return cls(connector_layout(design), cut_sizes(design, profile))

    def hole_diameter(self, kind: str) -> float:
        return self.pin_hole_diameter if kind == "pin" else self.tap_hole_diameter

    def nominal_volume(self) -> float:
        """Volume (mm³) in closed form: plate − pocket (square with rounded corners) − holes
        (tapped holes only below the pocket floor)."""
        k = self.layout
        sx, sy, t = (float(x) for x in k.size)
        r = k.pocket_corner_radius
        vol = sx * sy * t - (self.pocket_size**2 - (4 - math.pi) * r * r) * k.pocket_depth
        for h in k.holes:
            rr = self.hole_diameter(h.kind) / 2
            length = t - k.pocket_depth if h.kind == "tapped" else t
            vol -= math.pi * rr * rr * length
        return vol

    def pocket_tool(self) -> cq.Solid:
        k = self.layout
        s = self.pocket_size
        depth = k.pocket_depth + OVERSHOOT
        return (
            cq.Workplane("XY")
            .box(s, s, depth, centered=(True, True, False))
            .edges("|Z")
            .fillet(k.pocket_corner_radius)
            .val()
            .translate(cq.Vector(float(k.pocket_center[0]), float(k.pocket_center[1]), -k.pocket_depth))
        )

    def hole_tools(self) -> list[cq.Solid]:
        out = []
        for h in self.layout.holes:
            p = np.array(h.center, float)
            p[2] = h.lo - OVERSHOOT
            out.append(
                cq.Solid.makeCylinder(
                    self.hole_diameter(h.kind) / 2, h.length + 2 * OVERSHOOT, _v(p), cq.Vector(0, 0, 1)
                )
            )
        return out

    def build(self) -> cq.Solid:
        """The connector as one solid in frame T."""
        k = self.layout
        sx, sy, t = (float(x) for x in k.size)
        plate = cq.Solid.makeBox(sx, sy, t, _v(k.lo))
        return single_solid(plate.cut(self.pocket_tool(), *self.hole_tools()), "connector")


def pin_solid(pin: Pin) -> cq.Solid:
    """One dowel pin (ISO 2338 form A: plain cylinder) in T."""
    return cq.Solid.makeCylinder(pin.diameter / 2, pin.length, _v(pin.base), cq.Vector(0, 0, 1))


def build_connector(design: Design, profile: Profile = "cnc") -> cq.Solid:
    """The connector of ``design`` under ``profile``, in frame T."""
    return ConnectorPart.of(design, profile).build()
