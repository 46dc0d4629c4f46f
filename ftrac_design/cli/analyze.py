"""``ftrac-design analyze DESIGN.toml|PRESET|FEATURES.json [-o DIR]``: score a design over the
workspace and map its blind spots (SPEC §5; format in :mod:`ftrac_design.workflows.analyze`)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import click

_POS = click.FloatRange(min=0.0, min_open=True)


def workspace_options(fn):
    """Options shared with ``compare``: workspace, noise and sampling."""
    for opt in reversed(
        [
            click.option(
                "--poses",
                type=click.IntRange(min=100),
                default=None,
                help="random workspace poses scored [default: the design's, else 20000]",
            ),
            click.option("--seed", type=int, default=None, help="random seed of the workspace poses [default: 0]"),
            click.option(
                "--cone-deg",
                type=click.FloatRange(min=0.0, max=180.0, min_open=True),
                default=None,
                help="workspace: beams within this angle of the nominal beam; 180 = the whole sphere [default: 25]",
            ),
            click.option(
                "--roll-range-deg",
                type=(float, float),
                default=None,
                metavar="FROM TO",
                help="workspace: roll about the beam drawn from this range [default: 0 360]",
            ),
            click.option(
                "--depth-mm", type=_POS, default=None, help="workspace: source to fiducial origin [default: 667]"
            ),
            click.option(
                "--depth-range-mm",
                type=click.FloatRange(min=0.0),
                default=None,
                help="workspace: ± this about the depth [default: 25]",
            ),
            click.option(
                "--lateral-mm",
                type=click.FloatRange(min=0.0),
                default=None,
                help="workspace: origin within this of the principal ray [default: 25]",
            ),
            click.option(
                "--segmentation-error-mm",
                type=_POS,
                default=None,
                help="the paper's uniform segmentation error magnitude, mm at the detector [default: 0.25]",
            ),
        ]
    ):
        fn = opt(fn)
    return fn


def image_score_options(atlas: bool = False):
    """Options shared by ``analyze``, ``compare`` and ``report``: the image-true score's sample
    (``--score-images``, ``--score-seed``), with ``atlas`` its blind-spot atlas
    (``--image-atlas-step-deg``), and the processes that render and track (``--workers``)."""
    opts = [
        click.option(
            "--score-images",
            type=click.IntRange(min=0),
            default=100,
            show_default=True,
            help="the image-true score: workspace poses rendered and tracked per condition (clean, over a "
            "patient), the same images for every design; 0 = the paper's feature-level model only",
        ),
        click.option(
            "--score-seed", type=int, default=0, show_default=True, help="seed of the image-true score's sample"
        ),
    ]
    if atlas:
        opts.append(
            click.option(
                "--image-atlas-step-deg",
                type=click.FloatRange(min=0.0, max=45.0),
                default=20.0,
                show_default=True,
                help="the image-true blind-spot atlas: grid step over the sphere of view directions, each "
                "direction imaged (clean) and tracked at 2 rolls; 0 = none",
            )
        )
    opts.append(
        click.option(
            "--workers",
            type=click.IntRange(min=0),
            default=None,
            help="processes rendering and tracking the score's images [default: one per core; 0 = this process]",
        )
    )

    def decorate(fn):
        for opt in reversed(opts):
            fn = opt(fn)
        return fn

    return decorate


def overrides(
    poses, seed, cone_deg, roll_range_deg, depth_mm, depth_range_mm, lateral_mm, segmentation_error_mm, **extra
) -> dict:
    """Command-line values under the design file's [analysis] key names."""
    out = {
        "poses": poses,
        "seed": seed,
        "cone_deg": cone_deg,
        "roll_range_deg": roll_range_deg,
        "depth": depth_mm,
        "depth_range": depth_range_mm,
        "lateral": lateral_mm,
        "segmentation_error": segmentation_error_mm,
    }
    out.update(extra)
    return out


