"""The press-fit test coupon: groove widths and pocket diameters stepped around the profile's
values, cut the way the body is cut, so a shop finds which step holds its wire and balls.

The coupon is a solid cylinder of the body's outer diameter (the same A-axis set-up, the same
tools), ``GRIP`` mm at its ``−z`` end left plain for the chuck. Along it, one band of axial
slots — one per groove width — and one ring of pockets — one per pocket diameter — at the
body's seating depths (the line wires' and their beads', or the ellipse wires' and the free
beads' when the design has no lines). Slot ``k`` sits at azimuth ``k·360°/n``, pocket ``k``
half a spacing further round; each size is engraved on the ``+z`` end face on the radius of
its cut, reading outward, and listed in ``coupon.csv`` with its azimuth (= A on the machine)
and the interference (cnc: part − cut) or gap per side (fdm: (cut − part)/2) it gives.

:func:`plan_coupon` is plain numbers (no CadQuery); :func:`ftrac_design.cad.coupon.build_coupon`
makes the solid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..design.schema import Design
from ..machining.model import CutPlan, PocketCut, SlotCut, Stock, pocket_tool_diameter
from ..machining.simulate import Verification
from .profiles import Profile, cut_sizes, rule_limits

#: plain length at the −z end for the chuck, mm
GRIP = 5.0
#: slot length, mm (room to press in a piece of wire)
SLOT_LENGTH = 8.0
#: default step between sizes, mm: cnc 0.01 (the interference decides in hundredths), fdm 0.05
STEP = {"cnc": 0.01, "fdm": 0.05}
#: engraving depth of the size labels, mm
ENGRAVE_DEPTH = 0.1


@dataclass(frozen=True)
class CouponStep:
    """One cut of the coupon: ``kind`` groove|pocket, its ``size`` (width or diameter, mm), the
    bought part's diameter, ``fit`` (cnc: interference part − cut; fdm: gap per side, mm)."""

    kind: str
    index: int
    azimuth: float
    size: float
    part_diameter: float
    fit: float

    @property
    def label(self) -> str:
        """The size as engraved: three decimals, mm."""
        return f"{self.size:.3f}"

    @property
    def id(self) -> str:
        """``W<size>`` for a groove, ``P<size>`` for a pocket."""
        return f"{'W' if self.kind == 'groove' else 'P'}{self.label}"


@dataclass(frozen=True)
class Coupon:
    """The coupon's stock, steps and the cuts as the machining room takes them."""

    design: str
    profile: Profile
    stock: Stock
    steps: tuple[CouponStep, ...]
    plan: CutPlan
    step_mm: float
    label_height: float
    min_wall: float


def thinnest_wall(plan: CutPlan) -> float:
    """The thinnest material (mm) between two neighbouring cuts of a coupon: slots side by side
    (at their floors, where the ring is smallest), pockets side by side, and the slot band
    against the pocket ring along z."""
    walls = [math.inf]
    for group in (plan.slots, plan.pockets):
        if len(group) > 1:
            n = len(group)
            r = min(c.floor_radius for c in group)
            size = max(c.width if isinstance(c, SlotCut) else c.diameter for c in group)
            walls.append(2 * r * math.sin(math.pi / n) - size)
    if plan.slots and plan.pockets:
        top = max(s.z1 + s.end_radius for s in plan.slots)
        bottom = min(p.z - p.diameter / 2 for p in plan.pockets)
        walls.append(bottom - top)
    return min(walls)


def _sizes(nominal: float, step: float, count: int, smallest: float) -> list[float]:
    half = count // 2
    sizes = [round(nominal + step * (k - half), 6) for k in range(count)]
    shift = max(0.0, smallest - sizes[0])  # never narrower than the tool that cuts it
    return [round(s + shift, 6) for s in sizes]


