"""What ``optimize`` writes: the winner checked on fresh poses and by the solver, the best
design as TOML, the Pareto front, the convergence plot and start vs best side by side.

Output directory (written atomically: a temporary sibling renamed into place):

- ``best.toml`` — the winner as a design file ``build`` accepts (header: how it was found)
- ``summary.json`` — format ``ftrac-optimize`` v1: run, space, start and best (parameters,
  figures on the search sample and on fresh poses, Monte-Carlo solver errors, rules), front
- ``comparison.txt`` — start vs best: score (as ``compare`` prints it), rules (as ``check``),
  atlas
- ``pareto.json`` / ``pareto.csv`` / ``pareto.png`` — the non-dominated feasible candidates
- ``convergence.png`` — best objective so far and feasible share per generation
- ``evaluations.jsonl`` — the evaluation log
- ``build/`` — ``ftrac-design build`` of ``best.toml`` (unless ``--no-build``)
"""

from __future__ import annotations

import csv
import io
import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..analysis.score import AnalysisSettings
from ..fileio import atomic_file, write_json_atomic, write_text_atomic
from .search import SearchResult, _ok, objective_names

FORMAT = "ftrac-optimize"
VERSION = 1


def _round(v):
    if isinstance(v, float):
        return round(v, 4) + 0.0
    if isinstance(v, list):
        return [_round(x) for x in v]
    if isinstance(v, dict):
        return {k: _round(x) for k, x in v.items()}
    return v


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def _toml_table(data: dict, path: str, out: list[str]) -> None:
    scalars = {k: v for k, v in data.items()
               if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))}
    if path and (scalars or not data):
        out.append(f"\n[{path}]")
    out += [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    for k, v in data.items():
        sub = f"{path}.{k}" if path else k
        if isinstance(v, dict):
            _toml_table(v, sub, out)
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                out.append(f"\n[[{sub}]]")
                out += [f"{kk} = {_toml_value(vv)}" for kk, vv in item.items()]


def to_toml(data: dict) -> str:
    """Design data as TOML in the design files' own layout (``[table]``s, ``[[ellipses]]``,
    one-line arrays), which a generic writer such as tomli-w does not keep."""
    out: list[str] = []
    _toml_table(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"


def design_toml(data: dict, header: str, profiles: tuple[str, ...] = ()) -> str:
    """The design ``data`` as a TOML file with a comment header; values rounded to 0.1 µm /
    0.0001° (far below any tolerance) when the rounded design stays valid and fails no rule
    of ``profiles`` that ``data`` passes (a winner sits on its limits: rounding can push a
    "> 0" gap to −0.000), else exact."""
    from ..cad.rules import check_design
    from ..design.loader import parse_design
    from ..errors import InputError

    def failed(d: dict) -> set[str]:
        design = parse_design(d)
        return {f"{p}:{r.rule}" for p in profiles for r in check_design(design, p).results if r.verdict == "fail"}

    rounded = _round(data)
    try:
        body = to_toml(rounded) if not failed(rounded) - failed(data) else to_toml(data)
    except InputError:
        body = to_toml(data)
    comment = "".join(f"# {line}".rstrip() + "\n" for line in header.splitlines())
    return comment + "\n" + body


def verify(data: dict, settings: AnalysisSettings, poses: int, images: int, seed: int) -> dict:
    """Re-score ``data`` on ``poses`` fresh workspace poses (seed ``seed``) and solve
    ``images`` simulated images (seed ``seed + 1``) with the robust solver, no initial guess.

    Returns the predicted p95/worst 1σ errors on the fresh poses and the Monte-Carlo
    errors: RMS and p95 of the 3-D translation (mm) and rotation (°) errors, how many solved.
    """
    from ..analysis.poses import analyse_poses
    from ..analysis.sampling import workspace_poses
    from ..design.loader import parse_design
    from ..features import compute_features
    from ..pose import SolverOptions, solve_batch
    from ..pose.simulate import pose_errors, simulate_observation
    from .evaluate import score_figures

    design = parse_design(data)
    settings = settings.for_parts(design.analysis)       # its own parts' segmentation errors
    f = compute_features(design)
    fresh = score_figures(f, replace(settings, poses=poses, seed=seed))
    out = {"poses": poses, "pose_seed": seed, "predicted": fresh}
    if images:
        R, t = workspace_poses(settings.workspace, f.nominal_beam_direction, images, seed + 1)
        rng = np.random.default_rng(seed + 2)
        obs = [simulate_observation(f, settings.camera, R[i], t[i], settings.segmentation_error_mm, rng,
                                    error_factors=settings.error_factors)
               for i in range(images)]
        sol = solve_batch(f, obs, SolverOptions(noise=settings.noise))
        ok = np.array([p.converged for p in sol])
        Re = np.array([p.rotation if p.converged else np.eye(3) for p in sol])
        te = np.array([p.translation_mm if p.converged else np.zeros(3) for p in sol])
        dr, dt = pose_errors(Re, te, R, t)
        et = np.linalg.norm(dt, axis=1)[ok]
        er = np.degrees(np.linalg.norm(dr, axis=1))[ok]
        # the bound at the same poses: the solver should attain it (efficiency ≈ 1)
        m = analyse_poses(f, R, t, settings.camera, settings.noise, settings.contour, detail=False).overall
        pt = float(np.sqrt(np.mean(m.translation_rms_mm[ok] ** 2)))
        pr = float(np.sqrt(np.mean(m.rotation_rms_deg[ok] ** 2)))
        out["solver"] = {"images": images, "solved": int(ok.sum()), "image_seed": seed + 1,
                         "translation_rms_mm": float(np.sqrt(np.mean(et ** 2))),
                         "translation_p95_mm": float(np.percentile(et, 95)),
                         "rotation_rms_deg": float(np.sqrt(np.mean(er ** 2))),
                         "rotation_p95_deg": float(np.percentile(er, 95)),
                         "predicted_translation_rms_mm": pt, "predicted_rotation_rms_deg": pr}
    return out


def image_rows(start: dict, best: dict) -> str:
    """Start vs best on rendered radiographs (:func:`.imagecheck.image_check`) as a table."""
    def g(v, fmt="{:.3f}"):
        return "-" if v is None else fmt.format(v)

    rows = [("design", "right", "wrong", "t median mm", "t p95", "t RMS", "r median °", "r p95", "r RMS")]
    for name, d in (("start", start), ("best", best)):
        rows.append((name, str(d["right"]), str(d["wrong"]), g(d["translation_median_mm"]),
                     g(d["translation_p95_mm"]), g(d["translation_rms_mm"]), g(d["rotation_median_deg"]),
                     g(d["rotation_p95_deg"]), g(d["rotation_rms_deg"])))
    head = (f"rendered radiographs ({best['images']} each, the same poses and noise draws, tracked with no "
            f"initial guess; errors of the right poses, wrong = > 1° or > 5 mm off)")
    return head + "\n" + _aligned(rows) + "\n"


def _aligned(rows: list[tuple[str, ...]]) -> str:
    """Rows as text columns: the first left-aligned, the rest right-aligned."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
                     for r in rows)


def _score_rows(named: list[tuple[str, object]]) -> str:
    """Start vs best as ``compare`` prints designs (predicted 1σ, 3-D RMS)."""
    rows = [("design", "t p95 mm", "t worst", "depth p95", "r p95 °", "r worst", "cond med", "cond worst", "verdict")]
    for name, s in named:
        f = s.figures

        def g(v):
            return "inf" if v is None else f"{v:.3f}"

        rows.append((name, g(f["translation_mm"]["p95"]), g(f["translation_mm"]["worst"]),
                     g(f["translation_p95_per_axis_mm"][2]), g(f["rotation_deg"]["p95"]),
                     g(f["rotation_deg"]["worst"]),
                     "inf" if f["condition"]["median"] is None else f"{f['condition']['median']:.0f}",
                     "inf" if f["condition"]["worst"] is None else f"{f['condition']['worst']:.0f}",
                     "PASS" if s.passed else "FAIL"))
    return _aligned(rows)


def comparison(start: dict, best: dict, settings: AnalysisSettings, profiles: tuple[str, ...], poses: int,
               seed: int, atlas_step_deg: float = 4.0) -> tuple[str, dict]:
    """Start vs best side by side: score, rules of each profile, whole-sphere atlas."""
    from ..analysis.atlas import blind_spot_atlas
    from ..analysis.score import Thresholds, score_design
    from ..cad.rules import check_design
    from ..design.loader import parse_design
    from ..features import compute_features

    designs = {"start": parse_design(start), "best": parse_design(best)}
    feats = {k: compute_features(d) for k, d in designs.items()}
    s = replace(settings, poses=poses, seed=seed)
    scores = {}
    for k, d in designs.items():
        a = d.analysis
        th = Thresholds(a.max_translation, a.max_rotation_deg, a.max_condition)
        scores[k] = score_design(feats[k], s.for_parts(d.analysis), th)
    ws = s.workspace
    lines = [f"{s.poses} fresh poses within {ws.cone_deg:g}° of the nominal beam, depth {ws.depth_mm:g} ± "
             f"{ws.depth_range_mm:g} mm, {s.noise_text} (predicted 1σ, 3-D RMS); each design's own parts: "
             + "; ".join(f"{k} beads ×{b:.3g}, wires ×{w:.3g}" for k, (b, w) in
                         ((k, s.for_parts(designs[k].analysis).error_factors) for k in designs)),
             _score_rows([(f"{k}: {designs[k].name}", scores[k]) for k in designs]), ""]
    doc: dict = {"score": {k: v.figures for k, v in scores.items()}, "rules": {}, "atlas": {}}
    for prof in profiles:
        reps = {k: check_design(d, prof, feats[k]) for k, d in designs.items()}
        lines.append(f"rules ({prof}): start {reps['start'].summary}; best {reps['best'].summary}")
        rows = [("rule", "start", "", "best", "", "limit")]
        for a, b in zip(reps["start"].results, reps["best"].results):
            def m(r):
                return "-" if r.measured is None else f"{r.measured:.3f}"
            lim = "-" if a.measured is None else f"{a.comparison} {a.limit:g}"
            rows.append((a.rule, m(a), a.verdict, m(b), b.verdict, lim))
        widths = [max(len(r[i]) for r in rows) for i in range(6)]
        lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
        lines.append("")
        doc["rules"][prof] = {k: r.as_dict() for k, r in reps.items()}
    lines.append(f"atlas (whole sphere, {atlas_step_deg:g}° grid; fiducial at the isocentre)")
    rows = [("design", "cond median", "cond worst", "cond worst in cone", "t worst mm", "r worst °", "worst direction")]
    for k, f in feats.items():
        at = blind_spot_atlas(f, s.for_parts(designs[k].analysis), step_deg=atlas_step_deg, n_worst=1).to_dict()
        doc["atlas"][k] = at
        w = at["worst_directions"][0] if at["worst_directions"] else {}

        def g(v, fmt="{:.0f}"):
            return "inf" if v is None else fmt.format(v)

        where = (f"{w.get('angle_from_nominal_deg', 0):.0f}° from nominal, az {w.get('azimuth_deg', 0):.0f}°"
                 + (" (" + ", ".join(f"{r['id']} {r['reason']}" for r in w.get("responsible", [])) + ")"
                    if w.get("responsible") else ""))
        rows.append((k, g(at["condition"]["median"]), g(at["condition"]["worst"]),
                     g(at["condition"]["worst_in_cone"]), g(at["translation_mm"]["worst"], "{:.3f}"),
                     g(at["rotation_deg"]["worst"], "{:.3f}"), where))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(lines) + "\n", doc


def _plot_convergence(res: SearchResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = objective_names(res.config.objective)
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    idx = np.arange(1, len(res.entries) + 1)
    vals = np.array([e["objectives"][names[0]] if _ok(e) else np.nan for e in res.entries])
    ax[0].plot(idx, vals, ".", ms=3, color="0.6", label="feasible candidate")
    best = np.fmin.accumulate(np.where(np.isnan(vals), np.inf, vals))
    if names[0].endswith("ratio"):  # the start scores 1 by construction
        best = np.minimum(best, 1.0)
    ax[0].plot(idx, np.where(np.isfinite(best), best, np.nan), "C0-", label="best so far")
    ax[0].axhline(1.0 if names[0].endswith("ratio") else np.nan, color="k", lw=0.8, ls=":", label="start")
    ax[0].set_xlabel("evaluation")
    ax[0].set_ylabel(names[0].replace("_", " "))
    lo, hi = np.nanpercentile(vals, [0, 90]) if np.isfinite(vals).any() else (0, 1)
    ax[0].set_ylim(min(lo, 1.0) * 0.97, max(hi, 1.0) * 1.03)
    ax[0].legend(fontsize=8)
    gens = np.array([e["generation"] for e in res.entries])
    feas = np.array([e["feasible"] for e in res.entries], float)
    ug = np.unique(gens)
    ax[1].plot(ug, [feas[gens == g].mean() for g in ug], "C1-")
    ax[1].set_xlabel("generation")
    ax[1].set_ylabel("feasible share of candidates")
    ax[1].set_ylim(0, 1.02)
    fig.suptitle(f"{res.start.get('name', '')} optimize --objective {res.config.objective} "
                 f"(seed {res.config.seed}, {len(res.entries)} evaluations)", fontsize=10)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def _plot_front(res: SearchResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    feas = [e for e in res.entries if e["feasible"]]
    size = res.config.objective == "accuracy-diameter"
    if size:  # accuracy against size, each error on its own panel, with plain 1/size scaling
        panels = [("outer_diameter_mm", "translation_p95_mm", "p95 translation error, mm"),
                  ("outer_diameter_mm", "rotation_p95_deg", "p95 rotation error, °")]
    else:
        panels = [("translation_p95_mm", "rotation_p95_deg", "p95 rotation error, °")]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.4 * len(panels), 4.2), squeeze=False)
    for ax, (kx, ky, label) in zip(axes[0], panels):
        ax.plot([e["figures"][kx] for e in feas], [e["figures"][ky] for e in feas], ".", color="0.75", ms=3,
                label="feasible candidates")
        ax.plot([e["figures"][kx] for e in res.front], [e["figures"][ky] for e in res.front], "C0o-", ms=3,
                label="Pareto front")
        s0 = res.start["figures"]
        ax.plot([s0[kx]], [s0[ky]], "k*", ms=10, label="start")
        if size:
            d = np.linspace(s0[kx], max(e["figures"][kx] for e in feas), 50)
            ax.plot(d, s0[ky] * s0[kx] / d, "k:", lw=1, label="start scaled up (∝ 1/size)")
            ax.set_yscale("log")
            ax.set_xlabel("body outer diameter, mm (length 2 × diameter)")
        else:
            ax.set_xlabel("p95 translation error, mm")
        if res.best is not None:
            ax.plot([res.best["figures"][kx]], [res.best["figures"][ky]], "C3*", ms=10, label="best")
        ax.set_ylabel(label + " (predicted 1σ)")
        ax.legend(fontsize=8)
    fig.suptitle(f"optimize --objective {res.config.objective} (seed {res.config.seed}, "
                 f"{len(res.entries)} evaluations)", fontsize=10)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def _front_table(res: SearchResult) -> tuple[list[dict], str]:
    rows = []
    for e in res.front:
        rows.append({"index": e["index"], "design_sha256": e["design_sha256"], **e["figures"],
                     **{f"objective_{k}": v for k, v in e["objectives"].items()}, **e["parameters"]})
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return rows, buf.getvalue()


def write_outputs(res: SearchResult, tmp: Path, log_path: Path, command_line: str, verify_poses: int,
                  solver_images: int, build: bool, profile: str, check_images: int = 0,
                  progress: bool = False) -> dict:
    """Write every output of a finished search into ``tmp`` (the caller renames it);
    ``check_images`` rendered radiographs of start and best are tracked (:mod:`.imagecheck`)."""
    from ..design.loader import parse_design

    seed = res.config.seed
    # fresh poses: streams the search never used (search sample = seed)
    vseed = 1_000_003 + 2 * seed
    start_data = res.space.base
    best_data = res.space.candidate(np.asarray(res.best["x"])) if res.best is not None else None
    doc: dict = {"format": FORMAT, "version": VERSION, "command": command_line,
                 "run": {"objective": res.config.objective, "objectives": list(objective_names(res.config.objective)),
                         "evaluations": len(res.entries), "evaluated_now": res.evaluated, "replayed": res.replayed,
                         "seed": seed, "sigma0": res.config.sigma0, "popsize": res.popsize or res.config.popsize,
                         "seconds": res.seconds, "executor": res.executor, "stopped": res.stopped,
                         "feasible_fraction": res.feasible_fraction,
                         "refused_fraction": float(np.mean([bool(e["refused"]) for e in res.entries]))
                         if res.entries else 0.0},
                 "settings": res.settings.to_dict(),
                 "space": [{"key": p.key, "low": p.low, "high": p.high, "start": p.start,
                            "choices": list(p.choices) if p.choices else None} for p in res.space.parameters],
                 "start": {"figures": res.start["figures"], "margins": res.start["margins"]}}
    settings = res.settings.analysis
    doc["start"]["verification"] = verify(start_data, settings, verify_poses, solver_images, vseed)
    if check_images:
        from .imagecheck import image_check

        doc["start"]["verification"]["images"] = image_check(start_data, settings, check_images, vseed + 3, progress)
    if best_data is not None:
        header = (f"{best_data['name']}: found by `{command_line}`\n"
                  f"(ftrac-design optimize: {res.config.objective} objective, seed {seed}, {len(res.entries)} "
                  f"evaluations, {res.settings.analysis.poses} search poses; start design "
                  f"{res.start.get('design_sha256', '')[:12]}). Predicted p95 errors on {verify_poses} fresh poses,\n"
                  f"the Monte-Carlo solver check{' and the rendered-image check' if check_images else ''} are in "
                  f"summary.json beside it.")
        text = design_toml(best_data, header, res.settings.profiles)
        write_text_atomic(tmp / "best.toml", text)
        import tomllib

        written = tomllib.loads(text)
        parse_design(written, tmp / "best.toml")  # build accepts what we wrote
        v = verify(written, settings, verify_poses, solver_images, vseed)
        if check_images:
            v["images"] = image_check(written, settings, check_images, vseed + 3, progress)
        doc["best"] = {"index": res.best["index"], "generation": res.best["generation"],
                       "parameters": res.best["parameters"], "design_sha256": res.best["design_sha256"],
                       "figures": res.best["figures"], "objectives": res.best["objectives"],
                       "margins": res.best["margins"], "verification": v}
        s0, s1 = doc["start"]["verification"]["predicted"], v["predicted"]
        doc["best"]["change_on_fresh_poses"] = {
            "translation_p95": s1["translation_p95_mm"] / s0["translation_p95_mm"] - 1,
            "rotation_p95": s1["rotation_p95_deg"] / s0["rotation_p95_deg"] - 1}
        if solver_images:
            m0, m1 = doc["start"]["verification"]["solver"], v["solver"]
            doc["best"]["change_by_solver"] = {
                "translation_rms": m1["translation_rms_mm"] / m0["translation_rms_mm"] - 1,
                "rotation_rms": m1["rotation_rms_deg"] / m0["rotation_rms_deg"] - 1}
        if check_images:
            i0, i1 = doc["start"]["verification"]["images"], v["images"]
            change = {}
            for key in ("translation_p95_mm", "rotation_p95_deg", "translation_median_mm", "rotation_median_deg"):
                a, b = i0[key], i1[key]
                change[key.rsplit("_", 1)[0]] = b / a - 1 if a and b is not None else None
            from .imagecheck import paired_p95_ratio

            change["paired"] = paired_p95_ratio(i0, i1)
            doc["best"]["change_on_images"] = change
        text_cmp, cmp_doc = comparison(start_data, written, settings, res.settings.profiles, verify_poses, vseed)
        if check_images:
            text_cmp += "\n" + image_rows(doc["start"]["verification"]["images"], v["images"])
        write_text_atomic(tmp / "comparison.txt", text_cmp)
        doc["comparison"] = cmp_doc
        if build:
            from ..cad.build import build_fiducial

            b = build_fiducial(parse_design(written, tmp / "best.toml"), tmp / "build", profile=profile)
            doc["build"] = {"dir": "build", "seconds": b.manifest["build_time_s"]}
    else:
        doc["best"] = None
    rows, text_csv = _front_table(res)
    doc["front"] = rows
    write_json_atomic(tmp / "pareto.json", {"format": FORMAT + "-front", "version": VERSION,
                                            "objective": res.config.objective, "points": rows})
    write_text_atomic(tmp / "pareto.csv", text_csv)
    if res.entries:
        _plot_convergence(res, tmp / "convergence.png")
        if any(e["feasible"] for e in res.entries):
            _plot_front(res, tmp / "pareto.png")
    write_json_atomic(tmp / "summary.json", json.loads(json.dumps(doc, default=float)))
    shutil.copyfile(log_path, tmp / "evaluations.jsonl")
    return doc


def format_summary(doc: dict) -> str:
    """A few lines for the terminal: start vs best on fresh poses and by the solver."""
    r = doc["run"]
    out = [f"{r['evaluations']} evaluations ({r['evaluated_now']} now, {r['replayed']} from the log) in "
           f"{r['seconds']:.1f} s on {r['executor']}; {r['feasible_fraction']:.0%} feasible"]
    if doc.get("best") is None:
        out.append("no feasible candidate: nothing written but the log and the front")
        return "\n".join(out)
    s0, s1 = doc["start"]["verification"], doc["best"]["verification"]
    p0, p1 = s0["predicted"], s1["predicted"]
    ch = doc["best"]["change_on_fresh_poses"]
    out.append(f"fresh {s1['poses']} poses, predicted p95: translation {p0['translation_p95_mm']:.4f} -> "
               f"{p1['translation_p95_mm']:.4f} mm ({ch['translation_p95']:+.1%}), rotation "
               f"{p0['rotation_p95_deg']:.4f} -> {p1['rotation_p95_deg']:.4f}° ({ch['rotation_p95']:+.1%})")
    if "solver" in s1:
        m0, m1 = s0["solver"], s1["solver"]
        c = doc["best"]["change_by_solver"]
        out.append(f"solver, {m1['images']} images ({m0['solved']} / {m1['solved']} solved), RMS: translation "
                   f"{m0['translation_rms_mm']:.4f} -> {m1['translation_rms_mm']:.4f} mm "
                   f"({c['translation_rms']:+.1%}), rotation {m0['rotation_rms_deg']:.4f} -> "
                   f"{m1['rotation_rms_deg']:.4f}° ({c['rotation_rms']:+.1%}); "
                   f"bound at the same poses {m0['predicted_translation_rms_mm']:.4f} -> "
                   f"{m1['predicted_translation_rms_mm']:.4f} mm, {m0['predicted_rotation_rms_deg']:.4f} -> "
                   f"{m1['predicted_rotation_rms_deg']:.4f}°")
    if "images" in s1:
        i0, i1 = s0["images"], s1["images"]

        def g(v, fmt):
            return "-" if v is None else fmt.format(v)

        out.append(f"rendered images, {i1['images']} tracked with no initial guess (right / wrong: start "
                   f"{i0['right']} / {i0['wrong']}, best {i1['right']} / {i1['wrong']}): p95 translation "
                   f"{g(i0['translation_p95_mm'], '{:.3f}')} -> {g(i1['translation_p95_mm'], '{:.3f}')} mm, rotation "
                   f"{g(i0['rotation_p95_deg'], '{:.3f}')} -> {g(i1['rotation_p95_deg'], '{:.3f}')}°; median "
                   f"{g(i0['translation_median_mm'], '{:.3f}')} -> {g(i1['translation_median_mm'], '{:.3f}')} mm, "
                   f"{g(i0['rotation_median_deg'], '{:.3f}')} -> {g(i1['rotation_median_deg'], '{:.3f}')}°")
        pr = doc["best"].get("change_on_images", {}).get("paired")
        if pr:
            out.append(f"  p95 ratio over the {pr['poses']} poses both got right: translation "
                       f"{pr['translation_p95_ratio']:.2f} (95 % bootstrap {pr['translation_p95_ratio_95ci'][0]:.2f}–"
                       f"{pr['translation_p95_ratio_95ci'][1]:.2f}), rotation {pr['rotation_p95_ratio']:.2f} "
                       f"({pr['rotation_p95_ratio_95ci'][0]:.2f}–{pr['rotation_p95_ratio_95ci'][1]:.2f})")
    return "\n".join(out)


def replot(log_path: str | Path, out_dir: str | Path) -> list[Path]:
    """Redraw ``convergence.png`` and ``pareto.png`` into ``out_dir`` from an evaluation log
    alone (``python -c "from ftrac_design.optimize.report import replot; replot(LOG, DIR)"``)."""
    from .search import SearchConfig, _front_mask

    lines = [json.loads(s) for s in Path(log_path).read_text(encoding="utf-8").splitlines() if s.strip()]
    head, start = lines[0], lines[1]
    cfg = SearchConfig(**{k: v for k, v in head["config"].items() if k in SearchConfig.__dataclass_fields__})
    entries = [e for e in lines[2:] if e.get("kind") == "candidate"]
    feas = [e for e in entries if e["feasible"]]
    if cfg.multi:
        f = np.array([list(e["objectives"].values()) for e in feas])
        front = sorted((e for e, m in zip(feas, _front_mask(f)) if m), key=lambda e: list(e["objectives"].values())[1])
        best = min(front, key=lambda e: list(e["objectives"].values())[0]) if front else None
    else:
        f = np.array([[e["figures"]["translation_p95_mm"], e["figures"]["rotation_p95_deg"]] for e in feas])
        front = sorted((e for e, m in zip(feas, _front_mask(f)) if m), key=lambda e: e["figures"]["translation_p95_mm"])
        ok = [e for e in feas if _ok(e)]
        best = min(ok, key=lambda e: (list(e["objectives"].values())[0], e["index"])) if ok else None
    res = SearchResult(None, cfg, None, start, entries, best, front, 0.0, 0, len(entries))
    out = Path(out_dir)
    _plot_convergence(res, out / "convergence.png")
    _plot_front(res, out / "pareto.png")
    return [out / "convergence.png", out / "pareto.png"]
