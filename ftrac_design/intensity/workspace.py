"""The pixel-level bound over the workspace, beside the feature-level one (``analyze --imaging``).

At each of a sample of workspace poses, two predicted 1σ errors per axis (rx, ry, rz, tx, ty, tz):

- **image** — the pixel-level Cramér–Rao bound (:func:`.bound.pixel_information`) of a
  radiograph rendered by :mod:`ftrac_design.xray` under a stated :class:`ImagingModel`
  (dose, blur, focal spot, energy), with the image's gain and a quadratic background unknown
  (``nuisance=True``: what :func:`.refine.refine_intensity` can reach), over the fiducial's
  region of interest (its projection plus 12 px), body included where the design has one;
- **features** — the feature-level bound of the existing analysis
  (:func:`ftrac_design.analysis.information.total_information`) at the same pose with the
  analysis's segmentation noise model (the paper's uniform error, σ per axis = e/√3).

Their ratio ``features / image`` says how much of the pose information segmentation throws
away (> 1: the image pins the pose better than the segmented features can). The pixel bound
costs ~13 renders of the region of interest per pose, hence a separate, smaller sample of
workspace poses (``poses``, default 60, drawn with the analysis's seed and workspace).
Angles in degrees at this edge (keys ``_deg``), lengths mm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera
from ..pose.problem import NoiseModel
from ..pose.simulate import ContourSampling, Workspace
from ..xray.materials import material_name
from ..xray.model import ImagingModel
from .bound import pixel_information
from .model import PARAMETERS

#: workspace poses of the image-level bound unless told (each costs ~13 ROI renders)
DEFAULT_IMAGING_POSES = 60
UNITS = ("deg", "deg", "deg", "mm", "mm", "mm")


def _deg_mm(std: np.ndarray) -> np.ndarray:
    """(…, 6) rad/mm → deg/mm."""
    out = np.array(std, float)
    out[..., :3] = np.degrees(out[..., :3])
    return out


@dataclass
class ImagingAnalysis:
    """Per-pose predicted 1σ (deg ×3, mm ×3) from the image and from the features, at poses R, t."""

    imaging: ImagingModel
    segmentation_error_mm: float
    R: np.ndarray
    t: np.ndarray
    image_std: np.ndarray  # (n, 6) deg / mm
    feature_std: np.ndarray  # (n, 6) deg / mm
    roi_pixels: np.ndarray  # (n,)
    body: str | None = None
    seed: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def ratio(self) -> np.ndarray:
        """(n, 6) feature-level / image-level σ per pose and axis."""
        return self.feature_std / self.image_std

    def plot(self, path: str | Path) -> Path:
        """Draw this analysis into ``path`` (PNG; :func:`plot_imaging`)."""
        return plot_imaging(self, path)

    def to_dict(self) -> dict[str, Any]:
        """The analysis.json ``imaging`` block."""

        def stats(a: np.ndarray) -> dict:
            return {
                k: dict(zip(PARAMETERS, np.percentile(a, q, axis=0).tolist())) for k, q in (("p50", 50), ("p95", 95))
            }

        im = self.imaging.to_dict()
        return {
            "settings": {
                "poses": int(len(self.t)),
                "seed": self.seed,
                "energy_kev": im["energy_kev"],
                "photons_per_px": im["photons_per_px"],
                "detector_blur_px": im["detector_blur_px"],
                "focal_spot_mm": im["focal_spot_mm"],
                "image_shape": im["image_shape"],
                "supersample": im["supersample"],
                "body": self.body,
                "segmentation_error_mm": self.segmentation_error_mm,
                "image_bound": "pixel-level Cramér–Rao bound, Poisson counts, gain and quadratic "
                "background unknown, ROI = projection + 12 px",
                "feature_bound": "solver Jacobian Cramér–Rao bound, uniform segmentation error "
                f"{self.segmentation_error_mm:g} mm (σ = e/√3 per axis)",
            },
            "units": dict(zip(PARAMETERS, UNITS)),
            "image_std": stats(self.image_std),
            "feature_std": stats(self.feature_std),
            "ratio_feature_to_image": stats(self.ratio),
            "roi_pixels_median": float(np.median(self.roi_pixels)),
        }


def imaging_analysis(
    features: Features,
    workspace: Workspace = Workspace(),
    imaging: ImagingModel = ImagingModel(),
    poses: int = DEFAULT_IMAGING_POSES,
    seed: int = 0,
    camera: Camera = Camera(),
    segmentation_error_mm: float = 0.25,
    contour: ContourSampling = ContourSampling(),
    progress: Callable[[int], None] | None = None,
) -> ImagingAnalysis:
    """Image- and feature-level predicted errors at ``poses`` workspace poses (see the module); the
    fiducial's body (``features.body``, where known) is part of the images.

    ``imaging`` must have a finite dose. Poses where the fiducial does not project into the
    image are skipped (ValueError if all are).
    """
    from ..analysis.information import feature_layout, total_information
    from ..analysis.sampling import workspace_poses

    if not imaging.noisy:
        raise ValueError("imaging: a finite dose (photons_per_px) is needed for a pixel-level bound")
    body = features.body
    R, t = workspace_poses(workspace, features.nominal_beam_direction, int(poses), seed)
    layout = feature_layout(features, contour)
    noise = NoiseModel.from_segmentation_error(segmentation_error_mm)
    keep, img_std, npix = [], [], []
    for k in range(len(t)):
        try:
            b = pixel_information(features, R[k], t[k], camera, imaging, nuisance=True)
        except (ValueError, np.linalg.LinAlgError):
            b = None
        if b is not None and np.all(np.isfinite(b.std)):
            keep.append(k)
            img_std.append(b.std)
            npix.append(b.roi[2] * b.roi[3])
        if progress is not None:
            progress(1)
    if not keep:
        raise ValueError("the fiducial projects into the image at none of the sampled poses")
    R, t = R[keep], t[keep]
    F = total_information(layout, camera, R, t, noise)
    feat = np.sqrt(np.diagonal(np.linalg.inv(F), axis1=1, axis2=2))
    name = (
        None
        if body is None
        else f"{material_name(body.material)} Ø{body.outer_diameter:g}/{body.bore_diameter:g} × {body.length:g} mm"
    )
    return ImagingAnalysis(
        imaging, segmentation_error_mm, R, t, _deg_mm(np.array(img_std)), _deg_mm(feat), np.array(npix), name, seed
    )


def plot_imaging(ia: ImagingAnalysis, path: str | Path) -> Path:
    """imaging.png: per axis, the distribution over the sampled poses of the predicted 1σ from
    the image and from the features (log scale), and their ratio."""
    from ..analysis.plots import pyplot, save_figure

    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    for ax, sl, unit in ((axes[0], slice(0, 3), "deg"), (axes[1], slice(3, 6), "mm")):
        names = PARAMETERS[sl]
        pos = np.arange(len(names))
        for off, data, lab, col in (
            (-0.18, ia.image_std[:, sl], "image (pixel bound)", "tab:blue"),
            (0.18, ia.feature_std[:, sl], "features (segmentation)", "tab:orange"),
        ):
            bp = ax.boxplot(
                data,
                positions=pos + off,
                widths=0.3,
                whis=(5, 95),
                showfliers=False,
                patch_artist=True,
                medianprops={"color": "k"},
            )
            for b in bp["boxes"]:
                b.set_facecolor(col)
                b.set_alpha(0.6)
            ax.plot([], [], color=col, lw=6, alpha=0.6, label=lab)
        ax.set_xticks(pos, names)
        ax.set_yscale("log")
        ax.set_ylabel(f"predicted 1σ ({unit})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    ax = axes[2]
    ax.boxplot(ia.ratio, whis=(5, 95), showfliers=False, medianprops={"color": "k"})
    ax.set_xticks(np.arange(1, 7), PARAMETERS)
    ax.set_yscale("log")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylabel("σ features / σ image")
    ax.grid(True, which="both", alpha=0.3)
    dose = ia.imaging.photons_per_px
    fig.suptitle(
        f"pose from the image vs from segmented features, {len(ia.t)} workspace poses "
        f"({ia.imaging.energy_kev:g} keV, {dose:.3g} quanta/px, segmentation error "
        f"{ia.segmentation_error_mm:g} mm)",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, Path(path))


def format_imaging(block: dict) -> str:
    """Lines for the text summary from an analysis.json ``imaging`` block."""
    s = block["settings"]
    out = [
        f"  imaging ({s['poses']} poses, {s['energy_kev']:g} keV, {s['photons_per_px']:.3g} quanta/px, "
        f"blur {s['detector_blur_px']:g} px, focal spot {s['focal_spot_mm']:g} mm): predicted 1σ "
        f"(deg, mm) vs features at segmentation error {s['segmentation_error_mm']:g} mm"
    ]
    out.append("    " + f"{'':>19}" + "".join(f"{a:>10}" for a in PARAMETERS))
    for key, lab in (("image_std", "image"), ("feature_std", "features"), ("ratio_feature_to_image", "features/image")):
        for q in ("p50", "p95"):
            out.append(f"    {lab + ' ' + q:>19}" + "".join(f"{block[key][q][a]:10.3g}" for a in PARAMETERS))
    return "\n".join(out)
