"""``ftrac-design compare``'s image-true part: every design's trial on the same sample (common random
numbers) and each design's paired p95 ratios against the first, with their intervals."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from typing import Any

from ..analysis.subject import Subject
from ..imagescore import TrialSettings, paired_ratios, run_trial, trial_figures
from .analyze import subject_body


def image_scores(
    subjects: Sequence[Subject],
    trial: TrialSettings,
    executor: Executor | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[dict[str, Any]]:
    """The image-true score of each design on one sample, and its paired ratios to the first.

    Parameters
    ----------
    subjects : sequence of Subject
        The designs, the first being the reference of the ratios.
    trial : TrialSettings
        The sample (the same images — poses, noise, patients — for every design).
    executor : concurrent.futures.Executor or None
        Where the images are rendered and tracked.
    progress : callable or None
        Called with the number of images done.

    Returns
    -------
    list of dict
        Per design: ``design``, ``figures`` (per condition, :func:`ftrac_design.imagescore.trial_figures`)
        and ``vs_first`` (per condition, :func:`ftrac_design.imagescore.paired_ratios`; None for the
        first design).
    """
    records = [run_trial(s.features, subject_body(s), trial, executor, progress) for s in subjects]
    out = []
    for i, (s, rec) in enumerate(zip(subjects, records)):
        out.append(
            {
                "design": s.features.name,
                "figures": trial_figures(rec, trial.seed),
                "vs_first": None
                if i == 0
                else {c: paired_ratios(records[0], rec, c, trial.seed) for c in trial.conditions},
            }
        )
    return out


def _g(v, spec: str = ".3f") -> str:
    return "–" if v is None else format(v, spec)


def image_table(scores: Sequence[dict[str, Any]], trial: TrialSettings) -> list[str]:
    """Lines of text: per condition, each design's p95 errors, shares refused and wrong, and its p95
    ratios to the first design with 95 % intervals."""
    lines = [
        f"image-true score: {trial.images} rendered images per condition, seed {trial.seed}, the same images "
        f"for every design (p95 of the right poses; ratios to {scores[0]['design']} paired, 95 % interval)"
    ]
    for cond in trial.conditions:
        rows = [(cond, "t p95 mm", "r p95 °", "refused %", "wrong %", "t ratio", "r ratio")]
        for s in scores:
            f = s["figures"][cond]
            p = (s["vs_first"] or {}).get(cond)

            def ratio(name, p=p):
                if p is None:
                    return "–"
                lo, hi = p[f"{name}_p95_ratio_95ci"]
                return f"{p[f'{name}_p95_ratio']:.2f} [{lo:.2f}, {hi:.2f}]"

            rows.append(
                (
                    s["design"],
                    _g(f["translation_p95_mm"]),
                    _g(f["rotation_p95_deg"]),
                    _g(f["refused_pct"], ".1f"),
                    _g(f["wrong_pct"], ".1f"),
                    ratio("translation"),
                    ratio("rotation"),
                )
            )
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        lines += [
            "  " + "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
            for r in rows
        ]
    return lines
