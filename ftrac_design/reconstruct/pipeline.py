"""From parsed inputs to the ``ftrac-reconstruction`` result: pairing, cameras, noise, frames."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from ..errors import InputError
from ..features.model import Features
from ..pose.camera import Camera
from ..pose.problem import NoiseModel
from . import frames as fr
from .io import result_dict
from .triangulate import MIN_PARALLAX_DEG, Views, triangulate

#: output frames reachable from F through features.json
FRAME_KEYS = {"fiducial": None, "template": "template_from_fiducial"}


def build_views(
    poses: list[dict],
    points: list[dict],
    camera: Camera | None,
    noise_px: float | None,
    poses_file: str,
    points_file: str,
) -> tuple[Views, list[int], list[dict], list[str], np.ndarray, np.ndarray]:
    """Views of the usable images, their input indices, the skipped ones (with why), the
    point ids and the pixels (N, n, 2) / seen mask (N, n)."""
    if len(poses) != len(points):
        raise InputError(
            points_file, None, f"one line per pose: {len(poses)} poses in {poses_file}, {len(points)} lines here"
        )
    used, skipped = [], []
    R, t, intr, sig, cov = [], [], [], [], []
    for i, (p, q) in enumerate(zip(poses, points)):
        cam = camera or p["camera"] or q["camera"]
        if cam is None:
            raise InputError(
                p["origin"],
                "camera",
                'a camera for this image: give --camera C.json, or a "camera" object in the pose or points line',
            )
        if not p["usable"]:
            skipped.append({"index": i, "reason": p["why"]})
            continue
        used.append(i)
        R.append(p["R"])
        t.append(p["t"])
        intr.append(cam.intrinsics)
        # SPEC's default segmentation error (0.25 mm uniform magnitude: σ = 0.102 mm per axis)
        sig.append(noise_px if noise_px is not None else NoiseModel().point_mm / float(np.mean(cam.pixel_size_mm)))
        cov.append(p["cov"] if p["cov"] is not None else np.zeros((6, 6)))
    ids = sorted({k for q in points for k in q["points"]})
    if not ids:
        raise InputError(points_file, None, "at least one image point ({id: [u, v]})")
    n = len(ids)
    uv = np.full((len(used), n, 2), np.nan)
    for a, i in enumerate(used):
        for k, pid in enumerate(ids):
            if pid in points[i]["points"]:
                uv[a, k] = points[i]["points"][pid]
    views = Views.make(
        np.array(R).reshape(-1, 3, 3),
        np.array(t).reshape(-1, 3),
        np.array(intr).reshape(-1, 4),
        np.array(sig),
        np.array(cov).reshape(-1, 6, 6),
    )
    return views, used, skipped, ids, uv, np.isfinite(uv).all(-1)


def reconstruct(
    features: Features,
    poses: list[dict],
    points: list[dict],
    camera: Camera | None = None,
    to: Literal["fiducial", "template"] = "fiducial",
    transform: fr.RigidTransform | None = None,
    noise_px: float | None = None,
    min_parallax_deg: float = MIN_PARALLAX_DEG,
    template_sigma_mm: float = 0.0,
    poses_file: str = "<poses>",
    points_file: str = "<points>",
    features_file: str = "<features>",
) -> dict[str, Any]:
    """The ``ftrac-reconstruction`` object for parsed inputs (see :mod:`.io`)."""
    views, used, skipped, ids, uv, seen = build_views(poses, points, camera, noise_px, poses_file, points_file)
    if views.N:
        tri = triangulate(views, uv, seen, min_parallax_deg)
    else:
        from .triangulate import Triangulation

        n = len(ids)
        tri = Triangulation(
            np.full((n, 3), np.nan),
            np.full((n, 3, 3), np.nan),
            np.full(n, np.nan),
            np.zeros((0, n), bool),
            np.full(n, np.nan),
            ["no usable pose"] * n,
        )
    chain_t: list[fr.RigidTransform] = []
    names = ["fiducial"]
    if to == "template":
        key = FRAME_KEYS["template"]
        if key not in features.frames:
            raise InputError(features_file, f"frames.{key}", "a 4x4 matrix (needed for --to template)")
        cov_t = fr.isotropic_covariance(template_sigma_mm) if template_sigma_mm > 0 else None
        chain_t.append(fr.RigidTransform(np.asarray(features.frames[key], float), "fiducial", "template", cov_t))
        names.append("template")
    if transform is not None:
        chain_t.append(transform)
        names.append(transform.target)
    ok = tri.ok
    P, cov = tri.P.copy(), tri.cov.copy()
    if ok.any():
        P[ok], cov[ok] = fr.chain(tri.P[ok], tri.cov[ok], chain_t)
    return result_dict(ids, tri, P, cov, names[-1], names, used, skipped, views.sigma_px.tolist(), tri.P, tri.cov)