def plan_coupon(design: Design, profile: Profile = "cnc", step: float | None = None, count: int = 7) -> Coupon:
    """The coupon for ``design``'s wire and balls under ``profile``: ``count`` groove widths and
    ``count`` pocket diameters, ``step`` mm apart (default :data:`STEP`), centred on the profile's."""
    step = STEP[profile] if step is None else step
    if step <= 0 or count < 1:
        raise ValueError("a positive step and at least one size")
    cuts, cnc = cut_sizes(design, profile), design.manufacturing.cnc
    R = design.outer_radius
    seat = design.seating.line_wire_depth if design.lines else design.seating.ellipse_wire_depth
    bead_seat = design.seating.line_wire_depth if design.lines else design.free_bead_depth
    steps: list[CouponStep] = []
    slots, pockets = [], []
    z_slot0 = -SLOT_LENGTH / 2 - 1.0  # the band below the middle, pockets above
    n = max(1, count)
    if design.wire is not None:
        wd = design.wire.diameter
        for k, w in enumerate(_sizes(cuts.groove_width, step, count, cnc.tool_diameter)):
            az = 2 * math.pi * k / n
            fit = wd - w if profile == "cnc" else (w - wd) / 2
            s = CouponStep("groove", k, az, w, wd, round(fit, 6))
            steps.append(s)
            slots.append(
                SlotCut(
                    s.id,
                    az,
                    R - seat - wd / 2,
                    R + 0.2,
                    w,
                    z_slot0 - SLOT_LENGTH / 2,
                    z_slot0 + SLOT_LENGTH / 2,
                    cnc.tool_diameter / 2,
                )
            )
    pocket_z = 0.0
    if design.bead is not None:
        bd = design.bead.diameter
        sizes = _sizes(cuts.pocket_diameter, step, count, 0.0)
        tool = pocket_tool_diameter(sizes[0], cnc.pocket_tool_diameter)
        if tool < sizes[-1] / 2:
            raise ValueError(
                f"one pocket end mill ({tool:g} mm) cannot clear pockets from {sizes[0]:g} to "
                f"{sizes[-1]:g} mm; use a smaller step or fewer sizes"
            )
        pocket_z = bd / 2 + 1.0
        for k, p in enumerate(sizes):
            az = 2 * math.pi * (k + 0.5) / n
            fit = bd - p if profile == "cnc" else (p - bd) / 2
            s = CouponStep("pocket", k, az, p, bd, round(fit, 6))
            steps.append(s)
            floor = R - bead_seat - bd / 2
            pockets.append(PocketCut(s.id, az, pocket_z, floor, p, R + 0.2 - floor))
    top = pocket_z + (design.bead.diameter / 2 + 1.5 if design.bead is not None else 0.0)
    bottom = (z_slot0 - SLOT_LENGTH / 2 - cnc.tool_diameter / 2 if design.wire is not None else 0.0) - GRIP
    half = (top - bottom) / 2
    shift = (top + bottom) / 2  # F's origin at mid-length, as on the body
    slots = [
        SlotCut(s.id, s.azimuth, s.floor_radius, s.top_radius, s.width, s.z0 - shift, s.z1 - shift, s.end_radius)
        for s in slots
    ]
    pockets = [PocketCut(p.id, p.azimuth, p.z - shift, p.floor_radius, p.diameter, p.depth) for p in pockets]
    stock = Stock(R, 0.0, half)
    label = min(1.5, 0.8 * 2 * math.pi * 0.6 * R / (2 * n), 0.8 * R / 5.5)
    plan = CutPlan(f"{design.name}_coupon", stock, (), tuple(slots), tuple(pockets))
    wall, limit = thinnest_wall(plan), rule_limits(design, profile).min_wall
    if wall < limit:  # the design rules' minimum wall (manufacture.rules, wall rules)
        raise ValueError(
            f"the coupon's thinnest wall is {wall:.3f} mm, below the {profile} minimum {limit:g} mm; use fewer sizes"
        )
    return Coupon(design.name, profile, stock, tuple(steps), plan, step, label, wall)


def coupon_csv(c: Coupon) -> str:
    """The steps table: what the shop fills in (``holds``) after pressing in its wire and balls."""
    fit = "interference_mm" if c.profile == "cnc" else "gap_per_side_mm"
    rows = [f"kind,index,size_mm,a_deg,part_diameter_mm,{fit},holds"]
    for s in c.steps:
        rows.append(f"{s.kind},{s.index},{s.size:.3f},{math.degrees(s.azimuth):.2f},{s.part_diameter:g},{s.fit:+.3f},")
    return "\n".join(rows) + "\n"


@dataclass(frozen=True)
class CouponProgram:
    """The coupon's 4-axis program, read back and verified against the coupon's cuts."""

    filename: str
    text: str
    cycle_time_s: dict[str, float]
    verification: Verification

    def verify_document(self) -> dict:
        """``<program>.verify.json``: the cycle time and the verification."""
        return {"cycle_time_s": self.cycle_time_s, **self.verification.as_dict()}


def coupon_program(c: Coupon, post: str, cnc) -> CouponProgram:
    """Plan, post, read back and verify the coupon's program (cnc), the way the body's is.

    Parameters
    ----------
    c : Coupon
        The coupon's plan.
    post : str
        The control (a key of :data:`ftrac_design.machining.post.POSTS`).
    cnc : ftrac_design.design.schema.CncProfile
        The design's CNC settings (its end mills).

    Returns
    -------
    CouponProgram
        The program and its verification.
    """
    from ..machining.gcode import cycle_time, parse_gcode
    from ..machining.model import tooling
    from ..machining.post import POSTS, emit
    from ..machining.simulate import verify
    from ..machining.toolpath import plan_program

    pockets = [p.diameter for p in c.plan.pockets]
    tools = tooling(cnc, min(pockets) if pockets else None)
    text = emit(
        plan_program(c.plan, tools, title=f"{c.design} coupon"),
        post,
        [
            f"{c.design} press-fit coupon, profile {c.profile}, step {c.step_mm:g} mm",
            "sizes and A positions in coupon.csv; machine convention as the body's",
        ],
    )
    parsed = parse_gcode(text, "the coupon program")
    v = verify(
        parsed, c.plan, tools={tools.groove.number: tools.groove.diameter, tools.pocket.number: tools.pocket.diameter}
    )
    return CouponProgram("coupon" + POSTS[post].suffix, text, cycle_time(parsed), v)
