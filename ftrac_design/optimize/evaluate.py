"""One evaluation of a candidate design: design rules first, then the score.

:func:`evaluate_candidate` is a pure, picklable top-level function of the candidate's TOML
data and the :class:`EvalSettings`, so any ``concurrent.futures``-style executor (a local
process pool, a Dask cluster) can run it and the result does not depend on where it ran.

- **Schema**: a candidate the design schema refuses is *refused* (violation
  :data:`REFUSED_VIOLATION`, no rules, no score).
- **Rules** (:func:`ftrac_design.manufacture.rules.check_design`, every rule of every profile asked
  for) as graded margins: ``(measured − limit) / scale`` for "at least" rules and
  ``(limit − measured) / scale`` for "at most" rules, scale = |limit| (the recommended
  value where the limit is 0, else 1 mm), so a wall 10 % short of its limit is −0.1
  whatever its size. The violation is Σ max(0, −margin) over the failed rules (plus 1e-6
  each, so a rule that fails at margin 0 — "> 0" rules — still counts). n/a rules have no margin.
- **Ellipse view angle** (``min_ellipse_view_deg``; the run's default is the start design's
  own value): over the search sample, no ellipse may be seen closer to edge-on than this
  (the angle between the ray to its centre and its plane). The Cramér–Rao score still
  credits an ellipse seen within a few degrees of edge-on, but there its conic fit turns
  nonlinear and the solver stops attaining the bound (measured on ``ftrac_mini`` with E1
  tilted 16.7° instead of 30°: solver RMS 13 % above the bound, 3 failures in 600 images,
  against 4 % and none for the preset); margin ``ellipses:view_angle``, normalised by
  max(limit, 1°).
- **Segmentability** (optional, ``min_clearance_px``; evaluated even when a rule fails, so
  its violation adds to theirs): the 5th percentile over the first
  ``clearance_poses`` poses of the sample of each pose's smallest image-plane clearance
  between feature projections (:func:`ftrac_design.analysis.segmentability.image_clearance`,
  px beyond the projected widths) must be at least ``min_clearance_px``; a graded margin
  ``segmentability:clearance_p5`` like the rules', normalised by max(|limit|, 1 px).
- **Score** (only when no rule fails): predicted 1σ errors (Cramér–Rao, the analysis's
  engine) over a fixed, seeded workspace sample — common random numbers: every candidate
  is scored on the same poses, which each worker draws once and keeps — with the
  candidate's own bead and wire error factors (``[analysis]``; set by the search space when
  it changes stock sizes, :func:`ftrac_design.optimize.space.apply_values`).
- **Image-true score** (``image_trial`` set): instead, the candidate is rendered at the trial's
  fixed sample of workspace poses, clean and over a patient, and every image tracked
  (:mod:`ftrac_design.imagescore`; common random numbers again: every candidate sees the same
  poses, noise and patients). Its figures are the geometric means over the conditions of each
  condition's p95 errors of the right poses, and the shares of images refused and wrong
  (:func:`image_figures`); a candidate
  with more wrong poses than the start breaks the objective's constraint
  (:func:`ftrac_design.optimize.search.objective_violation`).
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from ..analysis.score import AnalysisSettings
from ..imagescore import TrialSettings
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
    #: required 5th-percentile image clearance, px (None: no segmentability constraint)
    min_clearance_px: float | None = None
    clearance_poses: int = 500
    #: smallest angle (deg) any ellipse may be seen at from edge-on (None: no constraint)
    min_ellipse_view_deg: float | None = None
    #: score candidates on rendered, tracked images (None: the paper's feature-level model)
    image_trial: TrialSettings | None = None

    def to_dict(self) -> dict:
        d = {"profiles": list(self.profiles), "analysis": self.analysis.to_dict()}
        if self.image_trial is not None:
            d.update(
                image_trial={
                    "images": self.image_trial.images,
                    "seed": self.image_trial.seed,
                    "conditions": list(self.image_trial.conditions),
                }
            )
        if self.min_clearance_px is not None:
            d.update(min_clearance_px=self.min_clearance_px, clearance_poses=self.clearance_poses)
        if self.min_ellipse_view_deg is not None:
            d.update(min_ellipse_view_deg=self.min_ellipse_view_deg)
        return d


def min_ellipse_view_deg(features, settings: AnalysisSettings) -> float | None:
    """Smallest angle (deg) between the ray to an ellipse's centre and the ellipse's plane over
    ``settings``' sample (0 = seen edge-on somewhere); None for a design without ellipses."""
    if not features.ellipses:
        return None
    R, t = _sample(settings, tuple(float(v) for v in features.nominal_beam_direction))
    src = -np.einsum("bji,bj->bi", R, t)  # the source in F: −Rᵀt
    worst = 90.0
    for e in features.ellipses:
        ray = e.center - src
        ray /= np.linalg.norm(ray, axis=1, keepdims=True)
        worst = min(worst, float(np.degrees(np.arcsin(np.clip(np.abs(ray @ e.normal), 0.0, 1.0))).min()))
    return worst


