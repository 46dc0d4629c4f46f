"""The press-fit coupon's solid: the coupon's plan
(:func:`ftrac_design.manufacture.coupon.plan_coupon`) cut from a cylinder of the body's outer
diameter, each size engraved on the ``+z`` end face beside its cut.
"""

from __future__ import annotations

import math

import cadquery as cq
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

from ..manufacture.coupon import ENGRAVE_DEPTH, Coupon
from .body import cut


def build_coupon(c: Coupon):
    """The coupon solid (CadQuery): the cylinder minus every slot, pocket and engraved label."""
    s = c.stock
    blank = cq.Solid.makeCylinder(s.outer_radius, 2 * s.half_length, cq.Vector(0, 0, -s.half_length))
    tools = []
    for g in c.plan.slots:  # a box, a narrower box through the round ends, and the four corner cylinders
        u = (math.cos(g.azimuth), math.sin(g.azimuth))
        t = (-u[1], u[0])
        e, hgt = g.end_radius, g.top_radius - g.floor_radius
        for half, z0, z1 in ((g.width / 2, g.z0, g.z1), (g.width / 2 - e, g.z0 - e, g.z1 + e)):
            if half < 1e-6:  # the slot is as wide as the end mill: its ends are the cylinders
                continue
            corner = (u[0] * g.floor_radius - t[0] * half, u[1] * g.floor_radius - t[1] * half, z0)
            ax = gp_Ax2(gp_Pnt(*corner), gp_Dir(0, 0, 1), gp_Dir(u[0], u[1], 0))
            tools.append(cq.Solid(BRepPrimAPI_MakeBox(ax, hgt, 2 * half, z1 - z0).Shape()))
        if e > 0:
            axis = cq.Vector(u[0], u[1], 0)
            for side in (-1, 1):
                for zc in (g.z0, g.z1):
                    base = cq.Vector(
                        u[0] * g.floor_radius + t[0] * side * (g.width / 2 - e),
                        u[1] * g.floor_radius + t[1] * side * (g.width / 2 - e),
                        zc,
                    )
                    tools.append(cq.Solid.makeCylinder(e, hgt, base, axis))
    for p in c.plan.pockets:
        u = cq.Vector(math.cos(p.azimuth), math.sin(p.azimuth), 0)
        tools.append(cq.Solid.makeCylinder(p.diameter / 2, p.depth, cq.Vector(0, 0, p.z) + u * p.floor_radius, u))
    h = c.label_height
    for st in c.steps:
        r0 = 0.92 * s.outer_radius - 3.2 * h  # five characters reading outward, ending near the rim
        x, y = r0 * math.cos(st.azimuth), r0 * math.sin(st.azimuth)
        txt = (
            cq.Workplane("XY")
            .workplane(offset=s.half_length)
            .center(x, y)
            .transformed(rotate=(0, 0, math.degrees(st.azimuth)))
            .text(st.label, h, -ENGRAVE_DEPTH, combine=False, halign="left", valign="center")
        )
        tools.extend(txt.vals())
    return cut(blank, tools, f"{c.design} coupon")
