"""``optimize``: a whole run — design and space in, output directory out, resumable.

While a run is under way its evaluation log lives in a work directory beside the output,
``DIR.partial/evaluations.jsonl``; ``resume=True`` continues from it. When the run ends the
outputs are written into a temporary directory that is renamed to ``DIR`` (an earlier
optimize output there is replaced whole), the log is copied in, and the work directory
is removed.
"""

from __future__ import annotations

import math
import shutil
import tomllib
from concurrent.futures import Executor
from dataclasses import replace
from pathlib import Path

from ..errors import GoalError, InputError
from ..fileio import atomic_directory, check_output_dir, json_format_is
from .evaluate import EvalSettings
from .execution import open_executor
from .outputs import FORMAT, write_outputs
from .search import SearchConfig, require_search_packages, run_search
from .space import SearchSpace, default_space, load_space

#: workspace poses of the search sample unless the space file or the caller says otherwise
SEARCH_POSES = 2000
VERIFY_POSES = 20_000
SOLVER_IMAGES = 1000
#: rendered radiographs of start and winner tracked end to end (:mod:`.imagecheck`)
CHECK_IMAGES = 200


def read_design(path: str | Path) -> tuple[dict, object]:
    """The design file's TOML data and its validated :class:`~ftrac_design.design.Design`."""
    from ..design import load_design

    design = load_design(path)  # InputError for anything wrong, as everywhere
    return tomllib.loads(Path(design.source).read_text(encoding="utf-8")), design


def work_dir(out_dir: Path) -> Path:
    """Where an unfinished run keeps its log."""
    return out_dir.with_name(out_dir.name + ".partial")


def _check_output_dir(out_dir: Path) -> None:
    """Refuse to replace anything but an empty directory or an earlier optimize output."""
    check_output_dir(out_dir, "an earlier optimize output", lambda d: json_format_is(d / "summary.json", FORMAT))


def prepare(design_path: str | Path, space_path: str | Path | None = None, poses: int | None = None,
            seed: int = 0, profiles: tuple[str, ...] = ("cnc",),
            min_clearance_px: float | None = None,
            min_ellipse_view_deg: float | None = None) -> tuple[SearchSpace, EvalSettings]:
    """The search space and evaluation settings of a run: the design's own [analysis]
    workspace and noise, a sample of ``poses`` (else the space's ``search.poses``, else
    :data:`SEARCH_POSES`) drawn with ``seed``; ellipses seen no closer to edge-on than
    ``min_ellipse_view_deg`` (default: as close as the start design's, rounded down to
    0.1°; 0 switches the constraint off)."""
    from ..analysis.report import Subject, settings_for
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
    return space, EvalSettings(tuple(profiles), analysis, min_clearance_px,
                               min_ellipse_view_deg=min_ellipse_view_deg or None)


def optimize(design_path: str | Path, out_dir: str | Path, space_path: str | Path | None = None,
             objective: str = "max", evaluations: int = 400, seed: int = 0, profiles: tuple[str, ...] = ("cnc",),
             scheduler: str | None = None, workers: int | None = None, executor: Executor | None = None,
             resume: bool = False, poses: int | None = None, verify_poses: int | None = None,
             solver_images: int | None = None, build: bool = True, progress: bool = True,
             command_line: str | None = None, stop_after: int | None = None, sigma0: float | None = None,
             popsize: int | None = None, min_clearance_px: float | None = None,
             min_ellipse_view_deg: float | None = None, check_images: int | None = None) -> dict:
    """Run a search and write its outputs into ``out_dir`` (see :mod:`.report`); returns
    ``summary.json``'s content. ``executor`` (any ``concurrent.futures``-style one) wins
    over ``scheduler`` / ``workers`` (see :mod:`.execution`). Raises
    :class:`~ftrac_design.errors.GoalError` when no candidate is feasible."""
    out_dir = Path(out_dir)
    _check_output_dir(out_dir)
    space, settings = prepare(design_path, space_path, poses, seed, profiles, min_clearance_px,
                              min_ellipse_view_deg)
    config = SearchConfig(objective=objective, evaluations=evaluations, seed=seed,
                          sigma0=sigma0 or space.search.get("sigma0", SearchConfig.sigma0),
                          popsize=popsize or space.search.get("popsize"))
    require_search_packages(config)
    work = work_dir(out_dir)
    log = work / "evaluations.jsonl"
    if resume and not log.exists():
        raise InputError(log, None, "an interrupted run's log (none found)", parameter="resume")
    if not resume and work.exists():
        raise InputError(work, None, "no interrupted run here: resume it, or remove it", parameter="resume")
    work.mkdir(parents=True, exist_ok=True)
    command_line = command_line or (f"ftrac-design optimize {design_path} --objective {objective} "
                                    f"--evaluations {evaluations} --seed {seed}")
    try:
        if executor is not None:
            res = run_search(space, settings, config, executor, log, resume, progress, type(executor).__name__,
                             stop_after=stop_after)
        else:
            with open_executor(scheduler, workers) as (ex, name):
                res = run_search(space, settings, config, ex, log, resume, progress, name, stop_after=stop_after)
    except BaseException:
        if not log.exists() or not log.stat().st_size:  # nothing to resume: leave nothing behind
            shutil.rmtree(work, ignore_errors=True)
        raise
    with atomic_directory(out_dir) as tmp:
        doc = write_outputs(res, tmp, log, command_line,
                            verify_poses or space.search.get("verify_poses", VERIFY_POSES),
                            SOLVER_IMAGES if solver_images is None else solver_images, build, profiles[0],
                            space.search.get("check_images", CHECK_IMAGES) if check_images is None else check_images,
                            progress)
    shutil.rmtree(work, ignore_errors=True)
    if doc.get("best") is None:
        raise GoalError(f"no feasible candidate in {len(res.entries)} evaluations; outputs in {out_dir}")
    return doc
