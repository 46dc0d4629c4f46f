"""One evaluation of a candidate design: design rules first, then the score.

:func:`evaluate_candidate` is a pure, picklable top-level function of the candidate's TOML
data and the :class:`EvalSettings`, so any ``concurrent.futures``-style executor (a local
process pool, a Dask cluster) can run it and the result does not depend on where it ran.

- **Schema**: a candidate the design schema refuses is *refused* (violation
  :data:`REFUSED_VIOLATION`, no rules, no score).
- **Rules** (:func:`ftrac_design.cad.rules.check_design`, every rule of every profile asked
  for) as graded margins: ``(measured − limit) / scale`` for "at least" rules and
  ``(limit − measured) / scale`` for "at most" rules, scale = |limit| (the recommended
  value where the limit is 0, else 1 mm), so a wall 10 % short of its limit is −0.1
  whatever its size. The violation is Σ max(0, −margin) over the failed rules (plus 1e-6
  each, so a rule that fails at margin 0 — "> 0" rules — still counts). n/a rules have no margin.
- **Score** (only when no rule fails): predicted 1σ errors (Cramér–Rao, the analysis's
  engine) over a fixed, seeded workspace sample — common random numbers: every candidate
  is scored on the same poses, which each worker draws once and keeps.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from ..analysis.score import AnalysisSettings
from .space import design_hash

#: violation of a candidate the design schema refuses (larger than any sum of rule margins
#: seen in practice, so every refused candidate ranks below every merely rule-breaking one)
REFUSED_VIOLATION = 1000.0
#: violation of a candidate that is singular somewhere in the workspace (infinite error)
SINGULAR_VIOLATION = 100.0


@dataclass(frozen=True)
class EvalSettings:
    """How every candidate is judged: the rule profiles and the scoring sample."""

    profiles: tuple[str, ...] = ("cnc",)
    analysis: AnalysisSettings = field(default_factory=AnalysisSettings)

    def to_dict(self) -> dict:
        return {"profiles": list(self.profiles), "analysis": self.analysis.to_dict()}


def rule_margins(report) -> tuple[dict[str, float], float]:
    """Normalised margins of a :class:`~ftrac_design.cad.rules.CheckReport` (keys
    ``profile:rule``; positive = inside the limit) and the total violation (0 = feasible)."""
    margins: dict[str, float] = {}
    violation = 0.0
    for r in report.results:
        if r.measured is None:
            continue
        scale = abs(r.limit) or abs(r.recommended or 0.0) or 1.0
        m = (r.measured - r.limit) / scale if r.comparison in (">=", ">") else (r.limit - r.measured) / scale
        margins[f"{report.profile}:{r.rule}"] = float(m)
        if r.verdict == "fail":
            violation += max(0.0, -m) + 1e-6
    return margins, violation


@functools.lru_cache(maxsize=8)
def _sample(settings: AnalysisSettings, nominal_beam: tuple[float, float, float]):
    from ..analysis.sampling import workspace_poses

    return workspace_poses(settings.workspace, np.asarray(nominal_beam), settings.poses, settings.seed)


def score_figures(features, settings: AnalysisSettings) -> dict[str, float] | None:
    """p95 and worst predicted 1σ errors and the worst condition over ``settings``' sample
    (None when the design is singular somewhere in it)."""
    from ..analysis.poses import analyse_poses

    R, t = _sample(settings, tuple(float(v) for v in features.nominal_beam_direction))
    # one chunk: no thread pool inside a worker (the executor already uses the cores)
    m = analyse_poses(features, R, t, settings.camera, settings.noise, settings.contour, detail=False,
                      chunk=max(1, len(R))).overall
    tr, rot = m.translation_rms_mm, m.rotation_rms_deg
    if not (np.all(np.isfinite(tr)) and np.all(np.isfinite(rot)) and np.all(np.isfinite(m.condition))):
        return None
    return {"translation_p95_mm": float(np.percentile(tr, 95)), "rotation_p95_deg": float(np.percentile(rot, 95)),
            "translation_worst_mm": float(tr.max()), "rotation_worst_deg": float(rot.max()),
            "condition_worst": float(m.condition.max())}


def evaluate_candidate(data: dict, settings: EvalSettings) -> dict:
    """Rules, then (if they all pass) the score of the candidate design ``data``.

    Returns plain JSON values: ``design_sha256``, ``refused`` (the schema's one-line
    complaint or None), ``margins`` (``profile:rule`` → normalised margin), ``violation``,
    ``feasible``, ``figures`` (None unless scored: ``translation_p95_mm``,
    ``rotation_p95_deg``, worst values, ``condition_worst``, ``outer_diameter_mm``,
    ``length_mm``) and ``seconds``.
    """
    from ..cad.rules import check_design
    from ..design.loader import parse_design
    from ..errors import InputError
    from ..features import compute_features

    t0 = time.perf_counter()
    out: dict = {"design_sha256": design_hash(data), "refused": None, "margins": {}, "violation": 0.0,
                 "feasible": False, "figures": None}
    try:
        design = parse_design(data, "candidate")
    except InputError as exc:
        out.update(refused=str(exc), violation=REFUSED_VIOLATION, seconds=time.perf_counter() - t0)
        return out
    features = compute_features(design)
    for profile in settings.profiles:
        margins, violation = rule_margins(check_design(design, profile, features))
        out["margins"].update(margins)
        out["violation"] += violation
    if out["violation"] == 0.0:
        figures = score_figures(features, settings.analysis)
        if figures is None:
            out.update(refused="singular somewhere in the workspace", violation=SINGULAR_VIOLATION)
        else:
            figures.update(outer_diameter_mm=float(design.body.outer_diameter), length_mm=float(design.body.length))
            out.update(feasible=True, figures=figures)
    out["seconds"] = time.perf_counter() - t0
    return out
