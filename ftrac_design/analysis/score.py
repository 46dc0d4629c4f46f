"""The design score: predicted pose accuracy and conditioning over the workspace.

Figures (all from the Cramér–Rao bound of the solver's whitened Jacobian, see
:mod:`.information` and :mod:`.metrics`, at the stated segmentation error):

- ``translation_mm``: the 3-D RMS translation error √tr(Σ_t), worst case and 95th
  percentile over the workspace poses; per camera axis the 95th percentile of each standard
  deviation (z is depth, by far the largest, as in the paper's Table II);
- ``rotation_deg``: the 3-D RMS rotation error √tr(Σ_δ), likewise;
- ``condition``: the condition number of the scaled Jacobian J·H, worst and median.

A design passes when its worst translation, worst rotation and worst condition are all
within the thresholds — and, where those thresholds are set, when its features' images
stay apart (:mod:`.segmentability`: the share of workspace poses where they overlap, and
the 5th-percentile smallest clearance in px). The default thresholds come from the paper's accuracy budget
(§IV: the fiducial's pose accurate to about 0.5 mm inside a < 2 mm system budget; phantom
results 0.56 mm and 0.33°): 1 mm and 0.5° for the worst 1σ 3-D error at 0.25 mm
segmentation error, and a condition number of 1000 (well-placed features give ~50).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera
from ..pose.problem import NoiseModel
from ..pose.simulate import ContourSampling, Workspace
from .metrics import PoseMetrics
from .poses import PoseAnalysis, analyse_poses
from .sampling import angle_from, workspace_poses
from .segmentability import ClearanceSettings, Segmentability
from .segmentability import segmentability as _segmentability

DEFAULT_POSES = 20_000
#: workspace poses whose image clearances are measured (the first of the scored ones, an
#: i.i.d. sample: ±0.5 % on a 13 % share), ~0.1 ms each against ~0.02 ms for the conditioning
SEGMENTABILITY_POSES = 5_000


@dataclass(frozen=True)
class Thresholds:
    """Pass/fail limits of the design score (worst case over the workspace)."""

    max_translation_mm: float = 1.0
    max_rotation_deg: float = 0.5
    max_condition: float = 1000.0
    #: largest share of workspace poses where features' images may overlap (None: not judged)
    max_overlap_share: float | None = None
    #: smallest 5th-percentile image clearance between features, px (None: not judged)
    min_clearance_px: float | None = None


@dataclass(frozen=True)
class AnalysisSettings:
    """How a design is analysed: workspace, noise and sampling. Degrees only at this edge."""

    workspace: Workspace = field(default_factory=Workspace)
    segmentation_error_mm: float = 0.25
    #: bead centres' and wire contours' error as multiples of ``segmentation_error_mm``
    bead_error_factor: float = 1.0
    wire_error_factor: float = 1.0
    poses: int = DEFAULT_POSES
    seed: int = 0
    camera: Camera = field(default_factory=Camera)
    contour: ContourSampling = field(default_factory=ContourSampling)
    clearance: ClearanceSettings = field(default_factory=ClearanceSettings)
    segmentability_poses: int = SEGMENTABILITY_POSES

    @property
    def noise(self) -> NoiseModel:
        """The paper's uniform segmentation error as per-axis σ: beads ×``bead_error_factor``,
        line and ellipse contours ×``wire_error_factor``."""
        return NoiseModel.from_segmentation_error(self.segmentation_error_mm).scaled(
            self.bead_error_factor, self.wire_error_factor
        )

    def for_parts(self, spec) -> "AnalysisSettings":
        """These settings with the (bead, wire) error factors of a design's [analysis] table
        ``spec`` — the errors its own parts are read with (:mod:`ftrac_design.xray.localization`);
        unchanged for None (a features file)."""
        if spec is None:
            return self
        return replace(
            self, bead_error_factor=float(spec.bead_error_factor), wire_error_factor=float(spec.wire_error_factor)
        )

    @property
    def noise_text(self) -> str:
        """'segmentation error 0.25 mm' and, where not 1, the parts' factors."""
        parts = [f"{k} ×{v:.3g}" for k, v in zip(("beads", "wires"), self.error_factors) if v != 1.0]
        return f"segmentation error {self.segmentation_error_mm:g} mm" + (f" ({', '.join(parts)})" if parts else "")

    @property
    def error_factors(self) -> tuple[float, float]:
        """(bead, wire) multiples of the segmentation error."""
        return self.bead_error_factor, self.wire_error_factor

    def to_dict(self) -> dict:
        """Plain values for analysis.json."""
        ws = self.workspace
        return {
            "cone_deg": ws.cone_deg,
            "depth_mm": ws.depth_mm,
            "depth_range_mm": ws.depth_range_mm,
            "lateral_mm": ws.lateral_mm,
            "roll_deg": list(ws.roll_deg),
            "segmentation_error_mm": self.segmentation_error_mm,
            **(
                {"bead_error_factor": self.bead_error_factor, "wire_error_factor": self.wire_error_factor}
                if self.error_factors != (1.0, 1.0)
                else {}
            ),
            "poses": self.poses,
            "seed": self.seed,
            "camera": self.camera.to_dict(),
            "contour_samples": asdict(self.contour),
        }


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def summarise(m: PoseMetrics) -> dict:
    """Worst / 95th percentile / median of a set of pose metrics (None where infinite)."""
    t, r = m.translation_rms_mm, m.rotation_rms_deg

    def stats(a: np.ndarray) -> dict:
        return {"worst": _finite(np.max(a)), "p95": _finite(np.percentile(a, 95)), "median": _finite(np.median(a))}

    with np.errstate(invalid="ignore"):  # singular sets: infinite errors, percentiles of inf
        return _summary(m, t, r, stats)


