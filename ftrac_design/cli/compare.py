"""``ftrac-design compare A B …``: designs side by side over one workspace."""

from __future__ import annotations

from pathlib import Path

import click

from .analyze import image_score_options, overrides, workspace_options


@click.command("compare")
@click.argument("sources", nargs=-1, required=True, type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="overlay plot to write [default: outputs/compare.png]; compare.json beside it",
)
@workspace_options
@image_score_options()
def command(
    sources: tuple[Path, ...],
    output: Path | None,
    poses,
    seed,
    cone_deg,
    roll_range_deg,
    depth_mm,
    depth_range_mm,
    lateral_mm,
    segmentation_error_mm,
    score_images: int = 100,
    score_seed: int = 0,
    workers: int | None = None,
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
    common = overrides(
        poses, seed, cone_deg, roll_range_deg, depth_mm, depth_range_mm, lateral_mm, segmentation_error_mm
    )
    # the workspace is the same for every design: the defaults and the command line only
    base, _ = settings_for(Subject(subjects[0].features, None, subjects[0].path), **common)
    scores = []
    with tqdm(total=base.poses * len(subjects), unit="pose", desc="scoring", leave=False, disable=None) as bar:
        for sub in subjects:
            _, th = settings_for(sub, **common)
            scores.append(score_design(sub.features, base.for_parts(sub.spec), th, progress=bar.update))
    images = None
    if score_images:
        from ..imagescore import TrialSettings
        from ..optimize.execution import open_executor
        from ..workflows.compare import image_scores, image_table

        trial = TrialSettings(images=score_images, seed=score_seed, workspace=base.workspace, camera=base.camera)
        with (
            open_executor(None, workers) as (executor, _),
            tqdm(
                total=score_images * len(trial.conditions) * len(subjects),
                unit="image",
                desc="imaging",
                leave=False,
                disable=None,
            ) as bar,
        ):
            images = image_scores(subjects, trial, executor, bar.update)
        click.echo("\n".join(image_table(images, trial)))
        click.echo("the paper's model (feature-level Cramér–Rao bound):")
    rows = [
        (
            "design",
            "t p95 mm",
            "t worst",
            "depth p95",
            "r p95 °",
            "r worst",
            "cond med",
            "cond worst",
            "overlap",
            "clear p5 px",
            "verdict",
        )
    ]
    table = []
    for s in scores:
        f = s.figures

        def g(v):
            return "inf" if v is None else f"{v:.3f}"

        rows.append(
            (
                s.name,
                g(f["translation_mm"]["p95"]),
                g(f["translation_mm"]["worst"]),
                g(f["translation_p95_per_axis_mm"][2]),
                g(f["rotation_deg"]["p95"]),
                g(f["rotation_deg"]["worst"]),
                "inf" if f["condition"]["median"] is None else f"{f['condition']['median']:.0f}",
                "inf" if f["condition"]["worst"] is None else f"{f['condition']['worst']:.0f}",
                f"{100 * s.segmentability.overlap_share:.1f} %",
                g(s.segmentability.clearance_p5_px),
                "PASS" if s.passed else "FAIL",
            )
        )
        d = s.to_dict()
        seg = {k: d["segmentability"][k] for k in ("overlap_share", "clearance_px", "kinds")}
        table.append(
            {"design": s.name, "figures": f, "thresholds": d["thresholds"], "passed": s.passed, "segmentability": seg}
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    ws = base.workspace
    click.echo(
        f"{base.poses} poses within {ws.cone_deg:g}° of each nominal beam, depth {ws.depth_mm:g} ± "
        f"{ws.depth_range_mm:g} mm, {base.noise_text} (predicted 1σ, 3-D RMS)"
        + "".join(
            f"; {s.name}: beads ×{s.settings.bead_error_factor:.3g}, wires ×{s.settings.wire_error_factor:.3g}"
            for s in scores
            if s.settings.error_factors != (1.0, 1.0)
        )
    )
    for r in rows:
        click.echo("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))))
    out = Path(output) if output is not None else Path("outputs") / "compare.png"
    if out.suffix.lower() != ".png":
        raise InputError(out, "--output", "a .png file name")
    from ..analysis.plots import plot_compare
    from ..fileio import atomic_file

    with atomic_file(out) as tmp:
        plot_compare(scores, tmp)
    for row, im in zip(table, images or [None] * len(table)):
        row["image_score"] = im
    write_json_atomic(
        out.with_suffix(".json"),
        {"format": "ftrac-compare", "version": 1, "settings": base.to_dict(), "designs": table},
    )
    click.echo(f"wrote {out} and {out.with_suffix('.json')}")
    return 0
