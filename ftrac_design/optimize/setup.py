"""A search's starting point: the design file read and validated, the search space, and the
evaluation settings (the design's own workspace and noise, the pose sample)."""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

from .evaluate import EvalSettings
from .space import SearchSpace, default_space, load_space

#: workspace poses of the search sample unless the space file or the caller says otherwise
SEARCH_POSES = 2000


def read_design(path: str | Path) -> tuple[dict, object]:
    """The design file's TOML data and its validated :class:`~ftrac_design.design.Design`."""
    from ..design import load_design

    design = load_design(path)  # InputError for anything wrong, as everywhere
    return tomllib.loads(Path(design.source).read_text(encoding="utf-8")), design


def prepare(
    design_path: str | Path,
    space_path: str | Path | None = None,
    poses: int | None = None,
    seed: int = 0,
    profiles: tuple[str, ...] = ("cnc",),
    min_clearance_px: float | None = None,
    min_ellipse_view_deg: float | None = None,
    score_images: int = 0,
) -> tuple[SearchSpace, EvalSettings]:
    """The search space and evaluation settings of a run: the design's own [analysis]
    workspace and noise, a sample of ``poses`` (else the space's ``search.poses``, else
    :data:`SEARCH_POSES`) drawn with ``seed``; ellipses seen no closer to edge-on than
    ``min_ellipse_view_deg`` (default: as close as the start design's, rounded down to
    0.1°; 0 switches the constraint off); with ``score_images`` > 0 candidates are scored on that
    many rendered, tracked images per condition (the image-true score, seed ``seed``) instead of
    the paper's feature-level model."""
    from ..analysis.subject import Subject, settings_for
    from ..features import compute_features

    base, design = read_design(design_path)
    space = load_space(base, space_path) if space_path is not None else default_space(base)
    n = poses or space.search.get("poses", SEARCH_POSES)
    from .evaluate import min_ellipse_view_deg as view_of

    features = compute_features(design)
    analysis, _ = settings_for(Subject(features, design.analysis, Path(design_path)))
    analysis = replace(analysis, poses=int(n), seed=int(seed))
    if min_ellipse_view_deg is None:
        v = view_of(features, analysis)
        min_ellipse_view_deg = None if v is None else math.floor(v * 10) / 10
    trial = None
    if score_images:
        from ..imagescore import TrialSettings

        trial = TrialSettings(
            images=int(score_images), seed=int(seed), workspace=analysis.workspace, camera=analysis.camera
        )
    return space, EvalSettings(
        tuple(profiles),
        analysis,
        min_clearance_px,
        min_ellipse_view_deg=min_ellipse_view_deg or None,
        image_trial=trial,
    )
