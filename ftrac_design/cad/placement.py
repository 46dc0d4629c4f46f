"""Placing parts by the frames of ``features.json`` (4×4 homogeneous, row-major).

Parts are built in their own frames (body in F, mount in M, connector and pins in T) and
put into the assembly (frame F) only through the transforms
``frames.mount_from_fiducial`` and ``frames.template_from_fiducial`` — the CAD never
repeats the arithmetic that positions them.
"""

from __future__ import annotations

import cadquery as cq
import numpy as np
from OCP.gp import gp_Trsf


def trsf(T: np.ndarray) -> gp_Trsf:
    """An OCC rigid transformation from a 4×4 matrix (rotation must be orthonormal)."""
    T = np.asarray(T, float)
    if not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9) or abs(np.linalg.det(T[:3, :3]) - 1) > 1e-9:
        raise ValueError("not a rigid transform")
    t = gp_Trsf()
    t.SetValues(*(float(T[i, j]) for i in range(3) for j in range(4)))
    return t


def location(T: np.ndarray) -> cq.Location:
    """A CadQuery location (for ``Assembly.add(..., loc=…)``) from a 4×4 matrix."""
    return cq.Location(trsf(T))


def placed(shape: cq.Shape, T: np.ndarray) -> cq.Shape:
    """A copy of ``shape`` moved by the 4×4 transform ``T`` (a rigid move: geometry exact)."""
    return shape.moved(location(T))
