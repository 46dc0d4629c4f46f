"""The blind-spot atlas: conditioning and predicted error over every view direction.

Each direction is a pose with the fiducial origin on the principal ray at the workspace
depth (roll 0 — the figures mapped here do not depend on the roll there, see
:mod:`.sampling`). Two grids: the whole sphere (longitude about the fiducial axis, latitude
toward ``+z``; drawn in a Mollweide projection) and the workspace cone around the nominal
beam (drawn as a polar map). The worst directions are where the design's scaled Jacobian
comes closest to losing rank (the largest condition number; for a design that cannot fix
all six DOF, such as a lone ellipse, the smallest σ_r/σ₁ with r its attainable rank), at
least ``separation_deg`` apart; for each the features that have gone blind there are named —
those whose own rank ratio (σ_rank/σ₁ of the feature alone) has fallen below a quarter of its
median over the sphere, with their view angle: an ellipse seen edge-on (the paper's §II.A.2
singularity) or face-on and centred (a tilt then changes its image only to second order), or a
line seen end-on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..features.model import Features
from .poses import PoseAnalysis, analyse_poses
from .sampling import angle_from, cone_grid, isocentre_poses, sphere_grid
from .score import AnalysisSettings

#: relative rank ratio below which a feature counts as blind in a direction
BLIND_FACTOR = 0.25


@dataclass
class Atlas:
    """Metrics on the sphere grid (``lon``, ``lat`` deg, shape (nlat, nlon)) and on the
    workspace cone grid (``polar``, ``azimuth`` deg, shape (npolar, naz))."""

    name: str
    lon: np.ndarray
    lat: np.ndarray
    sphere: PoseAnalysis
    polar: np.ndarray
    azimuth: np.ndarray
    cone: PoseAnalysis
    cone_deg: float
    nominal_beam: np.ndarray
    worst: list[dict]
    blind_fraction: dict[str, float]

    def grid(self, values: np.ndarray) -> np.ndarray:
        """Per-direction values of the sphere analysis reshaped to the (nlat, nlon) grid."""
        return np.asarray(values).reshape(self.lon.shape)

    def cone_grid(self, values: np.ndarray) -> np.ndarray:
        """Per-direction values of the cone analysis reshaped to the (npolar, naz) grid."""
        return np.asarray(values).reshape(self.polar.shape)

    def relative_rank_ratio(self) -> np.ndarray:
        """(nlat, nlon, F) each feature's rank ratio over its median on the sphere."""
        rr = self.sphere.rank_ratio
        return (rr / np.median(rr, 0)).reshape(self.lon.shape + (rr.shape[1],))

    def to_dict(self) -> dict:
        """The atlas part of analysis.json (None where a figure is infinite: singular)."""
        m, c = self.sphere.overall, self.cone.overall
        inside = angle_from(self.nominal_beam, self.sphere.beam_directions())[0] <= self.cone_deg
        rd = self.sphere.rank_deficiency()
        return {
            "sphere_step_deg": float(abs(self.lon[0, 1] - self.lon[0, 0])),
            "directions": int(m.condition.size),
            "attainable_rank": self.sphere.attainable_rank(),
            "rank_ratio": {"median": float(np.median(rd)), "worst": float(np.min(rd))},
            "condition": {
                "median": _finite(np.median(m.condition)),
                "worst": _finite(np.max(m.condition)),
                "worst_in_cone": _finite(np.max(c.condition)),
            },
            "translation_mm": {
                "median": _finite(np.median(m.translation_rms_mm)),
                "worst": _finite(np.max(m.translation_rms_mm)),
                "worst_in_cone": _finite(np.max(c.translation_rms_mm)),
            },
            "rotation_deg": {
                "median": _finite(np.median(m.rotation_rms_deg)),
                "worst": _finite(np.max(m.rotation_rms_deg)),
                "worst_in_cone": _finite(np.max(c.rotation_rms_deg)),
            },
            "singular_fraction_of_sphere": float(np.mean(~np.isfinite(m.condition))),
            "fraction_of_sphere_within_cone": float(np.mean(inside)),
            "blind_fraction_of_sphere": self.blind_fraction,
            "worst_directions": self.worst,
        }