@click.command("analyze")
@click.argument("source", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path),
    default=None,
    help="output directory [default: outputs/<design name>/analysis/]",
)
@workspace_options
@click.option(
    "--max-translation-mm",
    type=_POS,
    default=None,
    help="pass only if the worst predicted translation error is within this [default: design's, else 1.0]",
)
@click.option(
    "--max-rotation-deg",
    type=_POS,
    default=None,
    help="pass only if the worst predicted rotation error is within this [default: design's, else 0.5]",
)
@click.option(
    "--max-condition",
    type=click.FloatRange(min=1.0),
    default=None,
    help="pass only if the worst condition number is within this [default: design's, else 1000]",
)
@click.option(
    "--max-overlap-share",
    type=click.FloatRange(min=0.0, max=1.0),
    default=None,
    help="pass only if features' images overlap at no larger share of workspace poses than this "
    "[default: design's, else not judged]",
)
@click.option(
    "--min-clearance-px",
    type=float,
    default=None,
    help="pass only if the 5th-percentile smallest image clearance between features is at least this, "
    "px beyond their widths [default: design's, else not judged]",
)
@click.option(
    "--atlas-step-deg",
    type=click.FloatRange(min=0.5, max=15.0),
    default=2.0,
    show_default=True,
    help="grid step of the whole-sphere atlas",
)
@click.option(
    "--imaging",
    is_flag=True,
    default=False,
    help="also the pixel-level Cramér–Rao bound of the pose from a rendered radiograph beside the "
    "feature-level one, at a separate sample of --imaging-poses workspace poses (imaging block, "
    "imaging.png)",
)
@click.option(
    "--imaging-poses",
    type=click.IntRange(min=1),
    default=60,
    show_default=True,
    help="workspace poses of the image-level bound (~13 renders of the fiducial each)",
)
@click.option(
    "--dose", type=_POS, default=1.0e4, show_default=True, help="imaging: unattenuated quanta per detector pixel"
)
@click.option(
    "--energy-kev",
    type=click.FloatRange(40.0, 100.0),
    default=60.0,
    show_default=True,
    help="imaging: effective beam energy",
)
@click.option(
    "--blur-px",
    type=click.FloatRange(min=0.0),
    default=0.7,
    show_default=True,
    help="imaging: detector line-spread Gaussian σ, pixels",
)
@click.option(
    "--focal-spot-mm",
    type=click.FloatRange(min=0.0),
    default=0.6,
    show_default=True,
    help="imaging: focal spot size (FWHM)",
)
@image_score_options(atlas=True)
@click.option("--no-plots", is_flag=True, default=False, help="write analysis.json only")
@click.option(
    "--report",
    is_flag=True,
    default=False,
    help="also write report.html into the output directory (with the build, for a build's features.json)",
)
def command(
    source: Path,
    output: Path | None,
    poses,
    seed,
    cone_deg,
    roll_range_deg,
    depth_mm,
    depth_range_mm,
    lateral_mm,
    segmentation_error_mm,
    max_translation_mm,
    max_rotation_deg,
    max_condition,
    atlas_step_deg,
    no_plots,
    report=False,
    max_overlap_share=None,
    min_clearance_px=None,
    imaging=False,
    imaging_poses=60,
    dose=1.0e4,
    energy_kev=60.0,
    blur_px=0.7,
    focal_spot_mm=0.6,
    score_images=100,
    score_seed=0,
    workers=None,
    image_atlas_step_deg=20.0,
) -> int:
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

    from ..analysis.subject import load_subject, settings_for
    from ..workflows.analyze import ImageScoring, atlas_directions, format_summary, run_analysis

    subject = load_subject(source)
    settings, thresholds = settings_for(
        subject,
        **overrides(
            poses,
            seed,
            cone_deg,
            roll_range_deg,
            depth_mm,
            depth_range_mm,
            lateral_mm,
            segmentation_error_mm,
            max_translation=max_translation_mm,
            max_rotation_deg=max_rotation_deg,
            max_condition=max_condition,
            max_overlap_share=max_overlap_share,
            min_clearance_px=min_clearance_px,
        ),
    )
    total = settings.poses + atlas_directions(atlas_step_deg, settings.workspace.cone_deg)
    pixel_level, format_imaging = None, None
    if imaging:
        from functools import partial

        from ..intensity.workspace import format_imaging, imaging_analysis
        from ..xray import ImagingModel

        pp = settings.camera.principal_point_px
        model = ImagingModel(
            energy_kev=energy_kev,
            image_shape=(round(2 * pp[1]), round(2 * pp[0])),
            focal_spot_mm=focal_spot_mm,
            detector_blur_px=blur_px,
            photons_per_px=dose,
        )
        bound = partial(
            imaging_analysis,
            subject.features,
            settings.workspace,
            model,
            imaging_poses,
            settings.seed,
            settings.camera,
            settings.segmentation_error_mm,
            settings.contour,
        )

        def pixel_level(progress):
            return bound(progress=progress)

        total += imaging_poses
    scoring = ImageScoring.from_options(score_images, score_seed, image_atlas_step_deg, workers)
    total += scoring.images()
    with contextlib.ExitStack() as stack:
        executor = None
        if scoring.any and workers != 0:
            from ..optimize.execution import open_executor

            executor, _ = stack.enter_context(open_executor(None, workers))
        bar = stack.enter_context(
            tqdm(total=total, unit="step", desc=f"analysing {subject.features.name}", leave=False, disable=None)
        )
        doc, out_dir = run_analysis(
            subject,
            settings,
            thresholds,
            output,
            atlas_step_deg,
            not no_plots,
            bar.update,
            imaging=pixel_level,
            trial=scoring.trial,
            executor=executor,
            image_atlas_settings=scoring.atlas,
        )
    click.echo(format_summary(doc, format_imaging))
    click.echo(f"wrote {out_dir / 'analysis.json'}" + (f" and {', '.join(doc['files'])}" if doc["files"] else ""))
    if report:
        from ..workflows.report import report_for_analysis

        click.echo(f"wrote {report_for_analysis(source, out_dir)}")
    if not doc["passed"]:
        failed = [c for c in doc["checks"] if not c["passed"]]
        click.echo(
            "failed: "
            + "; ".join(
                f"{c['figure']} {'inf' if c['value'] is None else format(c['value'], '.3g')} {c['unit']} "
                f"{'<' if c.get('at_least') else '>'} {c['limit']:g}"
                for c in failed
            ),
            err=True,
        )
        return 1
    return 0
