"""What ``optimize`` writes: the winner checked on fresh poses and by the solver, the best
design as TOML, the Pareto front, the convergence plot and start vs best side by side.

Output directory (written atomically: a temporary sibling renamed into place):

- ``best.toml`` — the winner as a design file ``build`` accepts (header: how it was found)
- ``summary.json`` — format ``ftrac-optimize`` v1: run, space, start and best (parameters,
  figures on the search sample and on fresh poses, Monte-Carlo solver errors, rules), front
- ``comparison.txt`` — start vs best: score (as ``compare`` prints it), rules (as ``check``),
  atlas, and the check on rendered images (for a search on the image-true score: a fresh trial,
  clean and over a patient, with paired p95 ratios)
- ``pareto.json`` / ``pareto.csv`` / ``pareto.png`` — the non-dominated feasible candidates
- ``convergence.png`` — best objective so far and feasible share per generation
- ``evaluations.jsonl`` — the evaluation log
- ``build/`` — ``ftrac-design build`` of ``best.toml`` (unless ``--no-build``)
"""

from __future__ import annotations

import json
import shutil
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..design.writer import round_values, to_toml
from ..fileio import write_json_atomic, write_text_atomic
from ..optimize.plots import plot_convergence, plot_front
from ..optimize.search import SearchResult, objective_names
from ..optimize.tables import comparison, front_table, image_rows, image_true_rows
from ..optimize.verify import verify

FORMAT = "ftrac-optimize"
VERSION = 1


def design_toml(data: dict, header: str, profiles: tuple[str, ...] = ()) -> str:
    """The design ``data`` as a TOML file with a comment header; values rounded to 0.1 µm /
    0.0001° (far below any tolerance) when the rounded design stays valid and fails no rule
    of ``profiles`` that ``data`` passes (a winner sits on its limits: rounding can push a
    "> 0" gap to −0.000), else exact."""
    from ..design.loader import parse_design
    from ..errors import InputError
    from ..manufacture.rules import check_design

    def failed(d: dict) -> set[str]:
        design = parse_design(d)
        return {f"{p}:{r.rule}" for p in profiles for r in check_design(design, p).results if r.verdict == "fail"}

    rounded = round_values(data)
    try:
        body = to_toml(rounded) if not failed(rounded) - failed(data) else to_toml(data)
    except InputError:
        body = to_toml(data)
    comment = "".join(f"# {line}".rstrip() + "\n" for line in header.splitlines())
    return comment + "\n" + body


@dataclass(frozen=True)
class WinnerChecks:
    """How the start and the winner are checked, and what is made of the winner.

    Attributes
    ----------
    verify_poses : int
        Fresh workspace poses that re-score both.
    solver_images : int
        Simulated feature observations solved for both (0: none).
    build : bool
        Build the winner (CAD) into ``build/``.
    profile : str
        The build's manufacturing profile.
    check_images : int
        Rendered radiographs of both tracked (:mod:`ftrac_design.optimize.imagecheck`): clean ones
        for a search on the paper's model; for a search on the image-true score, a fresh image-true
        trial of that many images per condition.
    """

    verify_poses: int
    solver_images: int
    build: bool
    profile: str
    check_images: int = 0