def _finite(x) -> float | None:
    return float(x) if np.isfinite(x) else None


def blind_spot_atlas(
    features: Features,
    settings: AnalysisSettings = AnalysisSettings(),
    step_deg: float = 2.0,
    n_worst: int = 6,
    separation_deg: float = 15.0,
    progress: Callable[[int], None] | None = None,
) -> Atlas:
    """Map ``features`` over the whole sphere (``step_deg`` grid) and the workspace cone.

    Parameters
    ----------
    features : Features
        The design's features.
    settings : AnalysisSettings
        Depth, camera, noise and the workspace cone.
    step_deg : float
        The sphere grid's step, degrees.
    n_worst : int
        How many worst view directions to report.
    separation_deg : float
        The smallest angle between two reported worst directions, degrees.
    progress : callable or None
        Called with the number of directions done.

    Returns
    -------
    Atlas
        The sphere's and the cone's analyses, the worst directions and each feature's blind share.
    """
    lon, lat, d = sphere_grid(step_deg)
    depth = settings.workspace.depth_mm
    sph = _analyse_directions(features, d, depth, settings, progress)
    pol, az, dc = cone_grid(features.nominal_beam_direction, settings.workspace.cone_deg)
    cone = _analyse_directions(features, dc, depth, settings, progress)
    ref = np.median(sph.rank_ratio, 0)
    blind = {fid: float(np.mean(sph.rank_ratio[:, f] < BLIND_FACTOR * ref[f])) for f, fid in enumerate(sph.layout.ids)}
    worst = _worst_directions(features, settings, sph, lon, lat, ref, n_worst, separation_deg)
    return Atlas(
        features.name,
        lon,
        lat,
        sph,
        pol,
        az,
        cone,
        settings.workspace.cone_deg,
        np.asarray(features.nominal_beam_direction, float),
        worst,
        blind,
    )


def _analyse_directions(features: Features, directions: np.ndarray, depth: float, settings, progress):
    """The analysis at the isocentre pose of each view direction."""
    R, t = isocentre_poses(directions.reshape(-1, 3), depth)
    return analyse_poses(
        features,
        R,
        t,
        settings.camera,
        settings.noise,
        settings.contour,
        detail=True,
        leave_one_out=False,
        progress=progress,
    )


def _worst_directions(features, settings, sph, lon, lat, ref, n_worst: int, separation_deg: float) -> list[dict]:
    """The view directions closest to losing rank (largest condition number, or for a design that
    cannot fix all six DOF the smallest σ_r/σ₁; ties by predicted error), each at least
    ``separation_deg`` from the others, with the features responsible."""
    m = sph.overall
    order = np.lexsort((-np.nan_to_num(m.translation_rms_mm, posinf=1e300), sph.rank_deficiency()))
    beams = sph.beam_directions()
    cos_sep = np.cos(np.radians(separation_deg))
    chosen: list[int] = []
    for i in order:
        if all(beams[i] @ beams[j] < cos_sep for j in chosen):
            chosen.append(int(i))
            if len(chosen) == n_worst:
                break
    polar, azim = angle_from(features.nominal_beam_direction, beams[chosen])
    return [
        {
            "beam_direction": [float(v) for v in beams[i]],
            "lon_deg": float(lon.flat[i]),
            "lat_deg": float(lat.flat[i]),
            "angle_from_nominal_deg": float(polar[k]),
            "azimuth_deg": float(azim[k]),
            "in_workspace": bool(polar[k] <= settings.workspace.cone_deg),
            "condition": _finite(m.condition[i]),
            "rank_ratio": float(sph.rank_deficiency()[i]),
            "translation_error_mm": _finite(m.translation_rms_mm[i]),
            "rotation_error_deg": _finite(m.rotation_rms_deg[i]),
            "responsible": sph.responsible(i, ref, BLIND_FACTOR),
        }
        for k, i in enumerate(chosen)
    ]
