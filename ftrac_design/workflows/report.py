"""The HTML report of a build or of an analysis run, running the design's analysis first when
the build has none (``ftrac-design report``, ``build --report``, ``analyze --report``); the page
itself is :mod:`ftrac_design.report`'s."""

from __future__ import annotations

from pathlib import Path

from ..report import collect, write_report
from .analyze import ImageScoring


def report_for_build(
    build_dir: str | Path,
    output: str | Path | None = None,
    analysis_dir: str | Path | None = None,
    run_analysis_if_missing: bool = True,
    poses: int | None = None,
    atlas_step_deg: float = 2.0,
    build_kept: bool = True,
    design=None,
    scoring: ImageScoring | None = None,
) -> Path:
    """Write the report of ``build_dir`` (default ``build_dir/report.html``); returns its path.

    The analysis comes from ``analysis_dir``, else ``build_dir/analysis/``; if neither holds
    one and ``run_analysis_if_missing``, it is run at the design's settings (``poses``
    overrides the number of workspace poses; ``scoring`` the image-true score and atlas, default
    :class:`~ftrac_design.workflows.analyze.ImageScoring`'s) into a temporary directory that is not
    kept.
    """
    import tempfile

    build_dir = Path(build_dir)
    output = Path(output) if output is not None else build_dir / "report.html"
    if analysis_dir is None and not (build_dir / "analysis" / "analysis.json").is_file() and run_analysis_if_missing:
        with tempfile.TemporaryDirectory(prefix="ftrac-report-") as tmp:
            _analyse(
                build_dir,
                design,
                Path(tmp) / "analysis",
                poses,
                atlas_step_deg,
                scoring if scoring is not None else ImageScoring(),
            )
            r = collect(build_dir, design, Path(tmp) / "analysis", build_kept)
            return write_report(r, output)
    return write_report(collect(build_dir, design, analysis_dir, build_kept), output)


def report_for_analysis(source: str | Path, analysis_dir: str | Path, output: str | Path | None = None) -> Path:
    """Write ``analysis_dir/report.html`` after ``ftrac-design analyze SOURCE``: with the build
    when SOURCE is a build's ``features.json`` (its ``manifest.json`` beside it), else the
    design's (or the features') own parts only."""
    from ..design.presets import resolve_design

    source, analysis_dir = resolve_design(source), Path(analysis_dir)
    output = Path(output) if output is not None else analysis_dir / "report.html"
    if source.suffix.lower() == ".json" and (source.parent / "manifest.json").is_file():
        return write_report(collect(source.parent, analysis_dir=analysis_dir), output)
    if source.suffix.lower() == ".toml":
        from ..design import load_design

        return write_report(collect(design=load_design(source), analysis_dir=analysis_dir), output)
    from ..features import load_features

    return write_report(collect(features=load_features(source), analysis_dir=analysis_dir), output)


def _analyse(
    build_dir: Path,
    design,
    out_dir: Path,
    poses: int | None,
    atlas_step_deg: float,
    scoring: ImageScoring,
) -> None:
    """Run the analysis of a build at its design's settings, with plots and the image-true score."""
    from ..analysis.subject import Subject, settings_for
    from ..design.loader import parse_design
    from ..features import load_features
    from ..report.inputs import read_manifest
    from .analyze import AnalysisPlan, run_analysis

    if design is None:
        design = parse_design(read_manifest(build_dir)["design"].get("parameters"), build_dir / "manifest.json")
    subject = Subject(load_features(build_dir / "features.json"), design.analysis, build_dir / "features.json", design)
    settings, thresholds = settings_for(subject, poses=poses)
    run_analysis(subject, AnalysisPlan(settings, thresholds, out_dir, atlas_step_deg, True, scoring))