def write_outputs(
    res: SearchResult,
    tmp: Path,
    log_path: Path,
    command_line: str,
    checks: WinnerChecks,
    progress: bool = False,
    executor: Executor | None = None,
) -> dict:
    """Write every output of a finished search into ``tmp`` (the caller renames it).

    Parameters
    ----------
    res : SearchResult
        The finished search.
    tmp : pathlib.Path
        The directory written.
    log_path : pathlib.Path
        The search's evaluation log, copied in.
    command_line : str
        The command that ran the search (best.toml's header, summary.json).
    checks : WinnerChecks
        How start and winner are checked.
    progress : bool
        Show progress bars.
    executor : concurrent.futures.Executor or None
        Where a fresh image-true trial is made (a search on the image-true score).

    Returns
    -------
    dict
        summary.json's object.
    """
    run = _Checking(res, checks, progress, executor)
    doc = _run_document(res, command_line)
    doc["start"]["verification"] = run.verification(res.space.base)
    if res.best is not None:
        _write_best(doc, run, tmp, command_line)
    else:
        doc["best"] = None
    rows, text_csv = front_table(res)
    doc["front"] = rows
    write_json_atomic(
        tmp / "pareto.json",
        {"format": FORMAT + "-front", "version": VERSION, "objective": res.config.objective, "points": rows},
    )
    write_text_atomic(tmp / "pareto.csv", text_csv)
    if res.entries:
        plot_convergence(res, tmp / "convergence.png")
        if any(e["feasible"] for e in res.entries):
            plot_front(res, tmp / "pareto.png")
    write_json_atomic(tmp / "summary.json", json.loads(json.dumps(doc, default=float)))
    shutil.copyfile(log_path, tmp / "evaluations.jsonl")
    return doc


