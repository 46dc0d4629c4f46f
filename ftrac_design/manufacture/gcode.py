"""The body's 4-axis program from the CAD's own plan (no CadQuery here).

:func:`cut_plan` hands :class:`~ftrac_design.manufacture.plan.BodyPlan` — the grooves and pockets the
CAD cuts — to :mod:`ftrac_design.machining` as plain numbers, so the program and the solid
come from one plan; :func:`body_program` plans, posts and (optionally) verifies it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..design.schema import Design
from ..features import compute_features
from ..machining.gcode import cycle_time, parse_gcode
from ..machining.model import CutPlan, EllipseCut, Machine, PocketCut, SlotCut, Stock, tooling
from ..machining.post import DEFAULT_POST, POSTS, emit
from ..machining.simulate import Verification, verify
from ..machining.toolpath import plan_program
from .plan import BodyPlan, plan_body
from .profiles import Profile, cut_sizes


def cut_plan(plan: BodyPlan, name: str = "body") -> CutPlan:
    """The CAD's cuts as :class:`~ftrac_design.machining.model.CutPlan` (same numbers)."""
    ell = tuple(
        EllipseCut.from_plane(
            g.feature.id,
            g.seat_radius,
            g.feature.normal,
            float(g.feature.center[2]),
            g.width,
            g.floor_depth,
            g.top_height,
        )
        for g in plan.ellipse_grooves
    )
    slots = tuple(
        SlotCut(g.feature.id, math.atan2(g.radial[1], g.radial[0]), g.floor_radius, g.top_radius, g.width, g.z0, g.z1)
        for g in plan.line_grooves
    )
    pockets = tuple(
        PocketCut(
            p.feature.id,
            math.atan2(p.axis[1], p.axis[0]),
            float(p.floor[2]),
            float(np.hypot(p.floor[0], p.floor[1])),
            p.diameter,
            p.depth,
        )
        for p in plan.pockets
    )
    return CutPlan(name, Stock(plan.outer_radius, plan.bore_radius, plan.half_length), ell, slots, pockets)


@dataclass
class BodyProgram:
    """A posted program, the plan it cuts and (when asked) its verification."""

    text: str
    post: str
    plan: CutPlan
    cycle: dict[str, float]
    verification: Verification | None = None

    @property
    def filename(self) -> str:
        """``body.ngc``, or the post's suffix (``body.nc`` for fanuc)."""
        return "body" + POSTS[self.post].suffix

    def summary(self) -> dict[str, Any]:
        """Plain-JSON facts for the manifest."""
        out: dict[str, Any] = {
            "file": self.filename,
            "post": self.post,
            "cycle_time_s": {k: round(v, 1) for k, v in self.cycle.items()},
        }
        if self.verification is not None:
            out["verification"] = self.verification.as_dict()
        return out


def body_program(
    design: Design, profile: Profile = "cnc", post: str = DEFAULT_POST, check: bool = True, machine: Machine = Machine()
) -> BodyProgram:
    """Plan, post and read back the body's program; ``check``: also simulate it against the plan.

    Raises ``ValueError`` when a cut is narrower than its end mill.
    """
    features = compute_features(design)
    cuts = cut_sizes(design, profile)
    plan = cut_plan(plan_body(design, features, cuts), design.name)
    tools = tooling(design.manufacturing.cnc, cuts.pocket_diameter or None)
    prog = plan_program(plan, tools, machine, title=f"{design.name} body ({profile})")
    header = [
        f"{design.name}: grooves and pockets of the body, profile {profile}, post {post}",
        f"design sha256 {design.sha256 or 'in memory'}",
        "units mm; G54 X0 at F's origin (mid-length), Y0 Z0 on the A axis; Z = tool tip from the A axis",
        "A = F azimuth in degrees (A0: F +x up); F +z along machine +X",
    ]
    text = emit(prog, post, header)
    parsed = parse_gcode(text, "body program")
    result = BodyProgram(text, post, plan, cycle_time(parsed, machine))
    if check:
        result.verification = verify(parsed, plan)
    return result
