"""The design report as one self-contained HTML page.

Every picture is embedded as a base64 ``data:`` URI and the style sheet is inline, so the
file opens in any browser with no network and can be mailed to a collaborator or a machine
shop as it is. Sections (their ``<h2>`` titles are :data:`SECTIONS`, in page order): render,
design parameters, features, design rules (cnc and fdm), score, blind-spot atlas, bill of
materials, wire cut list, output files (sha256), versions. A part that is not available
says which command produces it.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import math
from pathlib import Path
from typing import Any, Iterable

from ..errors import InputError
from ..fileio import write_text_atomic
from .inputs import ReportInputs

SECTIONS = (
    "Render",
    "Design parameters",
    "Features",
    "Design rules",
    "Score",
    "Blind-spot atlas",
    "Bill of materials",
    "Wire cut list",
    "Output files",
    "Versions",
)

_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d2330;margin:0;background:#f4f6f9}
header{background:#1f3a5f;color:#fff;padding:18px 28px}
header h1{margin:0 0 4px;font-size:24px}
header p{margin:2px 0;color:#d4e0f0}
nav{background:#29496f;padding:6px 28px}
nav a{color:#fff;margin-right:14px;text-decoration:none;font-size:13px}
main{padding:8px 28px 40px;max-width:1200px}
section{background:#fff;border:1px solid #d9dee7;border-radius:6px;padding:6px 18px 14px;margin:16px 0}
h2{font-size:18px;color:#1f3a5f;border-bottom:2px solid #e3e8f0;padding-bottom:4px}
h3{font-size:15px;margin:14px 0 6px}
table{border-collapse:collapse;margin:6px 0 10px;font-size:13px}
th,td{border:1px solid #d9dee7;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#eef2f8}
td.num{text-align:right;font-variant-numeric:tabular-nums}
code,.mono{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:12px}
.ok{background:#e3f4e6;color:#1d6b2c;font-weight:600}
.warn{background:#fff3d6;color:#8a5a00;font-weight:600}
.fail{background:#fde2e1;color:#a11d1a;font-weight:700}
.na{color:#7a8496}
.badge{display:inline-block;border-radius:4px;padding:1px 8px;margin-left:6px;font-size:13px}
.note{color:#5b6577;font-style:italic}
img{max-width:100%;border:1px solid #d9dee7;border-radius:4px;background:#fff}
.pics{display:flex;flex-wrap:wrap;gap:12px}
.pics figure{margin:0;flex:1 1 100%}
figcaption{font-size:12px;color:#5b6577}
.grid{display:flex;flex-wrap:wrap;gap:0 22px;align-items:flex-start}
.top{display:flex;flex-wrap:wrap;gap:18px;align-items:flex-start}
.top figure{margin:0;flex:1 1 520px;max-width:640px}
.summary{flex:1 1 300px}
.summary td:first-child{color:#5b6577}
"""


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(v: Any, fmt: str = ".4g") -> str:
    if v is None:
        return "–"
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return _e(v)
    if isinstance(v, float) and not math.isfinite(v):
        return "inf" if v > 0 else ("−inf" if v < 0 else "nan")
    return format(v, fmt) if isinstance(v, float) else str(v)


def _vec(v: Iterable[float], fmt: str = ".3f") -> str:
    return "(" + ", ".join(format(float(x), fmt) for x in v) + ")"


