"""Orthographic views and sections of a solid, as 2-D polylines for a drawing.

- :func:`project` runs OpenCASCADE's exact hidden-line removal (``HLRBRep_Algo``) for a
  parallel projection and returns the visible and hidden edges (sharp edges, smooth-edge
  seams and silhouettes) as polylines in the view's own 2-D frame.
- :func:`section` intersects the solid with a plane (``BRepAlgoAPI_Common`` with a planar
  face larger than the part) and returns the cut faces as closed loops in the plane's
  2-D frame, ready to hatch.

A view is given by a :class:`ViewFrame`: the 2-D x axis ``x_dir`` and the direction
``toward_viewer`` (pointing from the part to the eye); the 2-D y axis is
``toward_viewer × x_dir``. All coordinates mm, in the part's own frame (F for the body, M
for the mount, T for the connector).
"""

from __future__ import annotations

from dataclasses import dataclass

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

#: chord deflection of the polylines, mm (far below a drawn line's width at any drawing scale)
DEFLECTION = 0.005
#: chord of the triangulation the fast hidden-line removal works on, mm
MESH_DEFLECTION = 0.01


@dataclass(frozen=True)
class ViewFrame:
    """A parallel view: ``x_dir`` is the drawing's +x, ``toward_viewer`` points at the eye."""

    name: str
    x_dir: tuple[float, float, float]
    toward_viewer: tuple[float, float, float]
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def y_dir(self) -> np.ndarray:
        return np.cross(self.toward_viewer, self.x_dir)

    def to_2d(self, p: np.ndarray) -> np.ndarray:
        """Points (n, 3) in the part frame → (n, 2) in the view."""
        q = np.atleast_2d(np.asarray(p, float)) - np.asarray(self.origin, float)
        return np.column_stack([q @ np.asarray(self.x_dir, float), q @ self.y_dir])

    def ax2(self) -> gp_Ax2:
        return gp_Ax2(gp_Pnt(*self.origin), gp_Dir(*self.toward_viewer), gp_Dir(*self.x_dir))


@dataclass(frozen=True)
class Projection:
    """Visible and hidden edges of one view, each a polyline (n, 2) in mm."""

    frame: ViewFrame
    visible: tuple[np.ndarray, ...]
    hidden: tuple[np.ndarray, ...]

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of every edge."""
        pts = np.vstack(self.visible + self.hidden)
        return float(pts[:, 0].min()), float(pts[:, 0].max()), float(pts[:, 1].min()), float(pts[:, 1].max())


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
        hlr.Projector(HLRAlgo_Projector(frame.ax2()))
        hlr.Update()
        hlr.Hide()
        h = HLRBRep_HLRToShape(hlr)
    else:
        mesh = solid.copy()
        BRepMesh_IncrementalMesh(mesh.wrapped, MESH_DEFLECTION, False, 0.1, True)
        poly = HLRBRep_PolyAlgo()
        poly.Load(mesh.wrapped)
        poly.Projector(HLRAlgo_Projector(frame.ax2()))
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


def chain(polylines: list[np.ndarray], tol: float = 1e-6) -> list[np.ndarray]:
    """Join polylines that share end points into longer ones (a mesh's hidden-line removal
    returns one short edge per triangle side; drawing them one by one is slow)."""

    def key(p: np.ndarray) -> tuple[int, int]:
        return int(round(p[0] / tol)), int(round(p[1] / tol))

    ends: dict[tuple[int, int], list[int]] = {}
    for i, pl in enumerate(polylines):
        ends.setdefault(key(pl[0]), []).append(i)
        ends.setdefault(key(pl[-1]), []).append(i)
    used = [False] * len(polylines)

    def extend(path: list[np.ndarray]) -> None:
        while True:
            cand = [j for j in ends.get(key(path[-1][-1]), []) if not used[j]]
            if not cand:
                return
            j = cand[0]
            used[j] = True
            nxt = polylines[j]
            path.append(nxt[1:] if key(nxt[0]) == key(path[-1][-1]) else nxt[::-1][1:])

    out = []
    for i, pl in enumerate(polylines):
        if used[i]:
            continue
        used[i] = True
        fwd = [pl]
        extend(fwd)
        back = [pl[::-1]]
        extend(back)
        joined = np.vstack([*[b[::-1] for b in back[:0:-1]], *fwd]) if len(back) > 1 else np.vstack(fwd)
        out.append(joined)
    return out


@dataclass(frozen=True)
class Section:
    """The faces a plane cuts from a solid: each face as (outer loop, inner loops), mm in 2-D."""

    frame: ViewFrame
    faces: tuple[tuple[np.ndarray, tuple[np.ndarray, ...]], ...]

    def loops(self) -> list[np.ndarray]:
        return [loop for outer, inner in self.faces for loop in (outer, *inner)]

    def bounds(self) -> tuple[float, float, float, float]:
        pts = np.vstack(self.loops())
        return float(pts[:, 0].min()), float(pts[:, 0].max()), float(pts[:, 1].min()), float(pts[:, 1].max())


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