def _run_document(res: SearchResult, command_line: str) -> dict:
    """summary.json's run, settings, space and the start's figures."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "command": command_line,
        "run": {
            "objective": res.config.objective,
            "objectives": list(objective_names(res.config.objective)),
            "evaluations": len(res.entries),
            "evaluated_now": res.evaluated,
            "replayed": res.replayed,
            "seed": res.config.seed,
            "sigma0": res.config.sigma0,
            "popsize": res.popsize or res.config.popsize,
            "seconds": res.seconds,
            "executor": res.executor,
            "stopped": res.stopped,
            "feasible_fraction": res.feasible_fraction,
            "refused_fraction": float(np.mean([bool(e["refused"]) for e in res.entries])) if res.entries else 0.0,
        },
        "settings": res.settings.to_dict(),
        "space": [
            {
                "key": p.key,
                "low": p.low,
                "high": p.high,
                "start": p.start,
                "choices": list(p.choices) if p.choices else None,
            }
            for p in res.space.parameters
        ],
        "start": {"figures": res.start["figures"], "margins": res.start["margins"]},
    }


class _Checking:
    """The checks of start and winner on streams the search never used (its sample = the seed)."""

    def __init__(self, res: SearchResult, checks: WinnerChecks, progress: bool, executor: Executor | None):
        self.res, self.checks, self.progress, self.executor = res, checks, progress, executor
        self.vseed = 1_000_003 + 2 * res.config.seed
        self.on_images = res.settings.image_trial is not None
        # an image-scored winner is re-checked by the score's own kind of trial, on seeds it never saw
        self.clean_check = checks.check_images if not self.on_images else 0

    def verification(self, data: dict) -> dict:
        """A design's predicted errors on fresh poses, its solver check and its clean images' check."""
        settings = self.res.settings.analysis
        v = verify(data, settings, self.checks.verify_poses, self.checks.solver_images, self.vseed)
        if self.clean_check:
            from ..optimize.imagecheck import image_check

            v["images"] = image_check(data, settings, self.clean_check, self.vseed + 3, self.progress)
        return v

    def scored_by(self) -> str:
        res = self.res
        if self.on_images:
            return (
                f"the image-true score ({res.settings.image_trial.images} rendered, tracked images per condition, "
                f"seed {res.settings.image_trial.seed})"
            )
        return f"the paper's feature-level model on {res.settings.analysis.poses} search poses"

    def described(self) -> str:
        n = self.checks.check_images
        if self.on_images and n:
            return f"a fresh image-true trial of {n} images per condition"
        return "the Monte-Carlo solver check" + (" and the rendered-image check" if n else "")


def _write_best(doc: dict, run: _Checking, tmp: Path, command_line: str) -> None:
    """best.toml, the winner's checks against the start's, comparison.txt and the build."""
    import tomllib

    from ..design.loader import parse_design

    res = run.res
    best_data = res.space.candidate(np.asarray(res.best["x"]))
    header = (
        f"{best_data['name']}: found by `{command_line}`\n"
        f"(ftrac-design optimize: {res.config.objective} objective, seed {res.config.seed}, {len(res.entries)} "
        f"evaluations, scored by {run.scored_by()}; start design "
        f"{res.start.get('design_sha256', '')[:12]}). Predicted p95 errors on {run.checks.verify_poses} fresh poses\n"
        f"and {run.described()} are in summary.json beside it."
    )
    text = design_toml(best_data, header, res.settings.profiles)
    write_text_atomic(tmp / "best.toml", text)
    written = tomllib.loads(text)
    parse_design(written, tmp / "best.toml")  # build accepts what we wrote
    v = run.verification(written)
    doc["best"] = {
        "index": res.best["index"],
        "generation": res.best["generation"],
        "parameters": res.best["parameters"],
        "design_sha256": res.best["design_sha256"],
        "figures": res.best["figures"],
        "objectives": res.best["objectives"],
        "margins": res.best["margins"],
        "verification": v,
    }
    doc["best"].update(_changes(doc["start"]["verification"], v, run))
    write_text_atomic(tmp / "comparison.txt", _comparison(doc, run, written))
    if run.checks.build:
        from ..cad.build import build_fiducial

        b = build_fiducial(parse_design(written, tmp / "best.toml"), tmp / "build", profile=run.checks.profile)
        doc["build"] = {"dir": "build", "seconds": b.manifest["build_time_s"]}


def _changes(v0: dict, v1: dict, run: _Checking) -> dict:
    """The winner's figures against the start's: on fresh poses, by the solver, on clean images."""
    s0, s1 = v0["predicted"], v1["predicted"]
    out: dict = {
        "change_on_fresh_poses": {
            "translation_p95": s1["translation_p95_mm"] / s0["translation_p95_mm"] - 1,
            "rotation_p95": s1["rotation_p95_deg"] / s0["rotation_p95_deg"] - 1,
        }
    }
    if run.checks.solver_images:
        m0, m1 = v0["solver"], v1["solver"]
        out["change_by_solver"] = {
            "translation_rms": m1["translation_rms_mm"] / m0["translation_rms_mm"] - 1,
            "rotation_rms": m1["rotation_rms_deg"] / m0["rotation_rms_deg"] - 1,
        }
    if run.clean_check:
        from ..optimize.imagecheck import paired_p95_ratio

        i0, i1 = v0["images"], v1["images"]
        change = {}
        for key in ("translation_p95_mm", "rotation_p95_deg", "translation_median_mm", "rotation_median_deg"):
            a, b = i0[key], i1[key]
            change[key.rsplit("_", 1)[0]] = b / a - 1 if a and b is not None else None
        change["paired"] = paired_p95_ratio(i0, i1)
        out["change_on_images"] = change
    return out


def _comparison(doc: dict, run: _Checking, written: dict) -> str:
    """comparison.txt: start against the winner (score, rules, atlas; their images); the fresh
    image-true trial of a search on the image-true score goes into ``doc`` too."""
    res, start_data = run.res, run.res.space.base
    text, cmp_doc = comparison(
        start_data, written, res.settings.analysis, res.settings.profiles, run.checks.verify_poses, run.vseed
    )
    if run.clean_check:
        text += "\n" + image_rows(doc["start"]["verification"]["images"], doc["best"]["verification"]["images"])
    if run.checks.check_images and run.on_images:
        from ..optimize.imagecheck import image_true_check

        fresh = replace(res.settings.image_trial, images=run.checks.check_images, seed=run.vseed + 5)
        doc["best"]["image_true_check"] = image_true_check(start_data, written, fresh, run.executor, run.progress)
        text += "\n" + image_true_rows(doc["best"]["image_true_check"])
    doc["comparison"] = cmp_doc
    return text
