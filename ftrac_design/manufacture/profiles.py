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

Mount and connector (paper §II.A.3, §IV), same two profiles:

- ``cnc`` — the socket that takes the cylinder's end is a press fit with 0.05 mm diametral
  interference (``socket_interference``; for a metal part ISO 286 H7/p6 at Ø18–30 gives
  0.001–0.035 mm; POM on POM is ~60× less stiff than steel and creeps, so we take a little
  more — again a reasoned choice to confirm on a coupon). The dowel pins are pressed into
  the connector with 0.02 mm interference (as for the balls). The sliding fits — the mount
  in the connector's pocket and the key in the cylinder's slot — get 0.025 mm per side
  (ISO 286 H7/g6 at 50–80 mm: 0.010–0.059 mm on the diameter). Screw holes are cut at their
  nominal (ISO 273 clearance) size.
- ``fdm`` — press fits (socket, dowel pins) are printed 0.1 mm over nominal ("press +0.1",
  layer-one), sliding fits get 0.2 mm per side ("slide 0.2–0.3", printparams), and every
  other round hole (screw clearance holes, counterbores, tap drills) is enlarged by
  ``hole_allowance`` = 0.2 mm because FDM prints holes undersize.

:func:`rule_limits` gives each profile's design-rule limits (minimum walls, smallest tool,
depth-to-tool ratio, tolerance) with their sources (``docs/reference/manufacturing.md``).
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
    ``hole_allowance``: added to the diameter of every screw clearance hole, counterbore and
    tap drill in mount and connector.
    ``socket_diameter``: the mount's socket for the cylinder end (press fit).
    ``pin_hole_diameter``: the connector's holes for the template dowel pins (press fit).
    ``slide_clearance``: gap per side of the sliding fits: the connector's pocket around the
    mount block and the cylinder's end slot around the mount's key.
    """

    profile: Profile
    groove_width: float
    pocket_diameter: float
    hole_allowance: float
    fit: str
    socket_diameter: float = 0.0
    pin_hole_diameter: float = 0.0
    slide_clearance: float = 0.0

    def hole(self, nominal: float) -> float:
        """Cut diameter of a screw clearance hole, counterbore or tap drill of ``nominal`` size."""
        return nominal + self.hole_allowance if nominal > 0 else 0.0

    def slide(self, nominal: float) -> float:
        """Cut width of a sliding-fit opening for a part ``nominal`` wide."""
        return nominal + 2 * self.slide_clearance

    def as_dict(self) -> dict[str, float | str]:
        """Plain-JSON form for the manifest."""
        return {
            "profile": self.profile,
            "groove_width": self.groove_width,
            "pocket_diameter": self.pocket_diameter,
            "hole_allowance": self.hole_allowance,
            "socket_diameter": self.socket_diameter,
            "pin_hole_diameter": self.pin_hole_diameter,
            "slide_clearance": self.slide_clearance,
            "fit": self.fit,
        }


def cut_sizes(design: Design, profile: Profile = "cnc") -> CutSizes:
    """Cut sizes for ``design`` under ``profile`` (mm)."""
    wd = design.wire.diameter if design.wire else 0.0
    bd = design.bead.diameter if design.bead else 0.0
    od, pin = design.body.outer_diameter, design.connector.pin_diameter
    if profile == "cnc":
        p = design.manufacturing.cnc
        return CutSizes(
            "cnc",
            wd - p.wire_interference if wd else 0.0,
            bd - p.bead_interference if bd else 0.0,
            0.0,
            f"press fit: {p.wire_interference} mm (wire) / {p.bead_interference} mm (ball) interference",
            od - p.socket_interference,
            pin - p.pin_interference,
            p.slide_clearance,
        )
    if profile == "fdm":
        p = design.manufacturing.fdm
        return CutSizes(
            "fdm",
            wd + 2 * p.wire_clearance if wd else 0.0,
            bd + 2 * p.bead_clearance if bd else 0.0,
            p.hole_allowance,
            f"glued: {p.wire_clearance} mm (wire) / {p.bead_clearance} mm (ball) gap per side",
            od + p.press_allowance,
            pin + p.press_allowance,
            p.slide_clearance,
        )
    raise ValueError(f"unknown profile {profile!r}; expected one of {PROFILES}")


@dataclass(frozen=True)
class RuleLimits:
    """Design-rule limits of one profile (mm unless stated). See :mod:`ftrac_design.manufacture.rules`.

    ``min_wall``: thinner is a violation; ``recommended_wall``: thinner is a warning.
    ``tool``: the smallest cutter (CNC end mill) or bead (FDM nozzle) that shapes a groove.
    ``max_depth_ratio`` / ``recommended_depth_ratio``: groove depth over tool diameter (CNC).
    ``tolerance``: the process's positional accuracy, used as a recommended clearance.
    """

    profile: Profile
    min_wall: float
    recommended_wall: float
    tool: float
    tool_name: str
    max_depth_ratio: float | None
    recommended_depth_ratio: float | None
    tolerance: float
    sources: dict[str, str]


#: CNC limits: zekes3d CNC design guide and Neptune Labs (plastic wall ≥ 1.5 mm
#: recommended, 1.0 mm feasible); common CNC guides (pocket depth ≤ 3–4 × tool diameter;
#: ±0.05 mm on critical features)
CNC_WALL_MIN = 1.0
CNC_WALL_RECOMMENDED = 1.5
CNC_DEPTH_RATIO_MAX = 4.0
CNC_DEPTH_RATIO_RECOMMENDED = 3.0
CNC_TOLERANCE = 0.05
#: FDM limits for a 0.4 mm nozzle: printparams and layer-one (0.8 mm = 2 perimeters minimum,
#: 1.2–1.6 mm recommended); printparams "real-world fit" (accuracy about ±0.2 mm)
FDM_WALL_MIN = 0.8
FDM_WALL_RECOMMENDED = 1.2
FDM_TOLERANCE = 0.2


def rule_limits(design: Design, profile: Profile = "cnc") -> RuleLimits:
    """Limits that ``ftrac-design check`` applies to ``design`` under ``profile``."""
    if profile == "cnc":
        return RuleLimits(
            "cnc",
            CNC_WALL_MIN,
            CNC_WALL_RECOMMENDED,
            design.manufacturing.cnc.tool_diameter,
            "end-mill diameter (manufacturing.cnc.tool_diameter)",
            CNC_DEPTH_RATIO_MAX,
            CNC_DEPTH_RATIO_RECOMMENDED,
            CNC_TOLERANCE,
            {
                "wall": "zekes3d CNC design guide; Neptune Labs: plastic wall >= 1.5 mm recommended, 1.0 mm feasible",
                "tool": "an end mill cannot cut a slot narrower than itself (runout)",
                "depth": "common CNC guides: pocket depth <= 3-4 x tool diameter",
                "tolerance": "common CNC guides: +-0.05 mm on critical features",
            },
        )
    if profile == "fdm":
        return RuleLimits(
            "fdm",
            FDM_WALL_MIN,
            FDM_WALL_RECOMMENDED,
            design.manufacturing.fdm.nozzle_diameter,
            "nozzle width (manufacturing.fdm.nozzle_diameter)",
            None,
            None,
            FDM_TOLERANCE,
            {
                "wall": "printparams, layer-one: 0.8 mm (2 perimeters of a 0.4 mm nozzle) minimum, 1.2-1.6 recommended",
                "tool": "a printed gap narrower than one extrusion width closes up",
                "depth": "no depth limit for printed grooves",
                "tolerance": "printparams 'real-world fit': FDM accuracy about +-0.2 mm",
            },
        )
    raise ValueError(f"unknown profile {profile!r}; expected one of {PROFILES}")


#: general tolerance of a milled dimension not called out otherwise: common CNC guides, ±0.13 mm
CNC_GENERAL_TOLERANCE = 0.13


@dataclass(frozen=True)
class DrawingTolerances:
    """The ± tolerances a drawing prints under one profile (mm; angles in degrees at the edge).

    ``general``: every dimension not marked otherwise (CNC: ±0.13 mm, common CNC guides;
    FDM: ±0.2 mm, the process's accuracy). ``critical``: fit-critical sizes and the feature
    positions the tracker relies on (CNC: ±0.05 mm, :data:`CNC_TOLERANCE`; FDM: ±0.2 mm,
    nothing tighter is printable). An azimuth A is toleranced so that its arc on the outer
    surface stays within ``critical``: :meth:`angle_deg`.
    """

    profile: Profile
    general: float
    critical: float

    def angle_deg(self, radius: float) -> float:
        """± tolerance (degrees) of an azimuth measured on a surface of ``radius`` mm."""
        import math

        return math.degrees(self.critical / radius)


def drawing_tolerances(profile: Profile = "cnc") -> DrawingTolerances:
    """The tolerances the drawings of ``profile`` state."""
    if profile == "cnc":
        return DrawingTolerances("cnc", CNC_GENERAL_TOLERANCE, CNC_TOLERANCE)
    if profile == "fdm":
        return DrawingTolerances("fdm", FDM_TOLERANCE, FDM_TOLERANCE)
    raise ValueError(f"unknown profile {profile!r}; expected one of {PROFILES}")


#: FDM print settings the fdm profile's cut sizes and wall rules assume, as fractions or
#: counts (OrcaSlicer's layer-height guide: layer height 20–80 % of the nozzle, first layer
#: about 50 %; the wall rules count perimeters of one nozzle width)
FDM_LAYER_FRACTION = 0.25
FDM_FIRST_LAYER_FRACTION = 0.5


@dataclass(frozen=True)
class PrintSettings:
    """What the slicer must be set to for the fdm profile's sizes to hold (mm unless stated).

    ``line_width`` = the nozzle: the wall rules (0.8 mm minimum = 2 perimeters) and the
    narrowest printable gap assume one nozzle width per line. ``layer_height`` = 25 % of the
    nozzle, the fine end of the 20–80 % range, because a 0.6 mm groove on a tilted ellipse is
    resolved in z by the layers. ``perimeters``: enough lines to make the recommended wall
    (1.2 mm) solid. ``infill_percent`` = 100: the X-ray model takes the body as solid
    plastic, so partial infill would change its attenuation. ``xy_hole_compensation`` = 0:
    the CAD already enlarges holes (``hole_allowance``, clearances), the slicer must not
    do it again.
    """

    nozzle_diameter: float
    line_width: float
    layer_height: float
    first_layer_height: float
    perimeters: int
    infill_percent: int
    xy_hole_compensation: float
    sources: dict[str, str]

    def as_dict(self) -> dict[str, object]:
        """Plain-JSON form."""
        return {
            "nozzle_diameter_mm": self.nozzle_diameter,
            "line_width_mm": self.line_width,
            "layer_height_mm": self.layer_height,
            "first_layer_height_mm": self.first_layer_height,
            "perimeters": self.perimeters,
            "infill_percent": self.infill_percent,
            "xy_hole_compensation_mm": self.xy_hole_compensation,
            "sources": dict(self.sources),
        }


def print_settings(design: Design) -> PrintSettings:
    """The slicer settings that ``design``'s fdm cut sizes assume."""
    import math

    nozzle = design.manufacturing.fdm.nozzle_diameter
    return PrintSettings(
        nozzle,
        nozzle,
        round(FDM_LAYER_FRACTION * nozzle, 4),
        round(FDM_FIRST_LAYER_FRACTION * nozzle, 4),
        math.ceil(FDM_WALL_RECOMMENDED / nozzle - 1e-9),
        100,
        0.0,
        {
            "line_width": "one nozzle width per line: the wall rules (printparams, layer-one: 0.8 mm = 2 perimeters "
            "of a 0.4 mm nozzle)",
            "layer_height": "OrcaSlicer layer-height guide: 20-80 % of the nozzle; the fine end for the grooves",
            "first_layer_height": "OrcaSlicer layer-height guide: first layer about 50 % of the nozzle",
            "perimeters": "recommended wall 1.2 mm (printparams, layer-one) in whole lines",
            "infill_percent": "the X-ray model (xray.Body) takes the body as solid plastic",
            "xy_hole_compensation": "the CAD already adds the fdm profile's hole allowance and clearances",
        },
    )