def _summary(m: PoseMetrics, t: np.ndarray, r: np.ndarray, stats) -> dict:
    return {
        "translation_mm": stats(t),
        "translation_p95_per_axis_mm": [_finite(v) for v in np.percentile(m.translation_std_mm, 95, axis=0)],
        "rotation_deg": stats(r),
        "rotation_p95_per_axis_deg": [_finite(v) for v in np.degrees(np.percentile(m.rotation_std_rad, 95, axis=0))],
        "condition": {"worst": _finite(np.max(m.condition)), "median": _finite(np.median(m.condition))},
        "sigma_min": {"worst": float(np.min(m.sigma_min)), "median": float(np.median(m.sigma_min))},
        "d_optimality": {"worst": float(np.min(m.d_optimality)), "median": float(np.median(m.d_optimality))},
        "noise_amplification": {
            "worst": float(np.min(m.noise_amplification)),
            "median": float(np.median(m.noise_amplification)),
        },
    }


@dataclass
class DesignScore:
    """A design's score over its workspace, with the analysis it came from."""

    name: str
    settings: AnalysisSettings
    thresholds: Thresholds
    analysis: PoseAnalysis
    figures: dict
    checks: list[dict]
    groups: dict
    per_feature: list[dict]
    worst_poses: list[dict]
    #: image clearances at the first ``settings.segmentability_poses`` workspace poses
    segmentability: Segmentability | None = None

    @property
    def passed(self) -> bool:
        return all(c["passed"] for c in self.checks)

    def to_dict(self) -> dict:
        """The score part of analysis.json."""
        return {
            "figures": self.figures,
            "thresholds": asdict(self.thresholds),
            "checks": self.checks,
            "passed": self.passed,
            "groups": self.groups,
            "features": self.per_feature,
            "worst_poses": self.worst_poses,
            "segmentability": self.segmentability.to_dict() if self.segmentability is not None else None,
        }


def _check(name: str, value: float | None, limit: float, unit: str) -> dict:
    ok = value is not None and value <= limit
    return {"figure": name, "value": value, "limit": limit, "unit": unit, "passed": bool(ok)}


def segmentability_checks(seg: Segmentability, thresholds: Thresholds) -> list[dict]:
    """Checks of the thresholds on image clearance that are set. A lower limit is marked
    ``"at_least": true``; no pair to clear (one feature) passes it."""
    out = []
    if thresholds.max_overlap_share is not None:
        out.append(_check("overlap share", seg.overlap_share, thresholds.max_overlap_share, ""))
    if thresholds.min_clearance_px is not None:
        v = seg.clearance_p5_px
        out.append(
            {
                "figure": "clearance p5",
                "value": v,
                "limit": thresholds.min_clearance_px,
                "unit": "px",
                "at_least": True,
                "passed": bool(v is None or v >= thresholds.min_clearance_px),
            }
        )
    return out


