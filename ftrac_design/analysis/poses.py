"""Metrics of a design at a batch of poses: the whole design, each feature group, each
single feature (its own rank, its view angle, and the design without it).

This is the engine under the design score and the blind-spot atlas; it works chunk by
chunk so that memory stays small, and reports progress per chunk.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera
from ..pose.problem import NoiseModel
from ..pose.simulate import ContourSampling
from ..pose.solver import parameter_scale
from .information import (
    FEATURE_RANK,
    SOLVER_ROWS,
    FeatureLayout,
    feature_information,
    feature_layout,
    total_information,
)
from .metrics import PoseMetrics, pose_metrics, rank_ratio

#: poses per chunk: small enough to stay in cache-friendly sizes and to share out over cores
CHUNK = 512

GROUP_NAMES = {"point": "points", "line": "lines", "ellipse": "ellipses"}


@dataclass
class PoseAnalysis:
    """Everything computed at B poses (arrays of length B unless stated)."""

    features: Features
    layout: FeatureLayout
    R: np.ndarray
    t: np.ndarray
    overall: PoseMetrics
    #: "points" / "lines" / "ellipses" → metrics of that kind of feature alone
    groups: dict[str, PoseMetrics] = field(default_factory=dict)
    #: (B, F) σ_rank/σ₁ of each feature's own information (0 = that feature is blind)
    rank_ratio: np.ndarray | None = None
    #: (B, F) angle (deg) between the ray to each curve and the curve: an ellipse's plane
    #: (0 = edge-on) or a line (0 = end-on); NaN for beads
    view_angle_deg: np.ndarray | None = None
    #: feature id → metrics of the design without that feature
    without: dict[str, PoseMetrics] = field(default_factory=dict)

    def beam_directions(self) -> np.ndarray:
        """Beam directions (camera ``+z``) in F, (B, 3)."""
        return self.R[:, 2, :]

    def responsible(self, i: int, reference: np.ndarray | None = None, factor: float = 0.25) -> list[dict]:
        """The features that are (nearly) blind at pose ``i``: those whose rank ratio is below
        ``factor`` × their ``reference`` ratio (default: their median over these poses),
        worst first, each with its ratio relative to the reference and its view angle."""
        if self.rank_ratio is None:
            return []
        ref = np.median(self.rank_ratio, 0) if reference is None else reference
        rel = self.rank_ratio[i] / np.where(ref > 0, ref, 1.0)
        out = []
        for f in np.argsort(rel):
            if rel[f] >= factor:
                break
            kind = self.layout.kinds[f]
            ang = self.view_angle_deg[i, f] if self.view_angle_deg is not None else np.nan
            out.append(
                {
                    "id": self.layout.ids[f],
                    "kind": kind,
                    "relative_rank_ratio": float(rel[f]),
                    "view_angle_deg": None if not np.isfinite(ang) else float(ang),
                    "reason": _reason(kind, ang),
                }
            )
        return out

    def attainable_rank(self) -> int:
        """How many pose directions the features can pin down at best: Σ of their ranks, ≤ 6."""
        return min(6, sum(FEATURE_RANK[k] for k in self.layout.kinds))

    def rank_deficiency(self) -> np.ndarray:
        """(B,) σ_r/σ₁ of the whole design's scaled Jacobian, r = :meth:`attainable_rank`:
        1/condition for a design that determines the pose; for one that cannot (a single
        ellipse: r = 5) it still says where the design loses what it can see."""
        r = self.attainable_rank()
        s = self.overall.sigma
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(s[:, 0] > 0, s[:, r - 1] / s[:, 0], 0.0)


def _reason(kind: str, angle_deg: float) -> str:
    """Why a feature is blind, from its view angle (see :attr:`PoseAnalysis.view_angle_deg`)."""
    if kind == "ellipse":
        if angle_deg < 10:
            return "seen edge-on"  # projects to a segment: its shape says nothing of its tilt
        if angle_deg > 80:
            return "seen face-on"  # a tilt changes the image only to second order
    if kind == "line" and angle_deg < 10:
        return "seen end-on"  # projects to a point
    return "weakly seen"


def _workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def group_indices(layout: FeatureLayout) -> dict[str, list[int]]:
    """Feature indices of each non-empty kind, named as :data:`GROUP_NAMES`."""
    out: dict[str, list[int]] = {}
    for i, k in enumerate(layout.kinds):
        out.setdefault(GROUP_NAMES[k], []).append(i)
    return out


def _view_angles(features: Features, layout: FeatureLayout, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(B, F) degrees; see :attr:`PoseAnalysis.view_angle_deg`."""
    lines = {ln.id: ln for ln in features.lines}
    els = {e.id: e for e in features.ellipses}
    out = np.full((R.shape[0], len(layout.ids)), np.nan)
    for f, (fid, kind) in enumerate(zip(layout.ids, layout.kinds)):
        if kind == "point":
            continue
        geo = lines[fid] if kind == "line" else els[fid]
        c = (geo.start + geo.end) / 2 if kind == "line" else geo.center
        # the ray from the source to the feature, in F: Rᵀ (R c + t)
        ray = c + np.einsum("bji,bj->bi", R, t)
        ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
        if kind == "line":
            out[:, f] = np.degrees(np.arccos(np.clip(np.abs(ray @ geo.direction), 0.0, 1.0)))
        else:
            out[:, f] = np.degrees(np.arcsin(np.clip(np.abs(ray @ geo.normal), 0.0, 1.0)))
    return out


