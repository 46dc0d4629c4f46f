"""``optimize``: a whole run — design and space in, output directory out, resumable.

While a run is under way its evaluation log lives in a work directory beside the output,
``DIR.partial/evaluations.jsonl``; ``resume=True`` continues from it. When the run ends the
outputs are written into a temporary directory that is renamed to ``DIR`` (an earlier
optimize output there is replaced whole), the log is copied in, and the work directory
is removed.
"""

from __future__ import annotations

import contextlib
import shutil
from concurrent.futures import Executor
from pathlib import Path

from ..errors import GoalError, InputError
from ..fileio import atomic_directory, check_output_dir, json_format_is
from ..optimize.execution import open_executor
from ..optimize.search import Objective, SearchConfig, require_search_packages, run_search
from ..optimize.setup import prepare
from .optimize_outputs import FORMAT, WinnerChecks, write_outputs

VERIFY_POSES = 20_000
SOLVER_IMAGES = 1000
#: rendered radiographs of start and winner tracked end to end (:mod:`ftrac_design.optimize.imagecheck`)
CHECK_IMAGES = 200


def work_dir(out_dir: Path) -> Path:
    """Where an unfinished run keeps its log."""
    return out_dir.with_name(out_dir.name + ".partial")


def _check_output_dir(out_dir: Path) -> None:
    """Refuse to replace anything but an empty directory or an earlier optimize output."""
    check_output_dir(out_dir, "an earlier optimize output", lambda d: json_format_is(d / "summary.json", FORMAT))


def optimize(
    design_path: str | Path,
    out_dir: str | Path,
    space_path: str | Path | None = None,
    objective: Objective = "max",
    evaluations: int = 400,
    seed: int = 0,
    profiles: tuple[str, ...] = ("cnc",),
    scheduler: str | None = None,
    workers: int | None = None,
    executor: Executor | None = None,
    resume: bool = False,
    poses: int | None = None,
    verify_poses: int | None = None,
    solver_images: int | None = None,
    build: bool = True,
    progress: bool = True,
    command_line: str | None = None,
    stop_after: int | None = None,
    sigma0: float | None = None,
    popsize: int | None = None,
    min_clearance_px: float | None = None,
    min_ellipse_view_deg: float | None = None,
    check_images: int | None = None,
    score_images: int = 0,
) -> dict:
    """Run a search and write its outputs into ``out_dir`` (see :mod:`.optimize_outputs`); returns
    ``summary.json``'s content. ``executor`` (any ``concurrent.futures``-style one) wins
    over ``scheduler`` / ``workers`` (see :mod:`ftrac_design.optimize.execution`). Raises
    :class:`~ftrac_design.errors.GoalError` when no candidate is feasible."""
    out_dir = Path(out_dir)
    _check_output_dir(out_dir)
    space, settings = prepare(
        design_path, space_path, poses, seed, profiles, min_clearance_px, min_ellipse_view_deg, score_images
    )
    config = SearchConfig(
        objective=objective,
        evaluations=evaluations,
        seed=seed,
        sigma0=sigma0 or space.search.get("sigma0", SearchConfig.sigma0),
        popsize=popsize or space.search.get("popsize"),
    )
    require_search_packages(config)
    log = _log_of(out_dir, resume)
    command_line = command_line or (
        f"ftrac-design optimize {design_path} --objective {objective} --evaluations {evaluations} --seed {seed}"
    )
    checks = WinnerChecks(
        verify_poses or space.search.get("verify_poses", VERIFY_POSES),
        SOLVER_IMAGES if solver_images is None else solver_images,
        build,
        profiles[0],
        space.search.get("check_images", CHECK_IMAGES) if check_images is None else check_images,
    )
    try:
        with contextlib.ExitStack() as stack:
            if executor is not None:
                ex, name = executor, type(executor).__name__
            else:
                ex, name = stack.enter_context(open_executor(scheduler, workers))
            res = run_search(space, settings, config, ex, log, resume, progress, name, stop_after=stop_after)
            with atomic_directory(out_dir) as tmp:
                doc = write_outputs(res, tmp, log, command_line, checks, progress, ex)
    except BaseException:
        if not log.exists() or not log.stat().st_size:  # nothing to resume: leave nothing behind
            shutil.rmtree(log.parent, ignore_errors=True)
        raise
    shutil.rmtree(log.parent, ignore_errors=True)
    if doc.get("best") is None:
        raise GoalError(f"no feasible candidate in {len(res.entries)} evaluations; outputs in {out_dir}")
    return doc


def _log_of(out_dir: Path, resume: bool) -> Path:
    """The run's evaluation log in its work directory (made here), after checking that resuming,
    or not, matches what is there."""
    work = work_dir(out_dir)
    log = work / "evaluations.jsonl"
    if resume and not log.exists():
        raise InputError(log, None, "an interrupted run's log (none found)", parameter="resume")
    if not resume and work.exists():
        raise InputError(work, None, "no interrupted run here: resume it, or remove it", parameter="resume")
    work.mkdir(parents=True, exist_ok=True)
    return log
