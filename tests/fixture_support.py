"""Shared by the mount/connector and frame tests: cached part builds, B-rep probes
(cylindrical faces, inside/outside), STEP/STL round trips and assembly import."""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from cad_support import MODELS, PRESETS, PROFILES, ROOT, design_of  # noqa: F401  (re-exported to the tests)

TMP = Path(tempfile.mkdtemp(prefix="ftrac-fixture-tests-"))
atexit.register(shutil.rmtree, TMP, ignore_errors=True)


@functools.cache
def mount_part(preset: str, profile: str = "cnc"):
    from ftrac_design.cad.mount import MountPart

    part = MountPart.of(design_of(preset), profile)
    return part, part.build()


@functools.cache
def connector_part(preset: str, profile: str = "cnc"):
    from ftrac_design.cad.connector import ConnectorPart

    part = ConnectorPart.of(design_of(preset), profile)
    return part, part.build()


@dataclass(frozen=True)
class CylFace:
    """A cylindrical face of a B-rep: a point on its axis, unit axis direction, radius."""

    point: np.ndarray
    direction: np.ndarray
    radius: float

    def distance_to_line(self, p: np.ndarray, d: np.ndarray) -> float:
        """Distance between this face's axis and the line (p, d), if parallel (else inf)."""
        if abs(abs(float(self.direction @ d)) - 1.0) > 1e-9:
            return float("inf")
        w = self.point - p
        return float(np.linalg.norm(w - (w @ d) * d))


def cylindrical_faces(shape) -> list[CylFace]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cylinder

    out = []
    for f in shape.Faces():
        s = BRepAdaptor_Surface(f.wrapped)
        if s.GetType() != GeomAbs_Cylinder:
            continue
        c = s.Cylinder()
        ax = c.Axis()
        p, d = ax.Location(), ax.Direction()
        out.append(CylFace(np.array([p.X(), p.Y(), p.Z()]), np.array([d.X(), d.Y(), d.Z()]), c.Radius()))
    return out


def inside(shape, p) -> bool:
    import cadquery as cq

    return bool(shape.isInside(cq.Vector(*map(float, p)), 1e-7))


def step_round_trip(shape, path: Path):
    """Write ``shape`` as STEP, read it back: the re-imported shape."""
    import cadquery as cq

    cq.exporters.export(shape, str(path), exportType="STEP")
    return cq.importers.importStep(str(path)).val()


def stl_mesh(shape, path: Path, tolerance: float = 0.01):
    import trimesh

    shape.copy().exportStl(str(path), tolerance, 0.1, ascii=False, relative=False)
    return trimesh.load_mesh(str(path), file_type="stl", process=True)


def assembly_parts(path: Path) -> dict[str, tuple[object, tuple | None]]:
    """Top-level parts of an assembly STEP: name → (shape placed in the assembly frame, RGBA)."""
    import cadquery as cq

    assy = cq.Assembly.importStep(str(path))
    out = {}
    for name, sub in assy.traverse():
        if sub.obj is None or sub is assy:
            continue
        shape = sub.obj if isinstance(sub.obj, cq.Shape) else sub.obj.val()
        out[name] = (shape.moved(sub.loc), sub.color.toTuple() if sub.color else None)
    return out
