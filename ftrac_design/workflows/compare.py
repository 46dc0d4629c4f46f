"""``ftrac-design compare``: every design's image-true trial on the same sample (common random
numbers) and each design's paired p95 ratios against the first, with their intervals; the
paper's model's figures side by side; ``compare.json``."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from typing import Any

from ..analysis.score import FIGURE_COLUMNS, figure_cells
from ..analysis.subject import Subject
from ..imagescore import TrialSettings, paired_ratios, run_trial, trial_figures


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
    records = [run_trial(s.features, trial, executor, progress) for s in subjects]
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


#: the paper's model's table: column headings
MODEL_COLUMNS = ("design", *FIGURE_COLUMNS, "overlap", "clear p5 px", "verdict")


def _model_row(s) -> tuple[str, ...]:
    seg = s.segmentability
    clear = "inf" if seg.clearance_p5_px is None else f"{seg.clearance_p5_px:.3f}"
    return (
        s.name,
        *figure_cells(s.figures),
        f"{100 * seg.overlap_share:.1f} %",
        clear,
        "PASS" if s.passed else "FAIL",
    )


def model_table(scores: Sequence[Any], base) -> list[str]:
    """The paper's model's figures of each design, one line each under a line on the workspace.

    Parameters
    ----------
    scores : sequence of DesignScore
        Each design's score (:func:`ftrac_design.analysis.score.score_design`).
    base : AnalysisSettings
        The workspace and noise they share.

    Returns
    -------
    list of str
        The lines.
    """
    rows = [MODEL_COLUMNS, *(_model_row(s) for s in scores)]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    ws = base.workspace
    head = (
        f"{base.poses} poses within {ws.cone_deg:g}° of each nominal beam, depth {ws.depth_mm:g} ± "
        f"{ws.depth_range_mm:g} mm, {base.noise_text} (predicted 1σ, 3-D RMS)"
        + "".join(
            f"; {s.name}: beads ×{s.settings.bead_error_factor:.3g}, wires ×{s.settings.wire_error_factor:.3g}"
            for s in scores
            if s.settings.error_factors != (1.0, 1.0)
        )
    )
    body = ["  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))) for r in rows]
    return [head, *body]


def compare_document(scores: Sequence[Any], base, images: Sequence[dict[str, Any]] | None = None) -> dict[str, Any]:
    """``compare.json``: the shared settings and, per design, its figures, thresholds, verdict,
    segmentability and image-true score (None without one).

    Parameters
    ----------
    scores : sequence of DesignScore
        Each design's score.
    base : AnalysisSettings
        The workspace and noise they share.
    images : sequence of dict or None
        :func:`image_scores`' result, in the same order.

    Returns
    -------
    dict
        The document (format ``ftrac-compare``, version 1).
    """
    table = []
    for s, im in zip(scores, images or [None] * len(scores)):
        d = s.to_dict()
        seg = {k: d["segmentability"][k] for k in ("overlap_share", "clearance_px", "kinds")}
        table.append(
            {
                "design": s.name,
                "figures": s.figures,
                "thresholds": d["thresholds"],
                "passed": s.passed,
                "segmentability": seg,
                "image_score": im,
            }
        )
    return {"format": "ftrac-compare", "version": 1, "settings": base.to_dict(), "designs": table}
