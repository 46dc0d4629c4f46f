"""``ftrac-design optimize DESIGN.toml|PRESET [-o DIR]``: search a design's layout under the design
rules for the best predicted accuracy (see :mod:`ftrac_design.optimize`)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import click

from .options import (
    AT_LEAST_ONE,
    COUNT,
    design_argument,
    flag_option,
    min_clearance_option,
    optional_option,
    output_option,
    poses_option,
    profiles_option,
    score_images_option,
    shown_option,
    workers_option,
)

OBJECTIVE_CHOICES = ("max", "sum", "translation", "rotation", "translation-rotation", "accuracy-diameter")


@click.command("optimize")
@design_argument(dir_okay=False)
@optional_option(
    "--space",
    "space",
    type=click.Path(path_type=Path, dir_okay=False),
    help="search space (TOML: [parameters], optional [search], or a shipped space's name: "
    "`ftrac-design presets`) [default: the design's layout "
    "within its envelope; see --print-space]",
)
@shown_option(
    "--objective",
    type=click.Choice(OBJECTIVE_CHOICES),
    default="max",
    help="max/sum/translation/rotation: p95 errors over the start's, CMA-ES; "
    "translation-rotation, accuracy-diameter: Pareto front, NSGA-II",
)
@shown_option(
    "--evaluations",
    type=AT_LEAST_ONE,
    default=400,
    help="candidates to evaluate (rounded up to whole generations)",
)
@shown_option("--seed", type=COUNT, default=0, help="seeds the optimiser and the search's pose sample")
@profiles_option("design rules that constrain the search; repeat for both [default: cnc]")
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDR",
    help="Dask scheduler, e.g. tcp://host:8786 [default: $DASK_SCHEDULER_ADDRESS, else local processes]",
)
@workers_option("local worker processes; 0 = in this process [default: one per core]")
@flag_option("--resume", help="continue the interrupted run whose log is in DIR.partial/")
@output_option("output directory [default: outputs/<design name>/optimize/]")
@poses_option("workspace poses of the (fixed) search sample [default: space's, else 2000]")
@optional_option(
    "--verify-poses", type=click.IntRange(min=100), help="fresh poses that re-score start and best [default: 20000]"
)
@optional_option(
    "--solver-images",
    type=COUNT,
    help="simulated images solved for start and best (0 = skip) [default: 1000]",
)
@optional_option(
    "--check-images",
    type=COUNT,
    help="rendered radiographs of start and best tracked with no initial guess, the winner's "
    "check beyond the noise model (0 = skip) [default: 200]",
)
@min_clearance_option(
    "segmentability constraint: 5th percentile of the smallest image clearance between "
    "feature projections over the search poses, px (ftrac_mini: -1.9; 2005: -2.8) [default: none]"
)
@optional_option(
    "--min-ellipse-view-deg",
    type=click.FloatRange(min=0.0, max=90.0),
    help="no ellipse seen closer to edge-on than this anywhere in the search poses; 0 = off "
    "[default: the start design's own on the search sample: 3.9 for ftrac_mini at seed 0, "
    "3.6 at seed 1]",
)
@score_images_option(
    "score candidates on this many rendered, tracked images per condition (clean, over a patient; "
    "the image-true score, the same images for every candidate) instead of the paper's "
    "feature-level model; each candidate then costs ~0.2–0.5 s per image",
    default=0,
)
@flag_option("--no-build", help="do not build the best design (CAD)")
@flag_option("--print-space", help="print the search space (the default one, or --space's) as a file to edit, and exit")
def command(
    design: Path,
    space: Path | None,
    objective: str,
    evaluations: int,
    seed: int,
    profiles: tuple[str, ...],
    scheduler: str | None,
    workers: int | None,
    resume: bool,
    output: Path | None,
    poses: int | None,
    no_build: bool,
    print_space: bool,
    **checks,
) -> int:
    """Optimise the layout of DESIGN (a .toml file or a preset's name) under the design rules.

    Every candidate is checked against the rules of the profile(s) first (graded margins);
    feasible ones are scored by their predicted p95 translation and rotation errors over a
    fixed, seeded sample of workspace poses. The winner is re-scored on fresh poses,
    checked by solving simulated feature observations and by tracking rendered
    radiographs, written as best.toml and built. The same seed
    gives the same result with any number of workers; an interrupted run continues with
    --resume. Writes best.toml, summary.json, comparison.txt, pareto.json/.csv/.png,
    convergence.png, evaluations.jsonl and build/ into the output directory.
    """
    # **checks: --verify-poses, --solver-images, --check-images, --min-clearance-px,
    # --min-ellipse-view-deg and --score-images, named as optimize() takes them
    from ..optimize.setup import prepare, read_design
    from ..optimize.tables import format_summary
    from ..workflows.optimize import optimize

    profiles = profiles or ("cnc",)
    if print_space:
        sp, _ = prepare(design, space, poses, seed, profiles)
        click.echo(sp.to_toml(), nl=False)
        return 0
    _, d = read_design(design)
    out = output if output is not None else Path("outputs") / d.name / "optimize"
    cmd = (
        "ftrac-design optimize " + " ".join(shlex.quote(a) for a in sys.argv[2:])
        if len(sys.argv) > 2 and sys.argv[1] == "optimize"
        else None
    )
    try:
        doc = optimize(
            design,
            out,
            space,
            objective,
            evaluations,
            seed,
            profiles,
            scheduler,
            workers,
            resume=resume,
            poses=poses,
            build=not no_build,
            command_line=cmd,
            **checks,
        )
    except KeyboardInterrupt:
        click.echo(
            f"interrupted: the evaluation log is in {out.with_name(out.name + '.partial')}/; "
            "run the same command with --resume to continue",
            err=True,
        )
        raise click.exceptions.Exit(130) from None
    click.echo(format_summary(doc))
    click.echo(
        f"wrote {out}/ (best.toml, summary.json, comparison.txt, pareto.*, convergence.png"
        f"{', build/' if not no_build else ''})"
    )
    return 0
