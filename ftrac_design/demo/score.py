"""``make demo``'s score step: the design over its workspace, as ``ftrac-design analyze`` scores
it (the image-true score on 50 images per condition, its atlas on a 45° grid, the paper's model).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def demo_score(design_path: str | Path, out_dir: str | Path) -> dict[str, Any]:
    """Score the design over its workspace (``ftrac-design analyze``) into ``out_dir``: the
    image-true score on 50 images per condition and its atlas on a 45° grid, and the paper's model;
    returns the analysis.json object."""
    from ..analysis.subject import load_subject, settings_for
    from ..imagescore import TrialSettings
    from ..imagescore.atlas import AtlasSettings
    from ..workflows.analyze import AnalysisPlan, ImageScoring, run_analysis

    subject = load_subject(design_path)
    settings, thresholds = settings_for(subject)
    scoring = ImageScoring(TrialSettings(images=50), AtlasSettings(step_deg=45.0))
    doc, _ = run_analysis(subject, AnalysisPlan(settings, thresholds, Path(out_dir), scoring=scoring))
    return doc


def format_score(doc: dict[str, Any], out_dir: str | Path) -> str:
    """The analysis summary, headed for the demo."""
    from ..workflows.analyze import format_summary

    return (
        f"Scored over the workspace in {doc['time_s']:.1f} s -> {out_dir}/analysis.json, "
        + ", ".join(doc["files"])
        + "\n"
        + format_summary(doc)
    )


def demo_step(design_path: str | Path, out_dir: str | Path) -> str:
    """Score ``design_path`` into ``out_dir`` and return the text the demo prints.

    Parameters
    ----------
    design_path : str or pathlib.Path
        The design file.
    out_dir : str or pathlib.Path
        Where ``analysis.json`` and the pictures go.

    Returns
    -------
    str
        The analysis summary (:func:`format_score`).
    """
    return format_score(demo_score(design_path, out_dir), out_dir)
