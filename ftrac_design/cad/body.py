"""The fiducial body in CadQuery: a hollow cylinder with a groove along every wire and a
pocket for every bead (the cuts are planned in :mod:`ftrac_design.manufacture.plan`).

Ellipse grooves are swept with the cylinder surface as the sweep's support
(``BRepOffsetAPI_MakePipeShell.SetMode(face)``): the rectangular section stays normal to the
wire with its walls parallel to the surface normal, so the groove has the same width
everywhere around the ellipse — what a radial end mill on a 4-axis mill cuts. (A slab
intersected with the cylinder would be up to 1/cos τ wider at the major-axis ends.)
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import cadquery as cq
import numpy as np
from OCP.BRepAdaptor import BRepAdaptor_Curve
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Section
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon, BRepBuilderAPI_MakeWire
from OCP.BRepGProp import BRepGProp
from OCP.BRepOffsetAPI import BRepOffsetAPI_MakePipeShell
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
from OCP.Geom import Geom_CylindricalSurface
from OCP.gp import gp_Ax2, gp_Ax3, gp_Dir, gp_Pln, gp_Pnt, gp_Vec
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_EDGE
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Wire
from OCP.TopTools import TopTools_ListOfShape

from ..errors import GoalError
from ..features.model import EllipseFeature
from ..manufacture.plan import BodyPlan, EllipseGroove, LineGroove, Pocket

#: relative accuracy of :func:`volume`
VOLUME_EPS = 1e-9

#: the spine built by OCC must match the feature ellipse to this distance (mm)
SPINE_TOLERANCE = 1e-6


class CadError(GoalError):
    """A CAD operation failed (OCC returned nothing, an invalid solid, or several solids)."""


def _v(p) -> cq.Vector:
    return cq.Vector(float(p[0]), float(p[1]), float(p[2]))


def seat_cylinder_face(radius: float, z_extent: float) -> TopoDS_Face:
    """The cylindrical face of ``radius`` about the z axis, ``±z_extent`` long."""
    surf = Geom_CylindricalSurface(gp_Ax3(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), radius)
    return BRepBuilderAPI_MakeFace(surf, 0.0, 2 * math.pi, -z_extent, z_extent, 1e-7).Face()


def ellipse_spine(e: EllipseFeature, radius: float, support: TopoDS_Face) -> TopoDS_Wire:
    """The seated ellipse as one exact edge on ``support`` (with its p-curve on the face).

    Built as the section of the seating cylinder with the ellipse's plane, then checked
    against the feature's own parametrisation so the CAD cannot drift from the features.
    """
    sec = BRepAlgoAPI_Section(support, gp_Pln(gp_Pnt(*map(float, e.center)), gp_Dir(*map(float, e.normal))), False)
    sec.ComputePCurveOn1(True)
    sec.Approximation(False)
    sec.Build()
    if not sec.IsDone():
        raise CadError(f"ellipse {e.id}: section of the seating cylinder failed")
    edges = []
    ex = TopExp_Explorer(sec.Shape(), TopAbs_EDGE)
    while ex.More():
        edges.append(TopoDS.Edge_s(ex.Current()))
        ex.Next()
    if len(edges) != 1:
        raise CadError(f"ellipse {e.id}: expected one section edge, got {len(edges)}")
    c = BRepAdaptor_Curve(edges[0])
    ts = np.linspace(c.FirstParameter(), c.LastParameter(), 17)
    pts = np.array([[c.Value(t).X(), c.Value(t).Y(), c.Value(t).Z()] for t in ts])
    # distance to the feature ellipse: in its plane, on the cylinder of radius b
    rel = pts - e.center
    off_plane = np.abs(rel @ e.normal)
    x, y = rel @ e.major_axis, rel @ e.minor_axis
    off_curve = np.abs(np.hypot(x / e.semi_major, y / e.semi_minor) - 1.0) * e.semi_minor
    if max(off_plane.max(), off_curve.max(), abs(radius - e.semi_minor)) > SPINE_TOLERANCE:
        raise CadError(f"ellipse {e.id}: the CAD spine departs from the feature centre-line")
    return BRepBuilderAPI_MakeWire(edges[0]).Wire()


def _spine_frame(spine: TopoDS_Wire) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(point, unit tangent T, outward surface normal N, across B = T × N) at the spine's start."""
    ex = TopExp_Explorer(spine, TopAbs_EDGE)
    c = BRepAdaptor_Curve(TopoDS.Edge_s(ex.Current()))
    p, v = gp_Pnt(), gp_Vec()
    c.D1(c.FirstParameter(), p, v)
    P = np.array([p.X(), p.Y(), p.Z()])
    T = np.array([v.X(), v.Y(), v.Z()])
    T /= np.linalg.norm(T)
    N = np.array([P[0], P[1], 0.0])
    N /= np.linalg.norm(N)
    N -= T * (N @ T)  # T lies in the tangent plane already; this only removes round-off
    N /= np.linalg.norm(N)
    return P, T, N, np.cross(T, N)


