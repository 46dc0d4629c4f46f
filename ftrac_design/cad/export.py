"""STEP, STL and assembly exports, each checked after it is written.

- STEP (AP214, millimetres) of the body alone.
- STL with an absolute chord tolerance (``relative=False``: CadQuery's default deflection is
  relative to the part size and would smear a 0.5 mm groove) on a fresh copy of the shape,
  because OCC caches meshes on a shape and a later export would silently reuse them. The
  written file is read back with trimesh; if it is not a closed volume (zero-area triangles
  at sphere poles, duplicate vertices) it is cleaned and rewritten.
- Assembly STEP: body, wires and beads as named, coloured parts.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cadquery as cq
import numpy as np

from .body import CadError
from .parts import Part

#: assembly colours (RGBA): light acetal body, steel wires and beads in two metal tones
BODY_COLOR = (0.93, 0.92, 0.88, 1.0)
WIRE_COLOR = (0.80, 0.45, 0.15, 1.0)
BEAD_COLOR = (0.25, 0.35, 0.75, 1.0)


@dataclass(frozen=True)
class StlReport:
    """What the written STL holds."""

    triangles: int
    watertight: bool
    volume: float
    repaired: bool


def export_step(shape: cq.Shape, path: str | Path) -> Path:
    """Write ``shape`` as a STEP file (mm)."""
    path = Path(path)
    status = cq.exporters.export(shape, str(path), exportType="STEP")
    if status is False or not path.exists():
        raise CadError(f"STEP export to {path.name} failed")
    return path


def export_stl(shape: cq.Shape, path: str | Path, tolerance: float, angular_tolerance: float) -> StlReport:
    """Write ``shape`` as binary STL with an absolute chord ``tolerance`` (mm) and verify it."""
    import trimesh

    path = Path(path)
    fresh = shape.copy()  # no cached, coarser triangulation
    if not fresh.exportStl(str(path), tolerance, angular_tolerance, ascii=False, relative=False):
        raise CadError(f"STL export to {path.name} failed")
    mesh = trimesh.load_mesh(str(path), file_type="stl", process=True)
    repaired = False
    if not mesh.is_volume:
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.remove_unreferenced_vertices()
        mesh.merge_vertices()
        trimesh.repair.fix_normals(mesh)
        repaired = True
        if not mesh.is_volume:
            raise CadError(f"{path.name}: the mesh is not a closed volume after cleaning")
        mesh.export(str(path), file_type="stl")
    return StlReport(int(len(mesh.faces)), bool(mesh.is_watertight), float(mesh.volume), repaired)


def build_assembly(name: str, body: cq.Shape, parts: list[Part]) -> cq.Assembly:
    """The fiducial as an assembly: ``body`` plus every wire and bead, named and coloured."""
    assy = cq.Assembly(name=name)
    assy.add(body, name="body", color=cq.Color(*BODY_COLOR))
    for p in parts:
        rgba = WIRE_COLOR if p.kind == "wire" else BEAD_COLOR
        assy.add(p.solid, name=p.name, color=cq.Color(*rgba))
    return assy


def export_assembly(assy: cq.Assembly, path: str | Path) -> Path:
    """Write the assembly as STEP with names and colours (mm)."""
    path = Path(path)
    assy.export(str(path), exportType="STEP")
    if not path.exists():
        raise CadError(f"assembly export to {path.name} failed")
    return path


def mesh_arrays(shape: cq.Shape, tolerance: float, angular_tolerance: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3), triangles (m, 3)) of ``shape`` for rendering."""
    verts, tris = shape.copy().tessellate(tolerance, angular_tolerance)
    return np.array([v.toTuple() for v in verts], float), np.array(tris, dtype=np.int64).reshape(-1, 3)
