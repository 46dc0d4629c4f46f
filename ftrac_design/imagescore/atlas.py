"""The image-true blind-spot atlas: where on the sphere of view directions the fiducial fails to
track from a radiograph.

The paper's atlas (:mod:`ftrac_design.analysis.atlas`) maps the feature-level bound; it cannot see a
labelling that fails, features that overlap in the image, or a wire too faint to find. Here each
direction of a coarse longitude/latitude grid (:func:`ftrac_design.analysis.sampling.sphere_grid`)
is imaged at a few rolls about the beam with the fiducial at the isocentre (clean images,
:class:`ftrac_design.xray.ImagingModel`'s defaults, the noise seeded by direction and roll), each
image tracked with the default options (no time budget), and the direction gets the share of its
images tracked right and the median 3-D translation error of those.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.sampling import angle_from, isocentre_poses, sphere_grid
from ..features.model import Features
from ..pose.camera import Camera
from .trial import track_record

#: directions per task sent to an executor
CHUNK = 6


@dataclass(frozen=True)
class AtlasSettings:
    """The image-true atlas' grid: step (degrees at this edge), rolls per direction, seed, the
    fiducial's distance from the source (mm) and the camera."""

    step_deg: float = 20.0
    rolls: int = 2
    seed: int = 0
    depth_mm: float = 667.0
    camera: Camera = field(default_factory=Camera)


def _direction_records(
    features: Features, settings: AtlasSettings, directions: np.ndarray, indices: Sequence[int]
) -> list[dict[str, Any]]:
    from ..xray import ImagingModel, render

    out = []
    for i in indices:
        for j in range(settings.rolls):
            roll = 2.0 * math.pi * (j + 0.5) / settings.rolls
            R, t = isocentre_poses(directions[i][None], settings.depth_mm, roll)
            img = render(
                features,
                R[0],
                t[0],
                settings.camera,
                ImagingModel(),
                rng=np.random.default_rng([settings.seed, int(i), j, 3]),
            ).raw
            out.append({"direction": int(i), "roll": j, **track_record(img, features, R[0], t[0], settings.camera)})
    return out


def image_atlas(
    features: Features,
    settings: AtlasSettings = AtlasSettings(),
    executor: Executor | None = None,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Track the fiducial from every direction of the grid (see the module).

    Parameters
    ----------
    features : Features
        The fiducial (SPEC §2); its body (``features.body``), where known, is rendered and known
        to the tracker.
    settings : AtlasSettings
        Grid, rolls, seed, depth and camera.
    executor : concurrent.futures.Executor or None
        Where the images are made and tracked (None: here).
    progress : callable or None
        Called with the number of images done.

    Returns
    -------
    dict
        ``lon_deg``, ``lat_deg`` (nlat × nlon cell centres), ``right_share`` and
        ``translation_median_mm`` (nlat × nlon; None where no image was right),
        ``angle_from_nominal_deg`` per cell, ``settings``, the share right within the workspace cone
        (25°) and over the sphere, and the worst directions.
    """
    lon, lat, d = sphere_grid(settings.step_deg)
    dirs = d.reshape(-1, 3)
    records = _track_directions(features, settings, dirs, executor, progress)
    right = np.zeros(len(dirs))
    median = np.full(len(dirs), np.nan)
    for i in range(len(dirs)):
        mine = [r for r in records if r["direction"] == i]
        ok = [r["translation_mm"] for r in mine if r["outcome"] == "right"]
        right[i] = len(ok) / len(mine)
        if ok:
            median[i] = float(np.median(ok))
    polar, _ = angle_from(features.nominal_beam_direction, dirs)
    in_cone = polar <= 25.0
    order = np.lexsort((np.nan_to_num(-median, nan=-np.inf), right))[:5]
    return {
        "settings": {
            "step_deg": settings.step_deg,
            "rolls": settings.rolls,
            "seed": settings.seed,
            "depth_mm": settings.depth_mm,
        },
        "lon_deg": lon.tolist(),
        "lat_deg": lat.tolist(),
        "right_share": right.reshape(lon.shape).tolist(),
        "translation_median_mm": [
            [None if not np.isfinite(v) else float(v) for v in row] for row in median.reshape(lon.shape)
        ],
        "angle_from_nominal_deg": polar.reshape(lon.shape).tolist(),
        "right_share_sphere": float(right.mean()),
        "right_share_cone": float(right[in_cone].mean()) if in_cone.any() else None,
        "worst": [
            {
                "lon_deg": float(lon.flat[i]),
                "lat_deg": float(lat.flat[i]),
                "angle_from_nominal_deg": float(polar[i]),
                "right_share": float(right[i]),
            }
            for i in order
        ],
    }


def _track_directions(features, settings: AtlasSettings, dirs: np.ndarray, executor, progress) -> list[dict]:
    """Every direction's images made and tracked, in chunks (here, or on ``executor``), in order."""
    tasks = [list(range(i, min(i + CHUNK, len(dirs)))) for i in range(0, len(dirs), CHUNK)]
    records: list[dict[str, Any]] = []
    if executor is None:
        for idx in tasks:
            records += _direction_records(features, settings, dirs, idx)
            if progress:
                progress(len(idx) * settings.rolls)
    else:
        futures = [executor.submit(_direction_records, features, settings, dirs, idx) for idx in tasks]
        for fut, idx in zip(futures, tasks):
            records += fut.result()
            if progress:
                progress(len(idx) * settings.rolls)
    return records


def plot_image_atlas(atlas: dict[str, Any], path: str | Path, title: str = "") -> Path:
    """Draw the atlas' two maps (share tracked right; median translation error) on longitude/latitude
    axes, the nominal beam's 25° workspace cone outlined, to ``path`` (PNG); returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lon, lat = np.array(atlas["lon_deg"]), np.array(atlas["lat_deg"])
    ang = np.array(atlas["angle_from_nominal_deg"])
    share = np.array(atlas["right_share"], float)
    med = np.array([[np.nan if v is None else v for v in row] for row in atlas["translation_median_mm"]], float)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    extent = (-180, 180, -90, 90)
    for ax, data, label, cmap, vmin, vmax in (
        (axes[0], share, "share of images tracked right", "RdYlGn", 0, 1),
        (axes[1], med, "median 3-D translation error (mm)", "viridis", None, None),
    ):
        im = ax.imshow(data, origin="lower", extent=extent, aspect="auto", cmap=cmap, vmin=vmin, vmax=vmax)
        ax.contour(lon, lat, ang, levels=[25.0], colors="k", linewidths=1.0)
        ax.set_xlabel("longitude about the fiducial axis (°)")
        ax.set_ylabel("latitude toward +z (°)")
        fig.colorbar(im, ax=ax, label=label)
    s = atlas["settings"]
    fig.suptitle(
        (title or "image-true atlas") + f" — {s['step_deg']:g}° grid, {s['rolls']} rolls per direction; "
        f"right: {100 * atlas['right_share_sphere']:.0f} % of the sphere"
        + (
            f", {100 * atlas['right_share_cone']:.0f} % in the workspace cone (outlined)"
            if atlas["right_share_cone"] is not None
            else ""
        ),
        fontsize=9,
    )
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
