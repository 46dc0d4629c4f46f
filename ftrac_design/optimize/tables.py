"""The optimiser's text: start vs best side by side (score as ``compare`` prints it, rules as
``check``, the atlas, rendered-image figures), the Pareto front as rows, and the summary it
prints."""

from __future__ import annotations

import csv
import io
from dataclasses import replace

from ..analysis.score import FIGURE_COLUMNS, AnalysisSettings, figure_cells
from .search import SearchResult


def image_rows(start: dict, best: dict) -> str:
    """Start vs best on rendered radiographs (:func:`.imagecheck.image_check`) as a table."""

    def g(v, fmt="{:.3f}"):
        return "-" if v is None else fmt.format(v)

    rows = [("design", "right", "wrong", "t median mm", "t p95", "t RMS", "r median °", "r p95", "r RMS")]
    for name, d in (("start", start), ("best", best)):
        rows.append(
            (
                name,
                str(d["right"]),
                str(d["wrong"]),
                g(d["translation_median_mm"]),
                g(d["translation_p95_mm"]),
                g(d["translation_rms_mm"]),
                g(d["rotation_median_deg"]),
                g(d["rotation_p95_deg"]),
                g(d["rotation_rms_deg"]),
            )
        )
    head = (
        f"rendered radiographs ({best['images']} each, the same poses and noise draws, tracked with no "
        f"initial guess; errors of the right poses, wrong = > 1° or > 5 mm off)"
    )
    return head + "\n" + _aligned(rows) + "\n"


def image_true_rows(check: dict) -> str:
    """Start vs best on the fresh image-true trial (:func:`.imagecheck.image_true_check`) as a
    table per condition and the paired p95 ratios."""

    def g(v, fmt="{:.3f}"):
        return "-" if v is None else fmt.format(v)

    rows = [("condition", "design", "images", "refused %", "wrong %", "t median mm", "t p95", "r median °", "r p95")]
    for cond in check["start"]:
        for name in ("start", "best"):
            d = check[name][cond]
            rows.append(
                (
                    cond,
                    name,
                    str(d["images"]),
                    g(d["refused_pct"], "{:.1f}"),
                    g(d["wrong_pct"], "{:.1f}"),
                    g(d["translation_median_mm"]),
                    g(d["translation_p95_mm"]),
                    g(d["rotation_median_deg"]),
                    g(d["rotation_p95_deg"]),
                )
            )
    ratios = [("paired p95 best / start", "images", "translation [95 % CI]", "rotation [95 % CI]")]
    for cond, p in check["paired"].items():
        if p is None:
            ratios.append((cond, "-", "-", "-"))
            continue
        ci_t, ci_r = p["translation_p95_ratio_95ci"], p["rotation_p95_ratio_95ci"]
        ratios.append(
            (
                cond,
                str(p["images"]),
                f"{p['translation_p95_ratio']:.3f} [{ci_t[0]:.3f}, {ci_t[1]:.3f}]",
                f"{p['rotation_p95_ratio']:.3f} [{ci_r[0]:.3f}, {ci_r[1]:.3f}]",
            )
        )
    w = check["settings"]["wrong_if_beyond"]
    head = (
        f"image-true check: fresh rendered radiographs, the same poses, noise and patients for both, "
        f"tracked with the default options; errors of the right poses, wrong = > {w['rotation_deg']:g}° or "
        f"> {w['translation_mm']:g} mm off and > {w['sigma']:g}σ by its own covariance"
    )
    return head + "\n" + _aligned(rows) + "\n\n" + _aligned(ratios) + "\n"


