"""STEP, STL and assembly exports, each checked after it is written.

- STEP (AP214, millimetres) of the body alone.
- STL with an absolute chord tolerance (``relative=False``: CadQuery's default deflection is
  relative to the part size and would smear a 0.5 mm groove) on a fresh copy of the shape,
  because OCC caches meshes on a shape and a later export would silently reuse them. The
  written file is read back with trimesh; if it is not a closed volume (zero-area triangles
  at sphere poles, duplicate vertices) it is cleaned and rewritten.
- Assembly STEP: body, wires and beads as named, coloured parts.
- The mount's and the connector's STEP and STL (frames M and T) and the unrolled grooves
  (``grooves.csv``, ``grooves.dxf``) that a build writes beside the body
  (:func:`write_manufacturing_files`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cadquery as cq
import numpy as np

from ..design.schema import Design
from ..features.model import Features
from ..manufacture.plan import FIXTURE_STL_TOLERANCE, STL_VOLUME_TOLERANCE
from ..manufacture.profiles import Profile, cut_sizes
from ..manufacture.unwrap import unwrap_features, write_grooves_csv, write_grooves_dxf
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


def write_manufacturing_files(
    design: Design, features: Features, profile: Profile, out_dir: Path, parts: list
) -> dict[str, Any]:
    """Write the mount, connector and groove files into ``out_dir``; returns per-file facts.

    Parameters
    ----------
    design, features : Design, Features
        The design and its features.
    profile : {"cnc", "fdm"}
        The manufacturing profile (the grooves' cut widths).
    out_dir : pathlib.Path
        Where the files go.
    parts : list
        The :func:`~ftrac_design.cad.fixture.fixture_parts` built for the assembly; the mount's
        and the connector's ``local`` solids are exported.

    Returns
    -------
    dict
        Per part: its frame, volume, bounding box and STL check; ``grooves``: the polyline and
        pocket counts.
    """
    info: dict[str, Any] = {}
    for p in parts:
        if p.kind in ("mount", "connector"):
            info[p.name] = _export_fixture_part(p, out_dir)
    paths = unwrap_features(features, design.outer_radius, cut_sizes(design, profile))
    write_grooves_csv(out_dir / "grooves.csv", paths)
    write_grooves_dxf(
        out_dir / "grooves.dxf", paths, design.outer_radius, design.half_length, design.mount.socket_depth
    )
    info["grooves"] = {
        "polylines": sum(p.kind != "pocket" for p in paths),
        "pockets": sum(p.kind == "pocket" for p in paths),
    }
    return info


def _export_fixture_part(p, out_dir: Path) -> dict[str, Any]:
    """STEP and checked STL of one fixture part in its own frame; its manifest facts."""
    export_step(p.local, out_dir / f"{p.name}.step")
    stl = export_stl(p.local, out_dir / f"{p.name}.stl", *FIXTURE_STL_TOLERANCE)
    vol = float(p.local.Volume())
    rel = stl.volume / vol - 1.0
    if not stl.watertight or abs(rel) > STL_VOLUME_TOLERANCE:
        raise CadError(f"{p.name}.stl: watertight={stl.watertight}, volume off by {rel:+.3%} from the B-rep")
    bb = p.local.BoundingBox()
    return {
        "frame": p.frame,
        "volume_mm3": round(vol, 4),
        "bbox_mm": [
            [round(bb.xmin, 6), round(bb.ymin, 6), round(bb.zmin, 6)],
            [round(bb.xmax, 6), round(bb.ymax, 6), round(bb.zmax, 6)],
        ],
        "stl": {"triangles": stl.triangles, "watertight": stl.watertight, "volume_vs_brep": rel},
    }