def analyse_poses(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera = Camera(),
    noise: NoiseModel = NoiseModel(),
    contour: ContourSampling = ContourSampling(),
    detail: bool = True,
    leave_one_out: bool = True,
    chunk: int = CHUNK,
    progress: Callable[[int], None] | None = None,
) -> PoseAnalysis:
    """Metrics of ``features`` at poses R (B, 3, 3), t (B, 3) mm (F → X).

    ``detail=False`` computes the whole design's metrics only (the fast path the speed
    benchmark times); otherwise also each feature group, each feature's rank ratio and
    view angle, and (``leave_one_out``) the design without each feature. ``progress(k)``
    is called with the number of poses finished in each chunk.
    """
    layout = feature_layout(features, contour)
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    h = parameter_scale(features)
    m_all = layout.solver_rows
    groups = group_indices(layout) if detail else {}
    loo = layout.ids if detail and leave_one_out else ()

    def one(a: int) -> tuple[dict[str, PoseMetrics], np.ndarray | None]:
        b = min(R.shape[0], a + chunk)
        if not detail:
            return {"": pose_metrics(total_information(layout, camera, R[a:b], t[a:b], noise, chunk), h, m_all)}, None
        info = feature_information(layout, camera, R[a:b], t[a:b], noise, chunk=chunk)
        total = info.sum(1)
        res = {"": pose_metrics(total, h, m_all)}
        for g, idx in groups.items():
            res[g] = pose_metrics(info[:, idx].sum(1), h, sum(SOLVER_ROWS[layout.kinds[i]] for i in idx))
        for f, fid in enumerate(loo):
            res[f"-{fid}"] = pose_metrics(total - info[:, f], h, m_all - SOLVER_ROWS[layout.kinds[f]])
        ratios = np.stack([rank_ratio(info[:, f], h, FEATURE_RANK[k]) for f, k in enumerate(layout.kinds)], -1)
        return res, ratios

    parts: dict[str, list[PoseMetrics]] = {}
    ratios = []
    starts = range(0, R.shape[0], chunk)
    if len(starts) == 1:  # one chunk: a thread pool would only add its start-up cost
        results = map(one, starts)
        pool = None
    else:  # numpy's array loops release the GIL: chunks on threads use every core
        pool = ThreadPoolExecutor(max_workers=_workers())
        results = pool.map(one, starts)
    try:
        for a, (res, rr) in zip(starts, results):
            for k, v in res.items():
                parts.setdefault(k, []).append(v)
            if rr is not None:
                ratios.append(rr)
            if progress is not None:
                progress(min(R.shape[0], a + chunk) - a)
    finally:
        if pool is not None:
            pool.shutdown()

    def cat(ms: list[PoseMetrics]) -> PoseMetrics:
        return PoseMetrics(*(np.concatenate([getattr(x, f) for x in ms]) for f in PoseMetrics.__dataclass_fields__))

    out = PoseAnalysis(features, layout, R, t, cat(parts[""]))
    if detail:
        out.groups = {g: cat(parts[g]) for g in groups}
        out.without = {fid: cat(parts[f"-{fid}"]) for fid in loo}
        out.rank_ratio = np.concatenate(ratios)
        out.view_angle_deg = _view_angles(features, layout, R, t)
    return out