def _pipe(spine: TopoDS_Wire, support: TopoDS_Face, profile: TopoDS_Wire, what: str) -> cq.Solid:
    ps = BRepOffsetAPI_MakePipeShell(spine)
    ps.SetMode(support)
    ps.Add(profile, False, False)
    ps.Build()
    if not ps.IsDone() or not ps.MakeSolid():
        raise CadError(f"{what}: sweep failed")
    solid = cq.Shape.cast(ps.Shape())
    if not solid.isValid():
        raise CadError(f"{what}: sweep gave an invalid solid")
    return solid


def ellipse_groove_tool(g: EllipseGroove, z_extent: float) -> cq.Solid:
    """The solid removed by one ellipse groove (rectangle swept on the surface-normal frame)."""
    support = seat_cylinder_face(g.seat_radius, z_extent)
    spine = ellipse_spine(g.feature, g.seat_radius, support)
    P, _, N, B = _spine_frame(spine)
    poly = BRepBuilderAPI_MakePolygon()
    for s_b, s_n in ((0.5, -g.floor_depth), (0.5, g.top_height), (-0.5, g.top_height), (-0.5, -g.floor_depth)):
        q = P + B * (s_b * g.width) + N * s_n
        poly.Add(gp_Pnt(*map(float, q)))
    poly.Close()
    return _pipe(spine, support, poly.Wire(), f"groove {g.feature.id}")


def ellipse_wire_solid(e: EllipseFeature, z_extent: float) -> cq.Solid:
    """The ellipse wire itself: a circle of the wire diameter swept around the seated ellipse."""
    support = seat_cylinder_face(e.semi_minor, z_extent)
    spine = ellipse_spine(e, e.semi_minor, support)
    P, T, _, _ = _spine_frame(spine)
    circle = cq.Wire.makeCircle(e.wire_diameter / 2, _v(P), _v(T)).wrapped
    return _pipe(spine, support, circle, f"wire {e.id}")


def line_groove_tool(g: LineGroove) -> cq.Solid:
    """The solid removed by one line groove: a box, floor at seat − wire radius, along z."""
    corner = g.radial * g.floor_radius - g.tangential * (g.width / 2) + np.array([0.0, 0.0, g.z0])
    ax = gp_Ax2(gp_Pnt(*map(float, corner)), gp_Dir(0, 0, 1), gp_Dir(*map(float, g.radial)))
    return cq.Solid(BRepPrimAPI_MakeBox(ax, g.top_radius - g.floor_radius, g.width, g.z1 - g.z0).Shape())


def pocket_tool(p: Pocket) -> cq.Solid:
    """The solid removed by one bead pocket: a radial cylinder from the pocket floor outward."""
    return cq.Solid.makeCylinder(p.diameter / 2, p.depth, _v(p.floor), _v(p.axis))


