"""What ``analyze``, ``compare``, the report and the optimiser score: a fiducial's features with its
design's own ``[analysis]`` table, and the analysis settings that table and the caller's overrides
give."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..features.model import Features
from ..pose.simulate import Workspace
from .score import AnalysisSettings, Thresholds


@dataclass
class Subject:
    """What is analysed: the features, and the design's own [analysis] table if it came
    from a design file (None for features.json), and the design itself (None for features.json:
    its body is then found through the features' ``source`` where that file exists)."""

    features: Features
    spec: Any | None
    path: Path
    design: Any | None = None


def load_subject(path: str | Path) -> Subject:
    """What ``path`` names, ready to analyse.

    Parameters
    ----------
    path : str or pathlib.Path
        ``DESIGN.toml`` (features computed, with its [analysis] table), a preset's name
        (``"ftrac_mini"``) or ``FEATURES.json``.

    Returns
    -------
    Subject
        The features, the design's [analysis] table (None for features.json) and the file.
    """
    from ..design.presets import known_presets, resolve_design

    path = resolve_design(path)
    if path.suffix.lower() == ".toml":
        from ..design import load_design
        from ..features import compute_features

        design = load_design(path)
        return Subject(compute_features(design), design.analysis, path, design)
    if path.suffix.lower() == ".json":
        from ..features import load_features

        return Subject(load_features(path), None, path)
    raise InputError(path, None, f"a design file (.toml), a features file (.json) or a preset ({known_presets()})")


def settings_for(subject: Subject, **overrides: Any) -> tuple[AnalysisSettings, Thresholds]:
    """Settings and thresholds: the defaults, then the design's [analysis] table, then the
    command line's ``overrides`` (None = not given). Keys as :class:`~ftrac_design.design.schema.Analysis`."""
    vals: dict[str, Any] = {}
    if subject.spec is not None:
        vals.update(subject.spec.model_dump())
    vals.update({k: v for k, v in overrides.items() if v is not None})
    s, th = AnalysisSettings(), Thresholds()
    ws = replace(
        Workspace(),
        **{
            k: vals[k2]
            for k, k2 in (
                ("cone_deg", "cone_deg"),
                ("depth_mm", "depth"),
                ("depth_range_mm", "depth_range"),
                ("lateral_mm", "lateral"),
            )
            if k2 in vals
        },
    )
    if "roll_range_deg" in vals:
        ws = replace(ws, roll_deg=tuple(float(v) for v in vals["roll_range_deg"]))
    s = replace(
        s,
        workspace=ws,
        **{
            k: vals[k2]
            for k, k2 in (
                ("segmentation_error_mm", "segmentation_error"),
                ("bead_error_factor", "bead_error_factor"),
                ("wire_error_factor", "wire_error_factor"),
                ("poses", "poses"),
                ("seed", "seed"),
            )
            if k2 in vals
        },
    )
    th = replace(
        th,
        **{
            k: vals[k2]
            for k, k2 in (
                ("max_translation_mm", "max_translation"),
                ("max_rotation_deg", "max_rotation_deg"),
                ("max_condition", "max_condition"),
                ("max_overlap_share", "max_overlap_share"),
                ("min_clearance_px", "min_clearance_px"),
            )
            if k2 in vals
        },
    )
    return s, th