def rule_margins(report) -> tuple[dict[str, float], float]:
    """Normalised margins of a :class:`~ftrac_design.manufacture.rules.CheckReport` (keys
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


def _sample(settings: AnalysisSettings, nominal_beam: tuple[float, float, float]):
    return _poses(settings.workspace, settings.poses, settings.seed, nominal_beam)


@functools.lru_cache(maxsize=8)
def _poses(workspace, poses: int, seed: int, nominal_beam: tuple[float, float, float]):
    # keyed by the sample alone: candidates with other stock sizes (error factors) share it
    from ..analysis.sampling import workspace_poses

    return workspace_poses(workspace, np.asarray(nominal_beam), poses, seed)


def score_figures(features, settings: AnalysisSettings) -> dict[str, float] | None:
    """p95 and worst predicted 1σ errors and the worst condition over ``settings``' sample
    (None when the design is singular somewhere in it)."""
    from ..analysis.poses import analyse_poses

    R, t = _sample(settings, tuple(float(v) for v in features.nominal_beam_direction))
    # one chunk: no thread pool inside a worker (the executor already uses the cores)
    m = analyse_poses(
        features, R, t, settings.camera, settings.noise, settings.contour, detail=False, chunk=max(1, len(R))
    ).overall
    tr, rot = m.translation_rms_mm, m.rotation_rms_deg
    if not (np.all(np.isfinite(tr)) and np.all(np.isfinite(rot)) and np.all(np.isfinite(m.condition))):
        return None
    return {
        "translation_p95_mm": float(np.percentile(tr, 95)),
        "rotation_p95_deg": float(np.percentile(rot, 95)),
        "translation_worst_mm": float(tr.max()),
        "rotation_worst_deg": float(rot.max()),
        "condition_worst": float(m.condition.max()),
    }


def image_figures(features, trial: TrialSettings) -> dict[str, float] | None:
    """The image-true figures of a candidate: per condition of ``trial``, the p95 translation (mm)
    and rotation (deg) errors of the right poses; their geometric means over the conditions (what
    the objective compares, each condition's relative change weighted alike); the percentages of
    every image refused and wrong. None when a condition has fewer than
    :data:`ftrac_design.imagescore.figures.MIN_RIGHT` right images.

    The p95 of the conditions' right images pooled is not used: for a design that refuses half its
    images over a patient it sits near that condition's 85th percentile, not at either condition's
    p95 (measured on an ``ftrac_mini`` search winner: pooled ratio 0.80, per condition 1.02 and 1.01).

    Parameters
    ----------
    features : Features
        The candidate fiducial, its body (``features.body``) included.
    trial : TrialSettings
        The sample (the same for every candidate).

    Returns
    -------
    dict or None
        ``translation_p95_mm``, ``rotation_p95_deg`` (geometric means over the conditions),
        ``refused_pct``, ``wrong_pct`` and ``<condition>_translation_p95_mm`` /
        ``<condition>_rotation_p95_deg``.
    """
    from ..imagescore import run_trial, trial_figures

    records = run_trial(features, trial)
    per = trial_figures(records)
    if any(f["translation_p95_mm"] is None for f in per.values()):
        return None
    n = len(records)
    out = {
        "translation_p95_mm": float(np.exp(np.mean([np.log(f["translation_p95_mm"]) for f in per.values()]))),
        "rotation_p95_deg": float(np.exp(np.mean([np.log(f["rotation_p95_deg"]) for f in per.values()]))),
        "refused_pct": 100.0 * sum(r["outcome"] == "refused" for r in records) / n,
        "wrong_pct": 100.0 * sum(r["outcome"] == "wrong" for r in records) / n,
    }
    for cond, f in per.items():
        out[f"{cond}_translation_p95_mm"] = f["translation_p95_mm"]
        out[f"{cond}_rotation_p95_deg"] = f["rotation_p95_deg"]
    return out


def candidate_figures(design, features, settings: EvalSettings) -> dict[str, float] | None:
    """The figures a candidate is judged by: the image-true score's (:func:`image_figures`) when
    ``settings.image_trial`` is set, else the paper's model with the candidate's own parts' error
    factors (:func:`score_figures`; stock sizes other than the start's carry theirs). None when the
    candidate cannot be scored (too few right images; singular somewhere in the workspace)."""
    if settings.image_trial is not None:
        return image_figures(features, settings.image_trial)
    return score_figures(features, settings.analysis.for_parts(design.analysis))


def evaluate_candidate(data: dict, settings: EvalSettings) -> dict:
    """Rules, then (if they all pass) the score of the candidate design ``data``.

    Returns plain JSON values: ``design_sha256``, ``refused`` (the schema's one-line
    complaint or None), ``margins`` (``profile:rule`` → normalised margin), ``violation``,
    ``feasible``, ``figures`` (None unless scored: ``translation_p95_mm``,
    ``rotation_p95_deg``, worst values, ``condition_worst``, ``outer_diameter_mm``,
    ``length_mm``) and ``seconds``.
    """
    from ..design.loader import parse_design
    from ..errors import InputError
    from ..features import compute_features
    from ..manufacture.rules import check_design

    t0 = time.perf_counter()
    out: dict = {
        "design_sha256": design_hash(data),
        "refused": None,
        "margins": {},
        "violation": 0.0,
        "feasible": False,
        "figures": None,
    }
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
    if settings.min_ellipse_view_deg is not None:
        view = min_ellipse_view_deg(features, settings.analysis)
        if view is not None:
            lim = settings.min_ellipse_view_deg
            m = (view - lim) / max(lim, 1.0)
            out["ellipse_view_deg"] = view
            out["margins"]["ellipses:view_angle"] = m
            if view < lim - 1e-9:
                out["violation"] += -m + 1e-6
    # computed whether or not a rule failed: were it only computed for candidates that pass
    # the rules, a candidate just outside a rule would rank above every one inside the rules
    # that misses the clearance, and the search would stay outside (it found no feasible
    # candidate in 4,800 evaluations that way)
    if settings.min_clearance_px is not None:
        from ..analysis.segmentability import image_clearance

        R, t = _sample(settings.analysis, tuple(float(v) for v in features.nominal_beam_direction))
        n = min(len(R), settings.clearance_poses)
        p5 = float(np.percentile(image_clearance(features, settings.analysis.camera, R[:n], t[:n])[0], 5))
        lim = settings.min_clearance_px
        m = (p5 - lim) / max(abs(lim), 1.0)
        out["clearance_p5_px"] = p5
        out["margins"]["segmentability:clearance_p5"] = m
        if p5 < lim:
            out["violation"] += -m + 1e-6
    if out["violation"] == 0.0:
        figures = candidate_figures(design, features, settings)
        if figures is None:
            reason = (
                "tracked right in fewer than 20 images of a condition"
                if settings.image_trial is not None
                else "singular somewhere in the workspace"
            )
            out.update(refused=reason, violation=SINGULAR_VIOLATION)
        else:
            figures.update(outer_diameter_mm=float(design.body.outer_diameter), length_mm=float(design.body.length))
            out.update(feasible=True, figures=figures)
    out["seconds"] = time.perf_counter() - t0
    return out