def _aligned(rows: list[tuple[str, ...]]) -> str:
    """Rows as text columns: the first left-aligned, the rest right-aligned."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join(
        "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))) for r in rows
    )


def _score_rows(named: list[tuple[str, object]]) -> str:
    """Start vs best as ``compare`` prints designs (predicted 1σ, 3-D RMS)."""
    rows = [("design", *FIGURE_COLUMNS, "verdict")]
    for name, s in named:
        rows.append((name, *figure_cells(s.figures), "PASS" if s.passed else "FAIL"))
    return _aligned(rows)


def comparison(
    start: dict,
    best: dict,
    settings: AnalysisSettings,
    profiles: tuple[str, ...],
    poses: int,
    seed: int,
    atlas_step_deg: float = 4.0,
) -> tuple[str, dict]:
    """Start vs best side by side: score, rules of each profile, whole-sphere atlas."""
    from ..analysis.atlas import blind_spot_atlas
    from ..analysis.score import Thresholds, score_design
    from ..design.loader import parse_design
    from ..features import compute_features
    from ..manufacture.rules import check_design

    designs = {"start": parse_design(start), "best": parse_design(best)}
    feats = {k: compute_features(d) for k, d in designs.items()}
    s = replace(settings, poses=poses, seed=seed)
    scores = {}
    for k, d in designs.items():
        a = d.analysis
        th = Thresholds(a.max_translation, a.max_rotation_deg, a.max_condition)
        scores[k] = score_design(feats[k], s.for_parts(d.analysis), th)
    ws = s.workspace
    lines = [
        f"{s.poses} fresh poses within {ws.cone_deg:g}° of the nominal beam, depth {ws.depth_mm:g} ± "
        f"{ws.depth_range_mm:g} mm, {s.noise_text} (predicted 1σ, 3-D RMS); each design's own parts: "
        + "; ".join(
            f"{k} beads ×{b:.3g}, wires ×{w:.3g}"
            for k, (b, w) in ((k, s.for_parts(designs[k].analysis).error_factors) for k in designs)
        ),
        _score_rows([(f"{k}: {designs[k].name}", scores[k]) for k in designs]),
        "",
    ]
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

        where = f"{w.get('angle_from_nominal_deg', 0):.0f}° from nominal, az {w.get('azimuth_deg', 0):.0f}°" + (
            " (" + ", ".join(f"{r['id']} {r['reason']}" for r in w.get("responsible", [])) + ")"
            if w.get("responsible")
            else ""
        )
        rows.append(
            (
                k,
                g(at["condition"]["median"]),
                g(at["condition"]["worst"]),
                g(at["condition"]["worst_in_cone"]),
                g(at["translation_mm"]["worst"], "{:.3f}"),
                g(at["rotation_deg"]["worst"], "{:.3f}"),
                where,
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(lines) + "\n", doc


def front_table(res: SearchResult) -> tuple[list[dict], str]:
    rows = []
    for e in res.front:
        rows.append(
            {
                "index": e["index"],
                "design_sha256": e["design_sha256"],
                **e["figures"],
                **{f"objective_{k}": v for k, v in e["objectives"].items()},
                **e["parameters"],
            }
        )
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return rows, buf.getvalue()


def _4f(v: float) -> str:
    return f"{v:.4f}"


def _or_dash(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def _to(start: dict, best: dict, key: str, show=_4f) -> str:
    """``start -> best`` of the figure ``key``, each as ``show`` writes it."""
    return f"{show(start[key])} -> {show(best[key])}"


def _ratio(p: dict, which: str, ci_note: str = "") -> str:
    """The p95 ratio best / start of ``which`` (translation, rotation) with its 95 % interval."""
    lo, hi = p[f"{which}_p95_ratio_95ci"]
    return f"{p[f'{which}_p95_ratio']:.2f} ({ci_note}{lo:.2f}–{hi:.2f})"


def format_summary(doc: dict) -> str:
    """A few lines for the terminal: start vs best on fresh poses and by the solver."""
    r = doc["run"]
    out = [
        f"{r['evaluations']} evaluations ({r['evaluated_now']} now, {r['replayed']} from the log) in "
        f"{r['seconds']:.1f} s on {r['executor']}; {r['feasible_fraction']:.0%} feasible"
    ]
    if doc.get("best") is None:
        out.append("no feasible candidate: nothing written but the log and the front")
        return "\n".join(out)
    s0, s1 = doc["start"]["verification"], doc["best"]["verification"]
    p0, p1 = s0["predicted"], s1["predicted"]
    ch = doc["best"]["change_on_fresh_poses"]
    out.append(
        f"fresh {s1['poses']} poses, predicted p95: translation {_to(p0, p1, 'translation_p95_mm')} mm "
        f"({ch['translation_p95']:+.1%}), rotation {_to(p0, p1, 'rotation_p95_deg')}° ({ch['rotation_p95']:+.1%})"
    )
    if "solver" in s1:
        m0, m1 = s0["solver"], s1["solver"]
        c = doc["best"]["change_by_solver"]
        out.append(
            f"solver, {m1['images']} images ({m0['solved']} / {m1['solved']} solved), RMS: translation "
            f"{_to(m0, m1, 'translation_rms_mm')} mm ({c['translation_rms']:+.1%}), rotation "
            f"{_to(m0, m1, 'rotation_rms_deg')}° ({c['rotation_rms']:+.1%}); bound at the same poses "
            f"{_to(m0, m1, 'predicted_translation_rms_mm')} mm, {_to(m0, m1, 'predicted_rotation_rms_deg')}°"
        )
    if "images" in s1:
        i0, i1 = s0["images"], s1["images"]
        out.append(
            f"rendered images, {i1['images']} tracked with no initial guess (right / wrong: start "
            f"{i0['right']} / {i0['wrong']}, best {i1['right']} / {i1['wrong']}): p95 translation "
            f"{_to(i0, i1, 'translation_p95_mm', _or_dash)} mm, rotation {_to(i0, i1, 'rotation_p95_deg', _or_dash)}°; "
            f"median {_to(i0, i1, 'translation_median_mm', _or_dash)} mm, "
            f"{_to(i0, i1, 'rotation_median_deg', _or_dash)}°"
        )
        pr = doc["best"].get("change_on_images", {}).get("paired")
        if pr:
            out.append(
                f"  p95 ratio over the {pr['poses']} poses both got right: translation "
                f"{_ratio(pr, 'translation', '95 % bootstrap ')}, rotation {_ratio(pr, 'rotation')}"
            )
    check = doc["best"].get("image_true_check")
    if check:
        for cond, p in check["paired"].items():
            if p is None:
                continue
            d0 = check["start"].get(cond, {})
            d1 = check["best"].get(cond, {})
            wrong = f"; wrong {_to(d0, d1, 'wrong_pct', '{:.1f}'.format)} %" if d0 and d1 else ""
            out.append(
                f"image-true check, {cond}: p95 ratio best / start over {p['images']} images both got right: "
                f"translation {_ratio(p, 'translation')}, rotation {_ratio(p, 'rotation')}{wrong}"
            )
    return "\n".join(out)
