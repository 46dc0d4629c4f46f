"""``ftrac-design analyze DESIGN.toml|PRESET|FEATURES.json [-o DIR]``: score a design over the
workspace and map its blind spots (SPEC §5; format in :mod:`ftrac_design.workflows.analyze`)."""

from __future__ import annotations

from pathlib import Path

import click

from .options import (
    AT_LEAST_ONE,
    flag_option,
    image_score_options,
    imaging_options,
    min_clearance_option,
    optional_option,
    output_option,
    shown_option,
    workspace_options,
)
from .options import POSITIVE as _POS


@click.command("analyze")
@click.argument("source", type=click.Path(path_type=Path, dir_okay=False))
@output_option("output directory [default: outputs/<design name>/analysis/]")
@workspace_options()
@optional_option(
    "--max-translation-mm",
    type=_POS,
    help="pass only if the worst predicted translation error is within this [default: design's, else 1.0]",
)
@optional_option(
    "--max-rotation-deg",
    type=_POS,
    help="pass only if the worst predicted rotation error is within this [default: design's, else 0.5]",
)
@optional_option(
    "--max-condition",
    type=click.FloatRange(min=1.0),
    help="pass only if the worst condition number is within this [default: design's, else 1000]",
)
@optional_option(
    "--max-overlap-share",
    type=click.FloatRange(min=0.0, max=1.0),
    help="pass only if features' images overlap at no larger share of workspace poses than this "
    "[default: design's, else not judged]",
)
@min_clearance_option(
    "pass only if the 5th-percentile smallest image clearance between features is at least this, "
    "px beyond their widths [default: design's, else not judged]"
)
@shown_option(
    "--atlas-step-deg",
    type=click.FloatRange(min=0.5, max=15.0),
    default=2.0,
    help="grid step of the whole-sphere atlas",
)
@flag_option(
    "--imaging",
    help="also the pixel-level Cramér–Rao bound of the pose from a rendered radiograph beside the "
    "feature-level one, at a separate sample of --imaging-poses workspace poses (imaging block, "
    "imaging.png)",
)
@shown_option(
    "--imaging-poses",
    type=AT_LEAST_ONE,
    default=60,
    help="workspace poses of the image-level bound (~13 renders of the fiducial each)",
)
@imaging_options("imaging: ")
@image_score_options(atlas=True)
@flag_option("--no-plots", help="write analysis.json only")
@flag_option(
    "--report", help="also write report.html into the output directory (with the build, for a build's features.json)"
)
def command(source: Path, output: Path | None, report: bool, **options) -> int:
    """Score SOURCE (a design file, a preset's name or a features.json) over the C-arm workspace.

    The image-true score: a seeded sample of workspace poses rendered clean and over a patient,
    each image tracked as `track` does — the share refused and wrong, the p95 of the right poses'
    errors with 95 % intervals. Beside it the paper's model: predicted 1σ pose errors (the
    Cramér–Rao bound of the solver's Jacobian with a uniform segmentation error) and the
    condition number at every workspace pose, per feature group and feature, and a
    whole-sphere atlas of blind spots; the image clearance between features (segmentability).
    Writes analysis.json and image_score.png, score.png, atlas_sphere.png, atlas_cone.png,
    segmentability.png (and imaging.png with --imaging); exits 1 if a threshold is exceeded.
    """
    from tqdm import tqdm

    from ..analysis.subject import load_subject
    from ..workflows.analyze import format_summary, run_analysis

    subject = load_subject(source)
    plan = analysis_plan(subject, output, **options)
    with tqdm(
        total=plan.steps(), unit="step", desc=f"analysing {subject.features.name}", leave=False, disable=None
    ) as bar:
        doc, out_dir = run_analysis(subject, plan, bar.update)
    click.echo(format_summary(doc))
    click.echo(f"wrote {out_dir / 'analysis.json'}" + (f" and {', '.join(doc['files'])}" if doc["files"] else ""))
    if report:
        from ..workflows.report import report_for_analysis

        click.echo(f"wrote {report_for_analysis(source, out_dir)}")
    if not doc["passed"]:
        click.echo("failed: " + "; ".join(_failed_check(c) for c in doc["checks"] if not c["passed"]), err=True)
        return 1
    return 0


def _failed_check(c: dict) -> str:
    value = "inf" if c["value"] is None else format(c["value"], ".3g")
    return f"{c['figure']} {value} {c['unit']} {'<' if c.get('at_least') else '>'} {c['limit']:g}"


def analysis_plan(
    subject,
    output: Path | None,
    atlas_step_deg: float = 2.0,
    no_plots: bool = False,
    imaging: bool = False,
    imaging_poses: int = 60,
    dose: float = 1.0e4,
    energy_kev: float = 60.0,
    detector_blur_px: float = 0.7,
    focal_spot_mm: float = 0.6,
    score_images: int = 100,
    score_seed: int = 0,
    image_atlas_step_deg: float = 20.0,
    workers: int | None = None,
    **settings,
):
    """The analysis ``analyze``'s options ask for, resolved once.

    Parameters
    ----------
    subject : ftrac_design.analysis.subject.Subject
        What is analysed.
    output : pathlib.Path or None
        ``--output``.
    atlas_step_deg, no_plots, imaging, imaging_poses, dose, energy_kev, detector_blur_px, focal_spot_mm
        The atlas', the plots' and the pixel-level bound's options.
    score_images, score_seed, image_atlas_step_deg, workers
        The image-true score's options.
    **settings
        The workspace's, the noise's and the thresholds' options, by their settings' field names
        (:func:`ftrac_design.analysis.subject.settings_for`).

    Returns
    -------
    ftrac_design.workflows.analyze.AnalysisPlan
        The plan.
    """
    from ..analysis.subject import settings_for
    from ..workflows.analyze import AnalysisPlan, ImageScoring, PixelBound

    analysis, thresholds = settings_for(subject, **settings)
    pixel = None
    if imaging:
        pixel = PixelBound.from_options(analysis, imaging_poses, dose, energy_kev, detector_blur_px, focal_spot_mm)
    return AnalysisPlan(
        analysis,
        thresholds,
        output,
        atlas_step_deg,
        not no_plots,
        ImageScoring.from_options(score_images, score_seed, image_atlas_step_deg, workers),
        pixel,
    )
