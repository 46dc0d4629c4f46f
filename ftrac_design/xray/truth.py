"""``truth.json``: what a simulated radiograph shows, for scoring segmentation and tracking.

::

    {"format": "ftrac-radiograph-truth", "version": 1, "image": "<file name>",
     "pose": <SPEC §4 object, converged true, no covariance>, "camera": <SPEC §3 camera>,
     "imaging": {...ImagingModel...}, "body": {...} | null, "occluders": [...],
     "background": null | "anatomy seed S" | "given" | "<file>",
     "projected": {"points": {id: [u, v]},
                   "lines": {id: {"start": [u, v], "end": [u, v]}},
                   "ellipses": {id: {"conic": [A, B, C, D, E, F], "center": [u, v],
                                     "projected_center": [u, v]}}}}

Pixel coordinates follow SPEC §1 (``img[j, i]`` is centred at (u, v) = (i, j)). An
ellipse's ``center`` is the centre of its image conic; ``projected_center`` is the
projection of the 3-D centre (they differ under perspective). The conic is scaled to unit
norm, sign chosen so that F < 0 (inside negative).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..design import Body
from ..errors import InputError
from ..features.model import Features
from ..fileio import write_json_atomic
from ..pose.camera import Camera
from ..pose.fitting import conic_center_and_axes, conic_vector
from ..pose.record import Pose, TrackedPose
from ..pose.simulate import projected_conic
from .materials import material_name
from .model import ImagingModel, Occluder

FORMAT = "ftrac-radiograph-truth"
VERSION = 1


def _uv(camera: Camera, X: np.ndarray) -> list[float]:
    return [float(x) for x in camera.project(X)]


def projected_features(features: Features, R: np.ndarray, t: np.ndarray, camera: Camera) -> dict[str, Any]:
    """The ``projected`` object: exact projections of every feature at pose (R, t)."""
    R, t = np.asarray(R, float), np.asarray(t, float)
    out: dict[str, Any] = {"points": {}, "lines": {}, "ellipses": {}}
    for p in features.points:
        out["points"][p.id] = _uv(camera, R @ p.center + t)
    for ln in features.lines:
        out["lines"][ln.id] = {"start": _uv(camera, R @ ln.start + t), "end": _uv(camera, R @ ln.end + t)}
    for el in features.ellipses:
        M = projected_conic(el, camera, R[None], t[None])[0]
        theta = conic_vector(M)
        theta = theta / np.linalg.norm(theta)
        if theta[5] > 0:
            theta = -theta
        c, _, _ = conic_center_and_axes(theta)
        out["ellipses"][el.id] = {
            "conic": [float(x) for x in theta],
            "center": [float(x) for x in c],
            "projected_center": _uv(camera, R @ el.center + t),
        }
    return out


def body_dict(body: Body) -> dict[str, Any]:
    """The JSON object of a body as truth.json holds it: its sizes (mm) and the material as the
    simulator names it (:func:`.materials.material_name`: ``"acetal (POM-C)"`` → ``"acetal"``)."""
    return {
        "outer_diameter": body.outer_diameter,
        "length": body.length,
        "bore_diameter": body.bore_diameter,
        "material": material_name(body.material),
    }


def truth_dict(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera,
    imaging: ImagingModel,
    image_name: str = "",
    occluders: Sequence[Occluder] = (),
    background: str | None = None,
) -> dict[str, Any]:
    """The truth.json object of one rendered image (see module); its ``body`` is
    ``features.body`` with the material as the simulator names it (``"acetal"``)."""
    R, t = np.asarray(R, float), np.asarray(t, float)
    return {
        "format": FORMAT,
        "version": VERSION,
        "image": image_name,
        "features": features.name,
        # the true pose: SPEC §4's own keys, exact (no residual, no covariance)
        "pose": TrackedPose(Pose(R, t, True, 0.0, None, {}, 0)).spec_dict(),
        "camera": camera.to_dict(),
        "imaging": imaging.to_dict(),
        "body": None if features.body is None else body_dict(features.body),
        "occluders": [o.to_dict() for o in occluders],
        "background": background,
        "projected": projected_features(features, R, t, camera),
    }


def write_truth(path: str | Path, truth: dict[str, Any]) -> Path:
    """Write a truth object atomically."""
    return write_json_atomic(path, truth)


def read_truth(path: str | Path) -> dict[str, Any]:
    """Read a truth.json; adds ``"R"``, ``"t"`` (numpy) and ``"camera_obj"`` (Camera) for convenience.

    InputError naming the file and key when it is not a truth file.
    """
    path = Path(path)
    try:
        d = json.loads(path.read_text("utf-8"))
    except OSError as exc:
        raise InputError(path, None, f"a readable file ({exc.strerror})") from None
    except ValueError:
        raise InputError(path, None, "JSON text") from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise InputError(path, "format", f"'{FORMAT}'")
    try:
        d["R"] = np.asarray(d["pose"]["rotation"], float).reshape(3, 3)
        d["t"] = np.asarray(d["pose"]["translation_mm"], float).reshape(3)
        c = d["camera"]
        d["camera_obj"] = Camera(
            float(c["focal_length_mm"]),
            tuple(map(float, c["pixel_size_mm"])),
            tuple(map(float, c["principal_point_px"])),
        )
    except (KeyError, TypeError, ValueError):
        raise InputError(path, "pose/camera", "a SPEC §4 pose and a §3 camera") from None
    return d
