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


#: the design file's ``[analysis]`` keys (:class:`~ftrac_design.design.schema.Analysis`) by the
#: setting each one sets: a field of :class:`~ftrac_design.pose.simulate.Workspace`,
#: :class:`~.score.AnalysisSettings` or :class:`~.score.Thresholds`, which the command line's
#: flags are named after (``--depth-mm`` → ``depth_mm``)
FILE_KEYS = {
    "cone_deg": "cone_deg",
    "depth_mm": "depth",
    "depth_range_mm": "depth_range",
    "lateral_mm": "lateral",
    "roll_range_deg": "roll_range_deg",
    "segmentation_error_mm": "segmentation_error",
    "bead_error_factor": "bead_error_factor",
    "wire_error_factor": "wire_error_factor",
    "poses": "poses",
    "max_translation_mm": "max_translation",
    "max_rotation_deg": "max_rotation_deg",
    "max_condition": "max_condition",
    "max_overlap_share": "max_overlap_share",
    "min_clearance_px": "min_clearance_px",
}
_WORKSPACE = ("cone_deg", "depth_mm", "depth_range_mm", "lateral_mm")
_SETTINGS = ("segmentation_error_mm", "bead_error_factor", "wire_error_factor", "poses", "seed")
_THRESHOLDS = ("max_translation_mm", "max_rotation_deg", "max_condition", "max_overlap_share", "min_clearance_px")


def settings_for(subject: Subject, **overrides: Any) -> tuple[AnalysisSettings, Thresholds]:
    """Settings and thresholds: the defaults, then the design's [analysis] table, then the
    caller's ``overrides``.

    Parameters
    ----------
    subject : Subject
        What is analysed (its design's [analysis] table, when it has one).
    **overrides
        Settings by their field's name (``depth_mm=650.0``, ``roll_range_deg=(0, 90)``,
        ``max_translation_mm=0.5``, ``seed=1``); None = not given.

    Returns
    -------
    (AnalysisSettings, Thresholds)
        The settings and the thresholds.
    """
    unknown = set(overrides) - set(FILE_KEYS) - {"seed"}
    if unknown:
        raise TypeError(f"settings_for: no such setting {sorted(unknown)}")
    vals: dict[str, Any] = {}
    if subject.spec is not None:
        spec = subject.spec.model_dump()
        vals.update({field: spec[key] for field, key in FILE_KEYS.items() if key in spec})
    vals.update({k: v for k, v in overrides.items() if v is not None})
    ws = replace(Workspace(), **{k: vals[k] for k in _WORKSPACE if k in vals})
    if "roll_range_deg" in vals:
        ws = replace(ws, roll_deg=tuple(float(v) for v in vals["roll_range_deg"]))
    s = replace(AnalysisSettings(), workspace=ws, **{k: vals[k] for k in _SETTINGS if k in vals})
    th = replace(Thresholds(), **{k: vals[k] for k in _THRESHOLDS if k in vals})
    return s, th
