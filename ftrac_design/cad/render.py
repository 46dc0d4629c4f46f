"""``render.png``: the fiducial off-screen with pyvista — a pale, translucent body with the
steel wires and beads in metal colours inside it, seen from a raised three-quarter view."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import cadquery as cq
import numpy as np

from .export import BEAD_COLOR, BODY_COLOR, WIRE_COLOR, mesh_arrays
from .parts import Part


def _polydata(shape: cq.Shape, tolerance: float, angular_tolerance: float):
    import pyvista as pv

    v, t = mesh_arrays(shape, tolerance, angular_tolerance)
    faces = np.hstack([np.full((len(t), 1), 3, dtype=np.int64), t]).ravel()
    return pv.PolyData(v, faces).compute_normals(auto_orient_normals=True, split_vertices=True, feature_angle=35.0)


def render_png(
    body: cq.Shape,
    parts: list[Part],
    path: str | Path,
    title: str = "",
    part_size: float | None = None,
    size: tuple[int, int] = (1200, 900),
) -> Path:
    """Render ``body`` with its ``parts`` to ``path`` (PNG), headless.

    ``part_size`` (mm) is the smallest wire or bead diameter; the parts are tessellated to
    a sixth of it (enough for a round look, and ~10x faster than the STL's tolerance).
    """
    os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
    import pyvista as pv

    with contextlib.suppress(Exception):  # headless: VTK warns about the missing X server
        pv.vtk_verbosity("off")
    path = Path(path)
    bb = body.BoundingBox()
    scale = max(bb.xlen, bb.ylen, bb.zlen)
    # display tolerances, far coarser than the STL's: the picture needs ~1 px accuracy only
    part_tol = (part_size or scale / 100.0) / 6.0
    pl = pv.Plotter(off_screen=True, window_size=list(size))
    pl.set_background("white", top="#dfe6ee")
    pl.enable_anti_aliasing("ssaa")
    pl.enable_depth_peeling(number_of_peels=6)
    pl.add_mesh(
        _polydata(body, scale / 800.0, 0.3), color=BODY_COLOR[:3], opacity=0.35, smooth_shading=True, specular=0.3
    )
    for p in parts:
        rgb = WIRE_COLOR[:3] if p.kind == "wire" else BEAD_COLOR[:3]
        pl.add_mesh(_polydata(p.solid, part_tol, 0.5), color=rgb, smooth_shading=True, specular=0.7, specular_power=30)
    if title:
        pl.add_text(title, position="upper_left", font_size=12, color="black")
    # raised three-quarter view on the nominal source side (+y), axis upright
    c = np.array(bb.center.toTuple())
    eye = c + scale * np.array([1.35, 2.0, 0.9])
    pl.camera_position = [tuple(eye), tuple(c), (0.0, 0.0, 1.0)]
    pl.reset_camera_clipping_range()
    pl.camera.zoom(1.15)
    pl.add_axes(line_width=2, labels_off=False)
    pl.screenshot(str(path))
    pl.close()
    if not path.exists():
        raise RuntimeError(f"render to {path.name} failed")
    return path
