"""What every CAD command needs before and while it builds: the ``cad`` extra installed, and
OpenCASCADE's own exceptions turned into :class:`~ftrac_design.cad.body.CadError` (exit 1).

This module imports neither CadQuery nor OCP at import time, so a command can check for the
extra before anything is built.
"""

from __future__ import annotations

import contextlib
from typing import Iterator

from ..errors import require


def require_cad_packages(render: bool = True) -> None:
    """Raise :class:`~ftrac_design.errors.MissingDependencyError` before anything is built when
    the ``cad`` extra is not installed.

    Parameters
    ----------
    render : bool
        Whether the build renders its picture (pyvista is needed only then).
    """
    require("cadquery", "cad", "building the CAD parts")
    require("OCP", "cad", "building the CAD parts (OpenCascade)")
    require("trimesh", "cad", "building the CAD parts (the STL check)")
    require("ezdxf", "cad", "building the CAD parts (the unwrapped DXF)")
    if render:
        require("pyvista", "cad", "building the CAD parts (the render)")


@contextlib.contextmanager
def occ_errors(name: str) -> Iterator[None]:
    """Turn an exception raised inside OpenCASCADE into :class:`~ftrac_design.cad.body.CadError`.

    Parameters
    ----------
    name : str
        What was being built, for the message (the design's name).
    """
    from OCP.Standard import Standard_Failure

    from .body import CadError

    try:
        yield
    except Standard_Failure as exc:
        raise CadError(f"{name}: OpenCASCADE failed ({type(exc).__name__}: {exc})") from exc
