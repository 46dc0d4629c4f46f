"""``ftrac-design compare A B …``: designs side by side over one workspace."""

from __future__ import annotations

from pathlib import Path

import click

from .options import OUT_FILE, image_score_options, output_option, workspace_options


@click.command("compare")
@click.argument("sources", nargs=-1, required=True, type=click.Path(path_type=Path, dir_okay=False))
@output_option("overlay plot to write [default: outputs/compare.png]; compare.json beside it", type=OUT_FILE)
@workspace_options()
@image_score_options()
def command(
    sources: tuple[Path, ...],
    output: Path | None,
    score_images: int = 100,
    score_seed: int = 0,
    workers: int | None = None,
    **workspace,
) -> int:
    """Score each design (DESIGN.toml, a preset's name or FEATURES.json) over the same workspace and noise.

    First the image-true score: the same rendered images (clean and over a patient) for every
    design, tracked; p95 errors, shares refused and wrong, and each design's paired p95 ratios to
    the first with 95 % intervals. Then the paper's model: a side-by-side table of predicted 1σ
    errors, conditioning and image clearance between features (share of poses where they
    overlap, 5th-percentile clearance), their distributions drawn overlaid. Each design is judged
    by its own thresholds; the workspace is the command line's (or the defaults), the same for all.
    """
    from tqdm import tqdm

    from ..analysis.score import score_design
    from ..analysis.subject import Subject, load_subject, settings_for
    from ..errors import InputError
    from ..fileio import write_json_atomic

    subjects = [load_subject(s) for s in sources]
    # the workspace is the same for every design: the defaults and the command line only
    base, _ = settings_for(Subject(subjects[0].features, None, subjects[0].path), **workspace)
    scores = []
    with tqdm(total=base.poses * len(subjects), unit="pose", desc="scoring", leave=False, disable=None) as bar:
        for sub in subjects:
            _, th = settings_for(sub, **workspace)
            scores.append(score_design(sub.features, base.for_parts(sub.spec), th, progress=bar.update))
    images = _image_scores(subjects, base, score_images, score_seed, workers) if score_images else None
    from ..workflows.compare import compare_document, model_table

    click.echo("\n".join(model_table(scores, base)))
    out = Path(output) if output is not None else Path("outputs") / "compare.png"
    if out.suffix.lower() != ".png":
        raise InputError(out, "--output", "a .png file name")
    from ..analysis.plots import plot_compare
    from ..fileio import atomic_file

    with atomic_file(out) as tmp:
        plot_compare(scores, tmp)
    write_json_atomic(out.with_suffix(".json"), compare_document(scores, base, images))
    click.echo(f"wrote {out} and {out.with_suffix('.json')}")
    return 0


def _image_scores(subjects, base, score_images: int, score_seed: int, workers: int | None) -> list[dict]:
    """Every design's image-true score on one sample, its table printed."""
    from tqdm import tqdm

    from ..imagescore import TrialSettings
    from ..optimize.execution import open_executor
    from ..workflows.compare import image_scores, image_table

    trial = TrialSettings(images=score_images, seed=score_seed, workspace=base.workspace, camera=base.camera)
    total = score_images * len(trial.conditions) * len(subjects)
    with (
        open_executor(None, workers) as (executor, _),
        tqdm(total=total, unit="image", desc="imaging", leave=False, disable=None) as bar,
    ):
        images = image_scores(subjects, trial, executor, bar.update)
    click.echo("\n".join(image_table(images, trial)))
    click.echo("the paper's model (feature-level Cramér–Rao bound):")
    return images