def _table(head: list[str], rows: list[list[str]], num_cols: Iterable[int] = ()) -> str:
    """Cells are HTML already (escape before)."""
    nc = set(num_cols)
    h = "".join(f"<th>{c}</th>" for c in head)
    body = "".join(
        "<tr>" + "".join(f'<td class="num">{c}</td>' if i in nc else f"<td>{c}</td>" for i, c in enumerate(r)) + "</tr>"
        for r in rows
    )
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def data_uri(png: bytes) -> str:
    """A PNG as a ``data:image/png;base64,…`` URI."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _img(png: bytes, alt: str, caption: str = "") -> str:
    cap = f"<figcaption>{_e(caption)}</figcaption>" if caption else ""
    return f'<figure><img src="{data_uri(png)}" alt="{_e(alt)}">{cap}</figure>'


def _section(title: str, body: str) -> str:
    anchor = title.lower().replace(" ", "-")
    return f'<section id="{anchor}"><h2>{_e(title)}</h2>\n{body}\n</section>'


def _missing(what: str) -> str:
    return f'<p class="note">{_e(what)}</p>'


# ------------------------------------------------------------------------------- sections
def _render(r: ReportInputs) -> str:
    if r.render_png is None:
        pic = _missing(
            "No render: `ftrac-design build DESIGN.toml` writes render.png (translucent body, "
            "steel wires and beads); `ftrac-design report BUILD_DIR` shows it."
        )
    else:
        pic = _img(r.render_png, f"render of {r.name}", "render.png — body translucent, wires and beads steel")
    return f'<div class="top">{pic}<div class="summary"><h3>At a glance</h3>{_summary(r)}</div></div>'


def _summary(r: ReportInputs) -> str:
    """Key facts and verdicts beside the render."""
    f = r.features
    rows = [["features", _e(f"{len(f.points)} beads, {len(f.lines)} lines, {len(f.ellipses)} ellipses")]]
    if r.design is not None:
        b = r.design.body
        rows.append(["body", _e(f"Ø{b.outer_diameter:g} × {b.length:g} mm, bore Ø{b.bore_diameter:g}, {b.material}")])
    for profile, rep in r.rules.items():
        n, w = len(rep.violations), len(rep.warnings)
        cls = "fail" if n else ("warn" if w else "ok")
        rows.append(
            [
                f"rules {_e(profile)}",
                f'<span class="badge {cls}">{"FAIL" if n else "pass"}</span> '
                f"{n} violation{'s' * (n != 1)}, {w} warning{'s' * (w != 1)}",
            ]
        )
    a = r.analysis
    if a is not None and a.get("image_score"):
        for cond, f in a["image_score"]["figures"].items():
            rows.append(
                [
                    f"image-true score, {_e(cond)}",
                    f"translation p95 {_num(f.get('translation_p95_mm'), '.3g')} mm, rotation p95 "
                    f"{_num(f.get('rotation_p95_deg'), '.3g')}°, refused {_num(f.get('refused_pct'), '.1f')} %, "
                    f"wrong {_num(f.get('wrong_pct'), '.1f')} %",
                ]
            )
    if a is not None:
        fig = a["figures"]
        rows.append(
            [
                "paper's model",
                f'<span class="badge {"ok" if a.get("passed") else "fail"}">'
                f"{'pass' if a.get('passed') else 'FAIL'}</span> translation p95 "
                f"{_num(fig['translation_mm'].get('p95'), '.3g')} mm, rotation p95 "
                f"{_num(fig['rotation_deg'].get('p95'), '.3g')}°, condition ≤ "
                f"{_num(fig['condition'].get('worst'), '.3g')}",
            ]
        )
    if r.manifest is not None:
        bom = r.manifest["bom"]
        w = bom.get("wires") or {}
        if w.get("pieces"):
            rows.append(
                [
                    "wire",
                    _e(
                        f"{len(w['pieces'])} pieces, {_num(w.get('total_cut_length'), '.1f')} mm "
                        f"of Ø{_num(w.get('diameter'))} mm to cut"
                    ),
                ]
            )
        bd = bom.get("beads") or {}
        if bd.get("count"):
            rows.append(["beads", _e(f"{bd['count']} × Ø{_num(bd.get('diameter'))} mm")])
        rows.append(
            [
                "built",
                _e(
                    f"profile {r.manifest.get('profile', '–')}, {len(r.files)} files"
                    + ("" if r.build_kept else " (temporary build, not kept)")
                ),
            ]
        )
    return _table(["", ""], rows)


def _flatten(d: Any, prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    if isinstance(d, dict):
        for k, v in d.items():
            out += _flatten(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(d, list) and d and all(isinstance(x, dict) for x in d):
        for i, v in enumerate(d):
            out += _flatten(v, f"{prefix}[{i}]")
    else:
        out.append((prefix, d))
    return out


def _parameters(r: ReportInputs) -> str:
    if r.design is None:
        return _missing("No design parameters: this report was made from features.json alone.")
    params = r.design.model_dump(mode="json")
    head = (
        f"<p>Source <code>{_e(r.design_source or '–')}</code>, sha256 "
        f"<code>{_e(r.design_sha256 or '–')}</code>. Lengths mm; angles degrees in keys ending "
        f"<code>_deg</code>; defaults filled in.</p>"
    )
    top = {k: v for k, v in params.items() if not isinstance(v, (dict, list)) or k == "nominal_beam_direction"}
    blocks = [("design", [[f"<code>{_e(k)}</code>", _e(_fmt_value(v))] for k, v in top.items()])]
    lists = ""
    for key, val in params.items():
        if key in top:
            continue
        if isinstance(val, list):  # arrays of tables: one row per item
            if not val:
                continue
            cols = list(dict.fromkeys(c for item in val for c in item))
            rows = [[_e(_fmt_value(item.get(c))) for c in cols] for item in val]
            lists += f"<h3>[[{_e(key)}]]</h3>" + _table([f"<code>{_e(c)}</code>" for c in cols], rows)
        elif isinstance(val, dict):
            blocks.append((key, [[f"<code>{_e(k)}</code>", _e(_fmt_value(v))] for k, v in _flatten(val)]))
    grid = "".join(
        f'<div class="block"><h3>[{_e(name)}]</h3>{_table(["key", "value"], rows)}</div>'
        for name, rows in blocks
        if rows
    )
    return head + lists + f'<div class="grid">{grid}</div>'


def _fmt_value(v: Any) -> str:
    if isinstance(v, float):
        return format(v, ".6g")
    if isinstance(v, list):
        return "[" + ", ".join(_fmt_value(x) for x in v) + "]"
    return "–" if v is None else str(v)


def _features(r: ReportInputs) -> str:
    f = r.features
    rows = []
    for p in f.points:
        rows.append([_e(p.id), "bead", _vec(p.center), f"Ø {p.diameter:g}", _e(p.line or "free")])
    for ln in f.lines:
        rows.append(
            [
                _e(ln.id),
                "line",
                f"{_vec(ln.start)} → {_vec(ln.end)}",
                f"wire Ø {ln.wire_diameter:g}, length {float(((ln.end - ln.start) ** 2).sum() ** 0.5):.3f}",
                "",
            ]
        )
    for el in f.ellipses:
        rows.append(
            [
                _e(el.id),
                "ellipse",
                _vec(el.center),
                f"a {el.semi_major:.4f}, b {el.semi_minor:.4f}, wire Ø {el.wire_diameter:g}",
                f"major {_vec(el.major_axis, '.4f')}, minor {_vec(el.minor_axis, '.4f')}",
            ]
        )
    beam = _vec(f.nominal_beam_direction, ".3f")
    return (
        f"<p>As the pose solver sees them (SPEC §2, frame F, mm; centre-lines and centres of the wires and "
        f"beads as seated). {len(f.points)} beads, {len(f.lines)} lines, {len(f.ellipses)} ellipses; nominal "
        f"beam direction {beam}.</p>"
        + _table(["id", "kind", "centre / segment (mm)", "size (mm)", "on line / axes"], rows)
    )


_VERDICT = {"ok": "ok", "warn": "warn", "fail": "fail", "n/a": "na"}


def _rules(r: ReportInputs) -> str:
    if not r.rules:
        return _missing("No design rules: they need the design (a design file or a build directory).")
    body = (
        "<p>Manufacturability of the design under each profile (<code>ftrac-design check --profile "
        "cnc|fdm</code>): FAIL is a violation (<code>build</code> refuses it without "
        "<code>--force</code>), warn is within the limit but short of the recommended value.</p>"
    )
    for profile, rep in r.rules.items():
        n, w = len(rep.violations), len(rep.warnings)
        cls = "fail" if n else ("warn" if w else "ok")
        verdict = f"{n} violation{'s' * (n != 1)}, {w} warning{'s' * (w != 1)}"
        body += f'<h3>{_e(profile)} <span class="badge {cls}">{_e(verdict)}</span></h3>'
        rows = []
        for x in rep.results:
            meas, lim = x.cells("–")
            v = x.verdict
            rows.append(
                [
                    f"<code>{_e(x.rule)}</code>",
                    _e(meas),
                    _e(lim),
                    f'<span class="badge {_VERDICT.get(v, "na")}">{_e(v.upper() if v == "fail" else v)}</span>',
                    _e(x.where),
                ]
            )
        body += _table(["rule", "measured", "limit", "verdict", "where"], rows, (1,))
    return body


def _score(r: ReportInputs) -> str:
    a = r.analysis
    if a is None:
        return _missing(
            "No analysis: `ftrac-design analyze` writes analysis.json and the pictures; "
            "`report` runs it when the build directory has none."
        )
    s, f = a["settings"], a["figures"]
    cls = "ok" if a.get("passed") else "fail"
    body = _image_score(a.get("image_score"), r.analysis_pictures.get("image_score.png"))
    body += (
        f"<p><b>The paper's model.</b> Predicted 1σ pose errors (Cramér–Rao bound of the solver's "
        f"Jacobian, the paper's uniform segmentation error per feature) over {_num(s.get('poses'))} "
        f"workspace poses within {_num(s.get('cone_deg'))}° of the nominal beam, segmentation error "
        f"{_num(s.get('segmentation_error_mm'))} mm. Verdict "
        f'<span class="badge {cls}">{"pass" if a.get("passed") else "FAIL"}</span></p>'
    )
    rows = [
        [
            "translation (3-D, mm)",
            _num(f["translation_mm"].get("median")),
            _num(f["translation_mm"].get("p95")),
            _num(f["translation_mm"].get("worst")),
        ],
        [
            "rotation (°)",
            _num(f["rotation_deg"].get("median")),
            _num(f["rotation_deg"].get("p95")),
            _num(f["rotation_deg"].get("worst")),
        ],
        ["condition number", _num(f["condition"].get("median")), "–", _num(f["condition"].get("worst"))],
    ]
    body += _table(["figure", "median", "p95", "worst"], rows, (1, 2, 3))
    checks = [
        [
            _e(c["figure"]),
            _num(c.get("value")),
            _e(f"{c['limit']:g} {c.get('unit', '')}"),
            f'<span class="badge {"ok" if c["passed"] else "fail"}">{"ok" if c["passed"] else "FAIL"}</span>',
        ]
        for c in a.get("checks", [])
    ]
    body += _table(["check", "value", "limit", "verdict"], checks, (1,))
    if "score.png" in r.analysis_pictures:
        body += _img(r.analysis_pictures["score.png"], "score plot", "score.png")
    return body


def _image_score(block: dict | None, png: bytes | None) -> str:
    """The image-true score: per condition the p95 errors with intervals and the shares refused
    and wrong, its imaging model, and its picture."""
    if not block:
        return (
            "<p>No image-true score in this analysis (run <code>ftrac-design analyze</code> with "
            "<code>--score-images</code> &gt; 0).</p>"
        )
    m = block["model"]
    body = (
        f"<p><b>Image-true score.</b> {_num(m['images_per_condition'])} workspace poses per condition (seed "
        f"{_num(m['seed'])}) rendered and tracked with the defaults; a pose more than "
        f"{_num(m['wrong_if_beyond']['rotation_deg'])}° or {_num(m['wrong_if_beyond']['translation_mm'])} mm off "
        f"and more than {_num(m['wrong_if_beyond'].get('sigma'))} standard deviations from the truth by its own "
        f"covariance is a confident wrong pose. Clean: {_num(m['clean']['photons_per_px'])} quanta/px, "
        f"{_num(m['clean']['energy_kev'])} keV, "
        f"focal spot {_num(m['clean']['focal_spot_mm'])} mm; anatomy: {_e(m['anatomy']['patient'])}, "
        f"raw counts. p95 over the right poses, 95 % bootstrap interval in brackets.</p>"
    )

    def ci(f, key):
        c = f.get(key)
        return f"{_num(c[0], '.3g')}–{_num(c[1], '.3g')}" if c else "–"

    rows = [
        [
            _e(cond),
            _num(f.get("translation_p95_mm"), ".3g"),
            ci(f, "translation_p95_95ci_mm"),
            _num(f.get("rotation_p95_deg"), ".3g"),
            ci(f, "rotation_p95_95ci_deg"),
            _num(f.get("refused_pct"), ".1f"),
            _num(f.get("wrong_pct"), ".1f"),
        ]
        for cond, f in block["figures"].items()
    ]
    body += _table(
        ["condition", "translation p95 (mm)", "interval", "rotation p95 (°)", "interval", "refused %", "wrong %"],
        rows,
        (1, 2, 3, 4, 5, 6),
    )
    if png:
        body += _img(png, "image-true score plot", "image_score.png")
    return body


def _atlas(r: ReportInputs) -> str:
    a = r.analysis
    if a is None or not a.get("atlas"):
        return _missing("No atlas: `ftrac-design analyze` maps the blind spots over the whole sphere of views.")
    at = a["atlas"]
    rows = []
    for i, w in enumerate(at.get("worst_directions", [])[:5]):
        who = ", ".join(f"{x['id']} {x['reason']}" for x in w.get("responsible", [])) or "no single feature blind"
        rows.append(
            [
                str(i + 1),
                f"{w['lon_deg']:.0f}°, {w['lat_deg']:.0f}°",
                f"{w['angle_from_nominal_deg']:.0f}°",
                _num(w.get("translation_error_mm")),
                _num(w.get("condition")),
                _e(who),
            ]
        )
    body = (
        f"<p>{_num(at.get('directions'))} view directions on a {_num(at.get('sphere_step_deg'))}° grid; "
        f"condition number median {_num(at['condition'].get('median'))}, worst "
        f"{_num(at['condition'].get('worst'))} "
        f"(in the workspace cone {_num(at['condition'].get('worst_in_cone'))}).</p>"
    )
    body += _table(
        ["#", "lon, lat", "from nominal", "translation (mm)", "condition", "features blind there"], rows, (3, 4)
    )
    pics = [
        _img(r.analysis_pictures[n], n, n) for n in ("atlas_sphere.png", "atlas_cone.png") if n in r.analysis_pictures
    ]
    return (
        _image_atlas(a.get("image_atlas"), r.analysis_pictures.get("image_atlas.png"))
        + "<p><b>The paper's model.</b></p>"
        + body
        + (f'<div class="pics">{"".join(pics)}</div>' if pics else "")
    )


def _image_atlas(atlas: dict | None, png: bytes | None) -> str:
    """The image-true atlas: the shares tracked right over the sphere and the workspace cone, the
    worst directions, and its picture."""
    if not atlas:
        return (
            "<p>No image-true atlas in this analysis (run <code>ftrac-design analyze</code> with "
            "<code>--image-atlas-step-deg</code> &gt; 0).</p>"
        )
    s = atlas["settings"]
    body = (
        f"<p><b>Image-true atlas.</b> Each direction of a {_num(s['step_deg'])}° grid imaged clean at "
        f"{_num(s['rolls'])} rolls and tracked: right from "
        f"{_num(100 * atlas['right_share_sphere'], '.0f')} % of the sphere of view directions"
        + (
            f", {_num(100 * atlas['right_share_cone'], '.0f')} % of the workspace cone"
            if atlas.get("right_share_cone") is not None
            else ""
        )
        + ".</p>"
    )
    rows = [
        [
            str(i + 1),
            f"{w['lon_deg']:.0f}°, {w['lat_deg']:.0f}°",
            f"{w['angle_from_nominal_deg']:.0f}°",
            f"{100 * w['right_share']:.0f} %",
        ]
        for i, w in enumerate(atlas.get("worst", []))
    ]
    body += _table(["#", "lon, lat", "from nominal", "tracked right"], rows, (3,))
    if png:
        body += _img(png, "image-true atlas", "image_atlas.png")
    return body


def _bom(r: ReportInputs) -> str:
    if r.manifest is None:
        return _missing("No bill of materials: `ftrac-design build` writes it into manifest.json.")
    b = r.manifest["bom"]
    body = f"<p>Profile <b>{_e(b.get('profile', r.manifest.get('profile', '')))}</b>.</p><h3>Stock</h3>"
    rows = []
    for s in b.get("stock", []):
        size = (
            f"Ø {s['diameter']:g} × {s['length']:g}"
            if "diameter" in s
            else " × ".join(f"{x:g}" for x in s.get("size", []))
        )
        fin = s.get("finished")
        fin = (
            f"Ø {fin['diameter']:g} × {fin['length']:g}"
            if isinstance(fin, dict)
            else " × ".join(f"{x:g}" for x in (fin or []))
        )
        rows.append([_e(s.get("part")), _e(s.get("form")), _e(s.get("material")), _e(size), _e(fin)])
    body += _table(["part", "form", "material", "stock (mm)", "finished (mm)"], rows)
    items = []
    bd = b.get("beads") or {}
    if bd.get("count"):
        items.append([str(bd["count"]), _e(f"ball Ø {bd.get('diameter', 0):g} mm"), _e(bd.get("material", "")), ""])
    w = b.get("wires") or {}
    if w.get("pieces"):
        items.append(
            [
                str(len(w["pieces"])),
                _e(f"wire Ø {w.get('diameter', 0):g} mm pieces"),
                _e(w.get("material", "")),
                _e(f"{_num(w.get('total_cut_length'))} mm to cut (see the cut list)"),
            ]
        )
    for s in b.get("screws", []):
        items.append([str(s.get("qty", "")), _e(s.get("item", "")), "", _e(s.get("use", ""))])
    for p in b.get("dowel_pins", []):
        items.append(
            [
                str(p.get("qty", "")),
                _e(p.get("item", "")),
                "",
                _e(f"{p.get('use', '')}; grid nodes {p.get('grid_nodes', '')}"),
            ]
        )
    body += "<h3>Bought parts</h3>" + _table(["qty", "item", "material", "use"], items, (0,))
    return body


def _cut_list(r: ReportInputs) -> str:
    if r.manifest is None:
        return _missing("No cut list: `ftrac-design build` writes it into manifest.json.")
    w = r.manifest["bom"].get("wires") or {}
    if not w.get("pieces"):
        return _missing("This design has no wires.")
    rows = [
        [
            _e(p.get("feature")),
            _e(p.get("piece")),
            _e(p.get("shape")),
            _num(p.get("length"), ".2f"),
            _num(p.get("cut_length"), ".1f"),
        ]
        for p in w["pieces"]
    ]
    rows.append(["", "<b>total</b>", "", "", f"<b>{_num(w.get('total_cut_length'), '.1f')}</b>"])
    return (
        f"<p>Wire Ø {_num(w.get('diameter'))} mm, {_e(w.get('material', ''))}; each piece cut "
        f"{_num(w.get('cut_allowance'))} mm over its seated length.</p>"
        + _table(["feature", "piece", "shape", "seated length (mm)", "cut length (mm)"], rows, (3, 4))
    )


def _files(r: ReportInputs) -> str:
    if not r.files:
        return _missing("No output files: `ftrac-design build` writes them (and their sha256 into manifest.json).")
    note = (
        ""
        if r.build_kept
        else '<p class="note">Built in a temporary directory that was not kept; run '
        "<code>ftrac-design build</code> for the files (same hashes for the same design and versions "
        "except where a file records its time).</p>"
    )
    where = f"<p>Build directory <code>{_e(r.build_dir)}</code>.</p>" if r.build_kept else ""
    rows = [
        [
            f"<code>{_e(x.name)}</code>",
            f"{x.bytes:,d}",
            f'<span class="mono">{_e(x.sha256)}</span>',
            f'<span class="badge {"ok" if x.status == "ok" else ("na" if x.status == "not kept" else "fail")}">'
            f"{_e(x.status)}</span>",
        ]
        for x in r.files
    ]
    return where + note + _table(["file", "bytes", "sha256 (manifest)", "on disk"], rows, (1,))


def _versions(r: ReportInputs) -> str:
    rows = [[_e(k), f"<code>{_e(v)}</code>"] for k, v in r.versions.items()]
    return _table(["component", "version"], rows)


#: sections drawn from analysis.json (the others that read files read manifest.json)
_FROM_ANALYSIS = ("Score", "Blind-spot atlas")


def _guarded(title: str, fn, r: ReportInputs) -> str:
    """A section's HTML; a manifest or analysis.json that lacks what ``build`` / ``analyze``
    write (hand-edited, truncated) is bad input: InputError naming the file and the section."""
    try:
        return fn(r)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
        if title in _FROM_ANALYSIS and r.analysis_dir is not None:
            src, cmd = r.analysis_dir / "analysis.json", "analyze"
        else:
            src, cmd = (r.build_dir / "manifest.json" if r.build_dir is not None else None), "build"
        raise InputError(src, f"({title})", f"what `ftrac-design {cmd}` writes ({type(exc).__name__}: {exc})") from None


def render_html(r: ReportInputs, generated: _dt.datetime | None = None) -> str:
    """The whole page as a string."""
    generated = generated or _dt.datetime.now(_dt.timezone.utc)
    desc = getattr(r.design, "description", "") if r.design is not None else ""
    profile = r.manifest.get("profile") if r.manifest else None
    profile = profile if isinstance(profile, str) else None
    sub = [
        f"<p>{_e(desc)}</p>" if desc else "",
        f"<p>design <code>{_e(r.design_source or '–')}</code>"
        + (f" · built with profile <b>{_e(profile)}</b>" if profile else " · not built")
        + f" · report generated {_e(generated.strftime('%Y-%m-%d %H:%M UTC'))}</p>",
    ]
    nav = "".join(f'<a href="#{t.lower().replace(" ", "-")}">{_e(t)}</a>' for t in SECTIONS)
    makers = [_render, _parameters, _features, _rules, _score, _atlas, _bom, _cut_list, _files, _versions]
    sections = "\n".join(_section(t, _guarded(t, fn, r)) for t, fn in zip(SECTIONS, makers))
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>FTRAC design report: {_e(r.name)}</title><style>{_CSS}</style></head>\n"
        f"<body><header><h1>FTRAC design report: {_e(r.name)}</h1>{''.join(sub)}</header>"
        f"<nav>{nav}</nav>\n<main>\n{sections}\n</main></body></html>\n"
    )


def write_report(r: ReportInputs, path: str | Path) -> Path:
    """Write the page to ``path`` atomically (temporary name, then rename)."""
    return write_text_atomic(path, render_html(r))
