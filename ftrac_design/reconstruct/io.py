"""Files of ``ftrac-design reconstruct``: poses, image points, camera, transform in; result out.

Inputs (every problem raises :class:`~ftrac_design.errors.InputError` naming the file, the
line for JSON Lines, the key and what was expected):

- poses: JSON Lines of SPEC §4 pose objects, one per image. A pose with ``"converged":
  false`` or no rotation leaves its image unused; a ``null`` covariance counts as an exact pose.
- points: JSON Lines, one ``{id: [u, v]}`` object per image, in the order of the poses
  (SPEC §5). Ids are any strings (seeds, beads, …).
- camera: a SPEC §3 ``camera`` object (or an object holding one under ``"camera"``), for
  every image. *Extension:* a pose line or a points line may carry its own ``"camera"``
  object (then ``camera`` is not a point id); ``--camera`` overrides both (SPEC §5).
- transform: a rigid 4×4 ``target_from_source``, bare (a list of 4 rows) or as an object
  ``{"matrix": 4x4, "name": "ultrasound", "covariance": 6x6}`` (the covariance optional;
  rotation vector rad on the left then translation mm, as SPEC §4's).

Output (format ``ftrac-reconstruction``, version 1): see :func:`result_dict`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..fileio import json_lines, parse_json, read_text_input
from ..pose import TrackedPose
from ..pose.observation import camera_from_dict
from ..pose.record import finite_number, number_matrix, short_json
from .frames import RigidTransform, is_rigid

FORMAT = "ftrac-reconstruction"
VERSION = 1


def _json_lines(path: Path, what: str) -> list[tuple[str, Any]]:
    """(origin "file:line", parsed object) per non-blank line."""
    out = []
    for origin, d in json_lines(path):
        if not isinstance(d, dict):
            raise InputError(origin, None, f"a JSON object ({what}), got {short_json(d)}")
        out.append((origin, d))
    if not out:
        raise InputError(path, None, f"at least one line ({what}); the file is empty")
    return out


def read_poses(path: Path) -> list[dict[str, Any]]:
    """One dict per line of a run's poses (each read by :meth:`ftrac_design.pose.TrackedPose.from_dict`):
    ``R``, ``t``, ``cov`` (6×6, symmetric positive semi-definite, or None), ``camera`` (or
    None), ``usable`` and ``why`` (when not), ``origin``."""
    out = []
    for origin, d in _json_lines(path, "an ftrac-pose"):
        rec = TrackedPose.from_dict(d, origin)
        pose = rec.pose
        item: dict[str, Any] = {"origin": origin, "usable": True, "why": None, "cov": None}
        item["camera"] = rec.provenance.camera
        if not pose.converged:
            why = f"pose not solved ({pose.error or 'converged: false'})"
            item.update(usable=False, why=why, R=np.full((3, 3), np.nan), t=np.full(3, np.nan))
            out.append(item)
            continue
        cov = pose.covariance
        if cov is not None:
            if not (
                np.allclose(cov, cov.T, atol=1e-9 * max(1.0, np.abs(cov).max()))
                and np.linalg.eigvalsh((cov + cov.T) / 2).min() >= -1e-12 * max(1.0, np.abs(cov).max())
            ):
                raise InputError(origin, "covariance", "a symmetric positive semi-definite 6x6 matrix")
            cov = (cov + cov.T) / 2
        item.update(R=pose.rotation, t=pose.translation_mm, cov=cov)
        out.append(item)
    return out


def read_points(path: Path) -> list[dict[str, Any]]:
    """One dict per line: ``points`` {id: (2,) px}, ``camera`` (or None), ``origin``."""
    out = []
    for origin, d in _json_lines(path, "{id: [u, v]} for one image"):
        cam = camera_from_dict(d["camera"], origin) if "camera" in d else None
        pts = {}
        for k, v in d.items():
            if k == "camera":
                continue
            if not isinstance(v, list) or len(v) != 2:
                raise InputError(origin, k, f"[u, v] pixel coordinates, got {short_json(v)}")
            pts[k] = np.array([finite_number(x, origin, f"{k}[{i}]") for i, x in enumerate(v)])
        out.append({"origin": origin, "points": pts, "camera": cam})
    return out


def read_transform(path: Path, source: str) -> RigidTransform:
    """``--transform T.json``: a rigid 4×4 from ``source`` to the frame it names (default "user")."""
    d = parse_json(read_text_input(path), path)
    origin = str(path)
    name, cov = "user", None
    if isinstance(d, dict):
        if "matrix" not in d:
            raise InputError(origin, "matrix", "a 4x4 rigid transform (the key is required)")
        name = d.get("name", name)
        if not isinstance(name, str) or not name:
            raise InputError(origin, "name", f"a frame name (string), got {short_json(name)}")
        if d.get("covariance") is not None:
            cov = number_matrix(d["covariance"], 6, 6, origin, "covariance")
            if not (np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() >= -1e-12):
                raise InputError(origin, "covariance", "a symmetric positive semi-definite 6x6 matrix")
        M = number_matrix(d["matrix"], 4, 4, origin, "matrix")
        key = "matrix"
    else:
        M = number_matrix(d, 4, 4, origin, "matrix")
        key = "matrix"
    if not is_rigid(M):
        raise InputError(origin, key, "a rigid 4x4 transform (orthonormal rotation, det +1, last row 0 0 0 1), mm")
    return RigidTransform(M, source, name, cov)


def _fin(a: np.ndarray, nd: int = 6) -> Any:
    a = np.asarray(a, float)
    return np.round(a, nd).tolist() if np.isfinite(a).all() else None


def result_dict(
    ids: list[str],
    tri,
    P: np.ndarray,
    cov: np.ndarray,
    frame: str,
    chain: list[str],
    views_index: list[int],
    skipped: list[dict[str, Any]],
    noise_px: list[float],
    P_F: np.ndarray,
    cov_F: np.ndarray,
) -> dict[str, Any]:
    """The ``ftrac-reconstruction`` object.

    ``points`` maps each id to either ``{"position_mm", "covariance_mm2", "std_mm", "frame",
    "views", "rms_reprojection_px", "parallax_deg"}`` (plus ``position_fiducial_mm`` and
    ``covariance_fiducial_mm2`` when ``frame`` is not the fiducial) or ``{"refused": reason,
    "views"}``; ``views`` are 0-based image indices (line order of the input files).
    """
    points: dict[str, Any] = {}
    for k, pid in enumerate(ids):
        views = [views_index[i] for i in np.flatnonzero(tri.used[:, k])]
        if tri.refused[k] is not None:
            points[pid] = {"refused": tri.refused[k], "views": views}
            continue
        e: dict[str, Any] = {
            "frame": frame,
            "position_mm": _fin(P[k]),
            "covariance_mm2": _fin(cov[k], 9),
            "std_mm": _fin(np.sqrt(np.diag(cov[k]))),
            "views": views,
            "rms_reprojection_px": round(float(tri.rms_px[k]), 6),
            "parallax_deg": round(float(tri.parallax_deg[k]), 4),
        }
        if frame != "fiducial":
            e["position_fiducial_mm"] = _fin(P_F[k])
            e["covariance_fiducial_mm2"] = _fin(cov_F[k], 9)
        points[pid] = e
    return {
        "format": FORMAT,
        "version": VERSION,
        "units": "mm",
        "frame": frame,
        "frame_chain": chain,
        "images": len(views_index) + len(skipped),
        "images_used": views_index,
        "images_skipped": skipped,
        "noise_px": noise_px,
        "reconstructed": int(tri.ok.sum()),
        "refused": int((~tri.ok).sum()),
        "points": points,
    }