def blank(plan: BodyPlan) -> cq.Solid:
    """The uncut hollow cylinder, centred on the F origin."""
    L = 2 * plan.half_length
    outer = cq.Solid.makeCylinder(plan.outer_radius, L, cq.Vector(0, 0, -plan.half_length))
    if plan.bore_radius <= 0:
        return outer
    bore = cq.Solid.makeCylinder(plan.bore_radius, L + 2, cq.Vector(0, 0, -plan.half_length - 1))
    return outer.cut(bore).Solids()[0]


def cutting_tools(plan: BodyPlan) -> list[cq.Solid]:
    """Every groove and pocket tool, in plan order (ellipses, lines, pockets)."""
    zx = plan.half_length + plan.outer_radius
    tools = [ellipse_groove_tool(g, zx) for g in plan.ellipse_grooves]
    tools += [line_groove_tool(g) for g in plan.line_grooves]
    tools += [pocket_tool(p) for p in plan.pockets]
    return tools


def volume(shape: cq.Shape) -> float:
    """Volume of ``shape`` (mm³) by adaptive integration to a relative 1e-9.

    ``Shape.Volume()`` uses a fixed Gauss rule that is off by ~5e-6 relative on the swept
    groove faces (0.1 mm³ on ftrac_2005) — more than the volume test's tolerance needs.
    """
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, props, VOLUME_EPS)
    return float(props.Mass())


def single_solid(shape: cq.Shape, what: str) -> cq.Solid:
    """``shape`` as exactly one valid solid, or :class:`CadError`."""
    solids = shape.Solids()
    if len(solids) != 1:
        raise CadError(f"{what}: expected one solid, got {len(solids)}")
    solid = solids[0]
    if not solid.isValid():
        solid = solid.fix()
        if not solid.isValid():
            raise CadError(f"{what}: the result is not a valid solid")
    return solid


def cut(base: cq.Shape, tools: list[cq.Shape], what: str = "body") -> cq.Solid:
    """``base`` minus all ``tools`` in one boolean (parallel, oriented-bounding-box filtering)."""
    if not tools:
        return single_solid(base, what)
    args, tl = TopTools_ListOfShape(), TopTools_ListOfShape()
    args.Append(base.wrapped)
    for t in tools:
        tl.Append(t.wrapped)
    op = BRepAlgoAPI_Cut()
    op.SetArguments(args)
    op.SetTools(tl)
    op.SetRunParallel(True)
    op.SetUseOBB(True)  # the tools are long and thin: OBBs prune far more pairs than AABBs
    op.Build()
    if not op.IsDone():
        raise CadError(f"{what}: boolean cut failed")
    return single_solid(cq.Shape.cast(op.Shape()), what)


#: ways to cut the tools; "staged" is the default (see benchmarks/README.md)
Strategy = Literal["staged", "single", "sequential"]
STRATEGIES: tuple[Strategy, ...] = get_args(Strategy)


def build_body(plan: BodyPlan, strategy: Strategy = "staged") -> cq.Solid:
    """The finished body: the blank minus every groove and pocket tool.

    ``staged`` (default) cuts the ellipse grooves first, then the line grooves and pockets
    together: the swept (B-spline) groove walls meet the plane walls of the line grooves in
    the second boolean only where they really cross, which is faster than one boolean with
    every tool (1.2–1.3× on the 2-core machine; ``benchmarks/build_time.py``). ``single`` (one
    boolean) and ``sequential`` (one tool at a time) are kept for the benchmark; all three give
    the same solid.
    """
    zx = plan.half_length + plan.outer_radius
    ell = [ellipse_groove_tool(g, zx) for g in plan.ellipse_grooves]
    rest = [line_groove_tool(g) for g in plan.line_grooves] + [pocket_tool(p) for p in plan.pockets]
    body = blank(plan)
    if strategy == "staged":
        if ell:
            body = cut(body, ell)
        return cut(body, rest)
    if strategy == "single":
        return cut(body, ell + rest)
    if strategy == "sequential":
        for t in ell + rest:
            body = cut(body, [t])
        return body
    raise ValueError(f"unknown strategy {strategy!r}; expected one of {STRATEGIES}")
