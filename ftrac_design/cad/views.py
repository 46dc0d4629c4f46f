"""Orthographic views and sections of a solid, as 2-D polylines for a drawing.

- :func:`project` runs OpenCASCADE's exact hidden-line removal (``HLRBRep_Algo``) for a
  parallel projection and returns the visible and hidden edges (sharp edges, smooth-edge
  seams and silhouettes) as polylines in the view's own 2-D frame.
- :func:`section` intersects the solid with a plane (``BRepAlgoAPI_Common`` with a planar
  face larger than the part) and returns the cut faces as closed loops in the plane's
  2-D frame, ready to hatch.

- :class:`SolidViews` hands both to the drawings' sheets
  (:mod:`ftrac_design.manufacture.drawings`), which draw them without CadQuery.

The frames and the 2-D results are :mod:`ftrac_design.manufacture.views`. All coordinates mm,
in the part's own frame (F for the body, M for the mount, T for the connector).
"""

from __future__ import annotations

import cadquery as cq
import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.BRepLib import BRepLib
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepTools import BRepTools, BRepTools_WireExplorer
from OCP.GCPnts import GCPnts_QuasiUniformDeflection
from OCP.gp import gp_Ax2, gp_Ax3, gp_Dir, gp_Pln, gp_Pnt
from OCP.HLRAlgo import HLRAlgo_Projector
from OCP.HLRBRep import HLRBRep_Algo, HLRBRep_HLRToShape, HLRBRep_PolyAlgo, HLRBRep_PolyHLRToShape
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED, TopAbs_WIRE
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Shape

from ..manufacture.views import Projection, Section, ViewFrame, chain

#: chord deflection of the polylines, mm (far below a drawn line's width at any drawing scale)
DEFLECTION = 0.005
#: chord of the triangulation the fast hidden-line removal works on, mm
MESH_DEFLECTION = 0.01


def _ax2(frame: ViewFrame) -> gp_Ax2:
    """The view's axes as OpenCASCADE's: origin, the eye direction and the drawing's +x."""
    return gp_Ax2(gp_Pnt(*frame.origin), gp_Dir(*frame.toward_viewer), gp_Dir(*frame.x_dir))


def _edge_polylines(shape: TopoDS_Shape) -> list[np.ndarray]:
    out = []
    if shape is None or shape.IsNull():
        return out
    BRepLib.BuildCurves3d_s(shape, 1e-7)  # HLR edges carry 2-D curves only
    ex = TopExp_Explorer(shape, TopAbs_EDGE)
    while ex.More():
        edge = TopoDS.Edge_s(ex.Current())
        ex.Next()
        if BRep_Tool.Degenerated_s(edge):
            continue
        c = BRepAdaptor_Curve(edge)
        pts = GCPnts_QuasiUniformDeflection(c, DEFLECTION, c.FirstParameter(), c.LastParameter())
        if not pts.IsDone() or pts.NbPoints() < 2:
            continue
        out.append(np.array([[pts.Value(i).X(), pts.Value(i).Y()] for i in range(1, pts.NbPoints() + 1)]))
    return out


def project(solid: cq.Shape, frame: ViewFrame, exact: bool = False) -> Projection:
    """Hidden-line projection of ``solid`` seen along ``-frame.toward_viewer``.

    ``exact=False`` (default) removes hidden lines on a triangulation of chord
    :data:`MESH_DEFLECTION` (``HLRBRep_PolyAlgo``): ~100x faster than the exact algorithm on
    the body's swept grooves, and the drawn lines are within that chord of the exact ones.
    """
    if exact:
        hlr = HLRBRep_Algo()
        hlr.Add(solid.wrapped)
        hlr.Projector(HLRAlgo_Projector(_ax2(frame)))
        hlr.Update()
        hlr.Hide()
        h = HLRBRep_HLRToShape(hlr)
    else:
        mesh = solid.copy()
        BRepMesh_IncrementalMesh(mesh.wrapped, MESH_DEFLECTION, False, 0.1, True)
        poly = HLRBRep_PolyAlgo()
        poly.Load(mesh.wrapped)
        poly.Projector(HLRAlgo_Projector(_ax2(frame)))
        poly.Update()
        h = HLRBRep_PolyHLRToShape()
        h.Update(poly)
    visible = [
        *_edge_polylines(h.VCompound()),
        *_edge_polylines(h.Rg1LineVCompound()),
        *_edge_polylines(h.OutLineVCompound()),
    ]
    hidden = [*_edge_polylines(h.HCompound()), *_edge_polylines(h.OutLineHCompound())]
    # the projector's 2-D frame is the Ax2's (x_dir, toward_viewer × x_dir) about its origin
    return Projection(frame, tuple(chain(visible)), tuple(chain(hidden)))


def _wire_loop(wire, frame: ViewFrame) -> np.ndarray:
    pts = []
    ex = BRepTools_WireExplorer(wire)
    while ex.More():
        edge = ex.Current()
        c = BRepAdaptor_Curve(edge)
        d = GCPnts_QuasiUniformDeflection(c, DEFLECTION, c.FirstParameter(), c.LastParameter())
        seg = np.array([[d.Value(i).X(), d.Value(i).Y(), d.Value(i).Z()] for i in range(1, d.NbPoints() + 1)])
        if ex.Orientation() == TopAbs_REVERSED:
            seg = seg[::-1]
        pts.append(seg)
        ex.Next()
    loop = frame.to_2d(np.vstack(pts))
    return np.vstack([loop, loop[:1]])


def section(solid: cq.Shape, frame: ViewFrame) -> Section:
    """The cut of ``solid`` by the plane through ``frame.origin`` normal to ``toward_viewer``."""
    bb = solid.BoundingBox()
    size = 4 * max(bb.xlen, bb.ylen, bb.zlen) + 10
    plane = gp_Pln(gp_Ax3(gp_Pnt(*frame.origin), gp_Dir(*frame.toward_viewer), gp_Dir(*frame.x_dir)))
    face = BRepBuilderAPI_MakeFace(plane, -size, size, -size, size).Face()
    common = BRepAlgoAPI_Common(solid.wrapped, face)
    common.Build()
    faces = []
    ex = TopExp_Explorer(common.Shape(), TopAbs_FACE)
    while ex.More():
        f = TopoDS.Face_s(ex.Current())
        ex.Next()
        outer = BRepTools.OuterWire_s(f)
        inner = []
        wx = TopExp_Explorer(f, TopAbs_WIRE)
        while wx.More():
            w = TopoDS.Wire_s(wx.Current())
            wx.Next()
            if not w.IsSame(outer):
                inner.append(_wire_loop(w, frame))
        faces.append((_wire_loop(outer, frame), tuple(inner)))
    return Section(frame, tuple(faces))


class SolidViews:
    """A CAD solid's views for a sheet (:class:`~ftrac_design.manufacture.views.PartViews`).

    Parameters
    ----------
    solid : cadquery.Shape
        The part, in its own frame.
    exact : bool
        Exact hidden-line removal (the mount's, the connector's and the coupon's few analytic
        faces) rather than on a fine mesh (the body's swept grooves; see :func:`project`).
    """

    def __init__(self, solid: cq.Shape, exact: bool = False):
        self.solid = solid
        self.exact = exact

    def project(self, frame: ViewFrame) -> Projection:
        """The hidden-line projection of the solid in ``frame``."""
        return project(self.solid, frame, exact=self.exact)

    def section(self, frame: ViewFrame) -> Section:
        """The solid cut by the plane through ``frame.origin`` normal to ``toward_viewer``."""
        return section(self.solid, frame)