def _per_feature(pa: PoseAnalysis, ref: np.ndarray) -> list[dict]:
    """Each feature's own rank ratio, blind fraction, view angle and the score without it."""
    m = pa.overall
    p95_t = np.percentile(m.translation_rms_mm, 95)
    p95_r = np.percentile(m.rotation_rms_deg, 95)
    out = []
    for f, fid in enumerate(pa.layout.ids):
        wo = pa.without[fid]
        rr = pa.rank_ratio[:, f]
        ang = pa.view_angle_deg[:, f]
        wt, wr = np.percentile(wo.translation_rms_mm, 95), np.percentile(wo.rotation_rms_deg, 95)
        out.append(
            {
                "id": fid,
                "kind": pa.layout.kinds[f],
                "rank_ratio": {"median": float(ref[f]), "worst": float(rr.min())},
                "blind_fraction": float(np.mean(rr < 0.25 * ref[f])),
                "min_view_angle_deg": _finite(np.nanmin(ang)) if np.isfinite(ang).any() else None,
                "without": {
                    "translation_p95_mm": _finite(wt),
                    "rotation_p95_deg": _finite(wr),
                    "translation_loss": _finite(wt / p95_t),
                    "rotation_loss": _finite(wr / p95_r),
                },
            }
        )
    return out


def score_design(
    features: Features,
    settings: AnalysisSettings = AnalysisSettings(),
    thresholds: Thresholds = Thresholds(),
    progress: Callable[[int], None] | None = None,
    n_worst: int = 5,
    segmentability: bool = True,
) -> DesignScore:
    """Score ``features`` over ``settings.poses`` random workspace poses (see module doc);
    ``segmentability`` also measures image clearances at the first
    ``settings.segmentability_poses`` of them (needed for its thresholds)."""
    R, t = workspace_poses(settings.workspace, features.nominal_beam_direction, settings.poses, settings.seed)
    pa = analyse_poses(
        features, R, t, settings.camera, settings.noise, settings.contour, detail=True, progress=progress
    )
    m = pa.overall
    figures = summarise(m)
    checks = [
        _check("worst translation", figures["translation_mm"]["worst"], thresholds.max_translation_mm, "mm"),
        _check("worst rotation", figures["rotation_deg"]["worst"], thresholds.max_rotation_deg, "deg"),
        _check("worst condition", figures["condition"]["worst"], thresholds.max_condition, ""),
    ]
    groups = {g: summarise(gm) for g, gm in pa.groups.items()}
    for g, gm in pa.groups.items():
        groups[g]["singular_fraction"] = float(np.mean(~np.isfinite(gm.condition)))
    ref = np.median(pa.rank_ratio, 0)
    with np.errstate(invalid="ignore"):  # a singular leave-one-out set has infinite errors
        per_feature = _per_feature(pa, ref)
    order = np.argsort(-m.translation_rms_mm)[:n_worst]
    beams = pa.beam_directions()
    polar, az = angle_from(features.nominal_beam_direction, beams[order])
    worst = []
    for k, i in enumerate(order):
        worst.append(
            {
                "beam_direction": [float(v) for v in beams[i]],
                "angle_from_nominal_deg": float(polar[k]),
                "azimuth_deg": float(az[k]),
                "translation_mm": [float(v) for v in t[i]],
                "translation_error_mm": _finite(m.translation_rms_mm[i]),
                "rotation_error_deg": _finite(m.rotation_rms_deg[i]),
                "condition": _finite(m.condition[i]),
                "responsible": pa.responsible(i, ref),
            }
        )
    seg = None
    if segmentability or thresholds.max_overlap_share is not None or thresholds.min_clearance_px is not None:
        k = min(settings.poses, settings.segmentability_poses)
        seg = _segmentability(features, settings.camera, R[:k], t[:k], settings.clearance)
        checks += segmentability_checks(seg, thresholds)
    return DesignScore(features.name, settings, thresholds, pa, figures, checks, groups, per_feature, worst, seg)


#: :func:`figure_cells`' column headings
FIGURE_COLUMNS = ("t p95 mm", "t worst", "depth p95", "r p95 °", "r worst", "cond med", "cond worst")


def figure_cells(figures: dict) -> tuple[str, ...]:
    """A design score's headline figures as table cells (:data:`FIGURE_COLUMNS`): translation p95
    and worst (mm), depth p95 (mm), rotation p95 and worst (°), median and worst condition.

    Parameters
    ----------
    figures : dict
        :attr:`DesignScore.figures`.

    Returns
    -------
    tuple of str
        The cells, ``inf`` where a figure is unbounded.
    """

    def g(v):
        return "inf" if v is None else f"{v:.3f}"

    def whole(v):
        return "inf" if v is None else f"{v:.0f}"

    f = figures
    return (
        g(f["translation_mm"]["p95"]),
        g(f["translation_mm"]["worst"]),
        g(f["translation_p95_per_axis_mm"][2]),
        g(f["rotation_deg"]["p95"]),
        g(f["rotation_deg"]["worst"]),
        whole(f["condition"]["median"]),
        whole(f["condition"]["worst"]),
    )
