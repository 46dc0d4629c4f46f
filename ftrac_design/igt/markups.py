"""3D Slicer markups files (``.mrk.json``): a named list of points, in **LPS** millimetres.

We write one ``Fiducial`` (point list) markup whose control points are the given points with
their ids as labels, ``coordinateSystem: "LPS"`` (our coordinates, see the package). The
reader returns LPS positions, converting a file that says ``"RAS"``.

Sources (:func:`points_from_file`): a reconstruction (``ftrac-design reconstruct``'s JSON: its
reconstructed points in its ``frame``; refused points are left out) or a ``features.json``
(its beads' centres in F).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..fileio import parse_json, read_text_input, write_text_atomic

#: the markups schema 3D Slicer writes and reads
SCHEMA = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/"
    "Schema/markups-schema-v1.0.3.json#"
)


def markups_dict(points: list[tuple[str, np.ndarray]], name: str, description: str = "") -> dict[str, Any]:
    """The ``.mrk.json`` object of one point list.

    Parameters
    ----------
    points : (label, (3,) position mm in LPS) pairs, in order.
    name : the markup node's name in Slicer.
    description : put in each control point's ``description`` (e.g. the frame), or "".

    Returns
    -------
    dict : ``{"@schema", "markups": [{"type": "Fiducial", "coordinateSystem": "LPS", …}]}``.
    """
    cps = []
    for i, (label, p) in enumerate(points, 1):
        p = np.asarray(p, float)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise InputError(None, None, f"a finite 3-vector for point {label!r}", parameter="points")
        cps.append(
            {
                "id": str(i),
                "label": str(label),
                "description": description,
                "associatedNodeID": "",
                "position": [float(x) for x in p],
                "orientation": [-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0],
                "selected": True,
                "locked": True,
                "visibility": True,
                "positionStatus": "defined",
            }
        )
    return {
        "@schema": SCHEMA,
        "markups": [
            {
                "type": "Fiducial",
                "name": name,
                "coordinateSystem": "LPS",
                "coordinateUnits": "mm",
                "locked": True,
                "fixedNumberOfControlPoints": False,
                "labelFormat": "%N-%d",
                "lastUsedControlPointNumber": len(cps),
                "controlPoints": cps,
                "measurements": [],
                "display": {
                    "visibility": True,
                    "opacity": 1.0,
                    "pointLabelsVisibility": True,
                    "glyphType": "Sphere3D",
                    "glyphScale": 1.0,
                },
            }
        ],
    }


def write_markups(path: str | Path, points: list[tuple[str, np.ndarray]], name: str, description: str = "") -> Path:
    """Write :func:`markups_dict` to ``path`` atomically (InputError if it cannot be written)."""
    try:
        return write_text_atomic(
            path, json.dumps(markups_dict(points, name, description), indent=2, allow_nan=False) + "\n"
        )
    except OSError as exc:
        raise InputError(path, None, f"a writable output path ({exc.strerror or exc})") from None


def read_markups(path: str | Path) -> list[tuple[str, np.ndarray]]:
    """(label, (3,) LPS position mm) of every control point of every markup in a ``.mrk.json``.

    Parameters
    ----------
    path : the file.

    Returns
    -------
    list : in file order. A ``"RAS"`` markup's positions are converted to LPS. InputError on a
    file that is not a markups file.
    """
    d = parse_json(read_text_input(path), path)
    if not isinstance(d, dict) or not isinstance(d.get("markups"), list):
        raise InputError(path, "markups", "a list of markups (a 3D Slicer .mrk.json)")
    out = []
    for m, mk in enumerate(d["markups"]):
        key = f"markups[{m}]"
        cs = mk.get("coordinateSystem", "LPS") if isinstance(mk, dict) else None
        if cs not in ("LPS", "RAS"):
            raise InputError(path, f"{key}.coordinateSystem", f'"LPS" or "RAS", got {cs!r}')
        for i, cp in enumerate(mk.get("controlPoints", [])):
            pos = cp.get("position") if isinstance(cp, dict) else None
            if (
                not isinstance(pos, list)
                or len(pos) != 3
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in pos)
            ):
                raise InputError(path, f"{key}.controlPoints[{i}].position", "three finite numbers")
            p = np.array(pos, float)
            if cs == "RAS":
                p[:2] *= -1
            out.append((str(cp.get("label", cp.get("id", i + 1))), p))
    return out


def points_from_file(path: str | Path) -> tuple[list[tuple[str, np.ndarray]], str]:
    """The points to export from a reconstruction or a features file, and their frame.

    Parameters
    ----------
    path : ``ftrac-design reconstruct``'s JSON (format ``ftrac-reconstruction``) or a
        ``features.json`` (format ``ftrac-features``).

    Returns
    -------
    (points, frame) : (id, (3,) mm) pairs in file order and the frame they are in
    (``"fiducial"``, ``"template"``, …). InputError for another file or one with no point.
    """
    d = parse_json(read_text_input(path), path)
    fmt = d.get("format") if isinstance(d, dict) else None
    pts: list[tuple[str, np.ndarray]] = []
    if fmt == "ftrac-reconstruction":
        frame = str(d.get("frame", "fiducial"))
        items = d.get("points")
        if not isinstance(items, dict):
            raise InputError(path, "points", "an object of reconstructed points")
        for pid, e in items.items():
            if isinstance(e, dict) and e.get("position_mm") is not None:
                pts.append((pid, _vec3(e["position_mm"], path, f"points.{pid}.position_mm")))
    elif fmt == "ftrac-features":
        frame = "fiducial"
        items = d.get("points")
        if not isinstance(items, list):
            raise InputError(path, "points", "a list of beads")
        for i, e in enumerate(items):
            if not isinstance(e, dict) or "center" not in e:
                raise InputError(path, f"points[{i}]", "a bead with a center")
            pts.append((str(e.get("id", i + 1)), _vec3(e["center"], path, f"points[{i}].center")))
    else:
        raise InputError(path, "format", f'"ftrac-reconstruction" or "ftrac-features", got {fmt!r}')
    if not pts:
        raise InputError(path, "points", "at least one point with a position")
    return pts, frame


def _vec3(v: Any, path: str | Path, key: str) -> np.ndarray:
    if (
        not isinstance(v, list)
        or len(v) != 3
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    ):
        raise InputError(path, key, "three finite numbers (mm)")
    return np.array(v, float)
