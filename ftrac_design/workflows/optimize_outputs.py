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
from dataclasses import replace
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


def write_outputs(
    res: SearchResult,
    tmp: Path,
    log_path: Path,
    command_line: str,
    verify_poses: int,
    solver_images: int,
    build: bool,
    profile: str,
    check_images: int = 0,
    progress: bool = False,
    executor: Executor | None = None,
) -> dict:
    """Write every output of a finished search into ``tmp`` (the caller renames it);
    ``check_images`` rendered radiographs of start and best are tracked (:mod:`ftrac_design.optimize.imagecheck`):
    clean ones for a search on the paper's model; for a search on the image-true score, a fresh
    image-true trial of that many images per condition, made on ``executor``."""
    from ..design.loader import parse_design

    seed = res.config.seed
    # fresh poses: streams the search never used (search sample = seed)
    vseed = 1_000_003 + 2 * seed
    start_data = res.space.base
    best_data = res.space.candidate(np.asarray(res.best["x"])) if res.best is not None else None
    doc: dict = {
        "format": FORMAT,
        "version": VERSION,
        "command": command_line,
        "run": {
            "objective": res.config.objective,
            "objectives": list(objective_names(res.config.objective)),
            "evaluations": len(res.entries),
            "evaluated_now": res.evaluated,
            "replayed": res.replayed,
            "seed": seed,
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
    settings = res.settings.analysis
    doc["start"]["verification"] = verify(start_data, settings, verify_poses, solver_images, vseed)
    on_images = res.settings.image_trial is not None
    # an image-scored winner is re-checked by the score's own kind of trial, on seeds it never saw
    clean_check = check_images if not on_images else 0
    if clean_check:
        from ..optimize.imagecheck import image_check

        doc["start"]["verification"]["images"] = image_check(start_data, settings, check_images, vseed + 3, progress)
    if best_data is not None:
        scored_by = (
            f"the image-true score ({res.settings.image_trial.images} rendered, tracked images per condition, "
            f"seed {res.settings.image_trial.seed})"
            if on_images
            else f"the paper's feature-level model on {res.settings.analysis.poses} search poses"
        )
        checks = (
            f"a fresh image-true trial of {check_images} images per condition"
            if on_images and check_images
            else "the Monte-Carlo solver check" + (" and the rendered-image check" if check_images else "")
        )
        header = (
            f"{best_data['name']}: found by `{command_line}`\n"
            f"(ftrac-design optimize: {res.config.objective} objective, seed {seed}, {len(res.entries)} "
            f"evaluations, scored by {scored_by}; start design "
            f"{res.start.get('design_sha256', '')[:12]}). Predicted p95 errors on {verify_poses} fresh poses\n"
            f"and {checks} are in summary.json beside it."
        )
        text = design_toml(best_data, header, res.settings.profiles)
        write_text_atomic(tmp / "best.toml", text)
        import tomllib

        written = tomllib.loads(text)
        parse_design(written, tmp / "best.toml")  # build accepts what we wrote
        v = verify(written, settings, verify_poses, solver_images, vseed)
        if clean_check:
            v["images"] = image_check(written, settings, clean_check, vseed + 3, progress)
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
        s0, s1 = doc["start"]["verification"]["predicted"], v["predicted"]
        doc["best"]["change_on_fresh_poses"] = {
            "translation_p95": s1["translation_p95_mm"] / s0["translation_p95_mm"] - 1,
            "rotation_p95": s1["rotation_p95_deg"] / s0["rotation_p95_deg"] - 1,
        }
        if solver_images:
            m0, m1 = doc["start"]["verification"]["solver"], v["solver"]
            doc["best"]["change_by_solver"] = {
                "translation_rms": m1["translation_rms_mm"] / m0["translation_rms_mm"] - 1,
                "rotation_rms": m1["rotation_rms_deg"] / m0["rotation_rms_deg"] - 1,
            }
        if clean_check:
            i0, i1 = doc["start"]["verification"]["images"], v["images"]
            change = {}
            for key in ("translation_p95_mm", "rotation_p95_deg", "translation_median_mm", "rotation_median_deg"):
                a, b = i0[key], i1[key]
                change[key.rsplit("_", 1)[0]] = b / a - 1 if a and b is not None else None
            from ..optimize.imagecheck import paired_p95_ratio

            change["paired"] = paired_p95_ratio(i0, i1)
            doc["best"]["change_on_images"] = change
        text_cmp, cmp_doc = comparison(start_data, written, settings, res.settings.profiles, verify_poses, vseed)
        if clean_check:
            text_cmp += "\n" + image_rows(doc["start"]["verification"]["images"], v["images"])
        if check_images and on_images:
            from ..optimize.imagecheck import image_true_check

            fresh = replace(res.settings.image_trial, images=check_images, seed=vseed + 5)
            doc["best"]["image_true_check"] = image_true_check(start_data, written, fresh, executor, progress)
            text_cmp += "\n" + image_true_rows(doc["best"]["image_true_check"])
        write_text_atomic(tmp / "comparison.txt", text_cmp)
        doc["comparison"] = cmp_doc
        if build:
            from ..cad.build import build_fiducial

            b = build_fiducial(parse_design(written, tmp / "best.toml"), tmp / "build", profile=profile)
            doc["build"] = {"dir": "build", "seconds": b.manifest["build_time_s"]}
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
