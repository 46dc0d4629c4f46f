"""SPEC §4 pose files read for export: ``pose.json`` (one object) or JSON Lines (a run).

Strict: every problem is an :class:`~ftrac_design.errors.InputError` naming the file, the
line (for JSON Lines) and the key. A pose with ``"converged": false`` is kept (a lost frame
of a run: exported with status INVALID), its rotation and translation NaN.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..fileio import json_lines, parse_json, read_text_input

#: a rotation matrix is accepted when ‖RᵀR − I‖ and |det R − 1| are below this
ROTATION_TOL = 1e-6


@dataclass(frozen=True)
class PoseRecord:
    """One SPEC §4 pose as exported.

    Attributes
    ----------
    R, t : rotation (3, 3) and translation (3,) mm mapping F into X; NaN when not converged.
    converged : whether the pose was found.
    covariance : (6, 6) rotation vector (rad, on the left) then translation (mm), or None.
    time_s : the frame's time in the run (s), or None.
    frame : the 0-based frame index in the run, or None.
    status : SPEC §4 ``status`` (``tracked``, ``lost`` …), or None.
    error : why no pose was found, or None.
    origin : ``file`` or ``file:line``, for messages.
    """

    R: np.ndarray
    t: np.ndarray
    converged: bool
    covariance: np.ndarray | None
    time_s: float | None
    frame: int | None
    status: str | None
    error: str | None
    origin: str


def _short(v: Any) -> str:
    s = json.dumps(v) if not isinstance(v, float) else repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def _number(v: Any, origin: str, key: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(origin, key, f"a finite number, got {_short(v)}")
    return float(v)


def _matrix(v: Any, rows: int, cols: int, origin: str, key: str) -> np.ndarray:
    if not isinstance(v, list) or len(v) != rows or not all(isinstance(r, list) and len(r) == cols for r in v):
        raise InputError(
            origin, key, f"a {rows}x{cols} matrix (a list of {rows} rows of {cols} numbers), got {_short(v)}"
        )
    return np.array([[_number(x, origin, f"{key}[{i}][{j}]") for j, x in enumerate(r)] for i, r in enumerate(v)])


def pose_record(d: Any, origin: str) -> PoseRecord:
    """Validate one parsed SPEC §4 object.

    Parameters
    ----------
    d : the parsed JSON value.
    origin : ``file`` or ``file:line`` named in errors.

    Returns
    -------
    PoseRecord. Raises InputError on anything that is not a SPEC §4 pose.
    """
    if not isinstance(d, dict):
        raise InputError(origin, None, f"a JSON object (an ftrac-pose), got {_short(d)}")
    fmt = d.get("format", "ftrac-pose")
    if fmt != "ftrac-pose":
        raise InputError(origin, "format", f'"ftrac-pose", got {_short(fmt)}')
    conv = d.get("converged", True)
    if not isinstance(conv, bool):
        raise InputError(origin, "converged", f"true or false, got {_short(conv)}")
    time_s = None if d.get("time_s") is None else _number(d["time_s"], origin, "time_s")
    frame = d.get("frame")
    if frame is not None and (isinstance(frame, bool) or not isinstance(frame, int) or frame < 0):
        raise InputError(origin, "frame", f"a frame index (an integer ≥ 0), got {_short(frame)}")
    status, error = d.get("status"), d.get("error")
    if status is not None and not isinstance(status, str):
        raise InputError(origin, "status", f"a string, got {_short(status)}")
    if not conv:
        nan = np.full(3, np.nan)
        return PoseRecord(
            np.full((3, 3), np.nan),
            nan,
            False,
            None,
            time_s,
            frame,
            status,
            None if error is None else str(error),
            origin,
        )
    for k in ("rotation", "translation_mm"):
        if k not in d:
            raise InputError(origin, k, "a value (the key is required)")
    R = _matrix(d["rotation"], 3, 3, origin, "rotation")
    if not (np.abs(R.T @ R - np.eye(3)).max() < ROTATION_TOL and abs(np.linalg.det(R) - 1) < ROTATION_TOL):
        raise InputError(origin, "rotation", "a rotation matrix (orthonormal, determinant +1)")
    tv = d["translation_mm"]
    if not isinstance(tv, list) or len(tv) != 3:
        raise InputError(origin, "translation_mm", f"a list of 3 numbers, got {_short(tv)}")
    t = np.array([_number(x, origin, f"translation_mm[{i}]") for i, x in enumerate(tv)])
    cov = d.get("covariance")
    if cov is not None:
        cov = _matrix(cov, 6, 6, origin, "covariance")
    return PoseRecord(R, t, True, cov, time_s, frame, status, None, origin)


def read_pose_records(path: str | Path) -> list[PoseRecord]:
    """Every pose of a SPEC §4 file: a single JSON object, or JSON Lines (one per line).

    Parameters
    ----------
    path : ``pose.json`` or ``poses.jsonl`` (``track``'s or ``solve``'s output).

    Returns
    -------
    list[PoseRecord] : in file order; at least one. InputError on a bad file.
    """
    text = read_text_input(path)
    if not text.strip():
        raise InputError(path, None, "at least one SPEC §4 pose object; the file is empty")
    try:
        whole = parse_json(text, path)
    except InputError:
        # not one JSON value: JSON Lines, each line's error named by its line
        return [pose_record(d, origin) for origin, d in json_lines(path, text)]
    return [pose_record(whole, str(path))]
