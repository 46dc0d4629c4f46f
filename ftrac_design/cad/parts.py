"""The bought parts as solids: wires and beads, seated on the feature centre-lines.

They are separate solids for the assembly, the render and the bill of materials; the body
is not cut by them (its grooves and pockets are planned in :mod:`ftrac_design.manufacture.plan`).

- An ellipse wire is a circle of the wire diameter swept once around the seated ellipse
  (a closed ring; in the shop it is a length of wire bent into the groove).
- A line wire is a straight cylinder per piece between beads, butting against the balls
  (:meth:`ftrac_design.features.model.Features.wire_segments`), or one cylinder for a line
  without beads.
- A bead is a sphere of the ball diameter on its seated centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import cadquery as cq
import numpy as np

from ..features.model import Features
from .body import ellipse_wire_solid, volume


@dataclass(frozen=True)
class Part:
    """One bought part as placed in the assembly."""

    name: str
    kind: str  # "wire" or "bead"
    feature: str  # the feature id it realises
    solid: cq.Solid

    @property
    def volume(self) -> float:
        return volume(self.solid)


def _v(p) -> cq.Vector:
    return cq.Vector(float(p[0]), float(p[1]), float(p[2]))


def wire_parts(features: Features, z_extent: float) -> list[Part]:
    """Every wire piece: ``wire_<ellipse id>`` and ``wire_<line id>_<k>`` (k = 1, 2, … from start)."""
    out = [Part(f"wire_{e.id}", "wire", e.id, ellipse_wire_solid(e, z_extent)) for e in features.ellipses]
    for ln in features.lines:
        for k, (a, b) in enumerate(features.wire_segments(ln.id), start=1):
            d = np.asarray(b) - np.asarray(a)
            solid = cq.Solid.makeCylinder(ln.wire_diameter / 2, float(np.linalg.norm(d)), _v(a), _v(d))
            out.append(Part(f"wire_{ln.id}_{k}", "wire", ln.id, solid))
    return out


def bead_parts(features: Features) -> list[Part]:
    """Every bead as a sphere named ``bead_<point id>``."""
    return [
        Part(
            f"bead_{p.id}",
            "bead",
            p.id,
            cq.Solid.makeSphere(p.diameter / 2, _v(p.center), angleDegrees1=-90, angleDegrees2=90),
        )
        for p in features.points
    ]
