"""Manufacturing profiles: how big to cut each groove, pocket and hole.

A profile changes cut sizes only, never the feature geometry: every wire still seats with
its centre on the feature centre-line and every ball with its centre on the bead point,
because groove floors and pocket floors stay where the seating depth puts them (the wire
and ball rest on the floor); only widths and diameters change.

- ``cnc`` — acetal milled on a 4-axis mill, wires and balls pressed in (paper §II.A.3).
  Default interference 0.02 mm on the diameter for both the 0.5 mm wire and the 2 mm ball.
  No published press-fit figure for steel wire or balls in POM was found; this is a
  reasoned choice, not a measured one: POM's modulus (2.8–3.5 GPa) is ~1/60 of steel's, so
  the plastic takes all the strain, and 0.02 mm (1 % of the ball diameter) is a light
  interference that presses in by hand tool without splitting the thin groove walls. It is
  smaller than the ±0.05 mm that common CNC guides quote for critical features, so the
  drawing must call out these widths as critical, and plastics creep so press fits loosen:
  confirm on a test coupon of groove widths in 0.02 mm steps before a production run.
- ``fdm`` — a 0.4 mm nozzle, wires and balls glued in: 0.15 mm gap per side (the
  0.10–0.15 press / 0.2–0.3 slide range of FDM fit guides, at the tight end because glue
  fills it) and round holes enlarged by 0.2 mm because FDM prints holes undersize.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..design.schema import Design

Profile = Literal["cnc", "fdm"]
PROFILES: tuple[Profile, ...] = ("cnc", "fdm")


@dataclass(frozen=True)
class CutSizes:
    """Sizes of the cuts that receive bought parts, mm.

    ``groove_width``: across a wire groove, measured on the surface normal plane.
    ``pocket_diameter``: bead pocket (a flat-bottomed radial hole).
    ``hole_allowance``: added to the diameter of every round hole in mount and connector.
    """

    profile: Profile
    groove_width: float
    pocket_diameter: float
    hole_allowance: float
    fit: str

    def as_dict(self) -> dict[str, float | str]:
        """Plain-JSON form for the manifest."""
        return {"profile": self.profile, "groove_width": self.groove_width,
                "pocket_diameter": self.pocket_diameter, "hole_allowance": self.hole_allowance,
                "fit": self.fit}


def cut_sizes(design: Design, profile: Profile = "cnc") -> CutSizes:
    """Cut sizes for ``design`` under ``profile`` (mm)."""
    wd = design.wire.diameter if design.wire else 0.0
    bd = design.bead.diameter if design.bead else 0.0
    if profile == "cnc":
        p = design.manufacturing.cnc
        return CutSizes("cnc", wd - p.wire_interference if wd else 0.0,
                        bd - p.bead_interference if bd else 0.0, 0.0,
                        f"press fit: {p.wire_interference} mm (wire) / {p.bead_interference} mm (ball) interference")
    if profile == "fdm":
        p = design.manufacturing.fdm
        return CutSizes("fdm", wd + 2 * p.wire_clearance if wd else 0.0,
                        bd + 2 * p.bead_clearance if bd else 0.0, p.hole_allowance,
                        f"glued: {p.wire_clearance} mm (wire) / {p.bead_clearance} mm (ball) gap per side")
    raise ValueError(f"unknown profile {profile!r}; expected one of {PROFILES}")
