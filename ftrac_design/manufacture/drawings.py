"""Dimensioned shop drawings of the body, the mount and the connector (SVG and PDF).

One A3 landscape sheet per part, drawn with matplotlib (Agg) from the views of the CAD solids
and the dimension sets of :mod:`ftrac_design.manufacture.dimensions`:

- orthographic views and a section by hidden-line removal and plane cuts of the solid (a
  :class:`~ftrac_design.manufacture.views.PartViews`, which
  :class:`ftrac_design.cad.views.SolidViews` computes from the solid: exact for the mount and
  the connector, on a fine mesh for the body, whose swept grooves make the exact algorithm
  ~20x slower; :func:`ftrac_design.cad.drawings.write_drawings` builds them), at a true scale from
  the ISO 5455 series printed in the title block (on the PDF and the SVG, 1 mm of paper is
  1 mm);
- for the body, the outer surface unrolled (x = arc length R·A on the outer surface, y = z)
  with every groove's edges and every pocket, and a feature table with the azimuth A (°)
  and axial position z (mm) of every feature, groove width and depth, pocket Ø and depth,
  each with the profile's tolerance;
- datums A (the axis), B (the end face the part seats on) and C (the azimuth reference),
  fit-critical values marked ◆;
- a title block: design name, sha256 of the design file, material, profile, units, scale
  and date.

Every printed number is a text element whose SVG group id names it (``dim.<part>.<key>``
for dimensions, ``tol.*`` for the tolerance notes, ``tb.*`` for the title block), and SVG
text is kept as text (``svg.fonttype = none``), so a test can read every value back.
Nothing here imports CadQuery.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..design.schema import Design
from ..features.model import Features
from .dimensions import (
    CRITICAL_MARK,
    Dim,
    body_dimensions,
    connector_dimensions,
    datum_c,
    mount_dimensions,
)
from .plan import BodyPlan
from .profiles import DrawingTolerances, Profile, cut_sizes, drawing_tolerances
from .unwrap import unwrap_features
from .views import PartViews, ViewFrame

#: the parts that get a drawing, in sheet order
PARTS = ("body", "mount", "connector")
#: files :func:`ftrac_design.cad.drawings.write_drawings` writes
DRAWING_FILES = tuple(f"drawing_{p}.{ext}" for p in PARTS for ext in ("svg", "pdf"))

#: A3 landscape, mm
SHEET = (420.0, 297.0)
MARGIN = 10.0
#: ISO 5455 scales, largest first (enlargement, full size, reduction)
SCALES = (10.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.1)
FONT_PT = 6.0
ROW_MM = 3.6
#: top of the notes block, above the title block (mm of paper)
NOTES_TOP = MARGIN + 36 + 38
VIS_LW, HID_LW = 0.45, 0.25


def scale_text(s: float) -> str:
    """``5:1``, ``1:1``, ``1:2`` …"""
    return f"{int(round(s))}:1" if s >= 1 else f"1:{int(round(1 / s))}"


def pick_scale(width: float, height: float, box_w: float, box_h: float) -> float:
    """The largest ISO 5455 scale at which ``width × height`` (mm) fits ``box_w × box_h`` (mm of paper)."""
    for s in SCALES:
        if width * s <= box_w and height * s <= box_h:
            return s
    return SCALES[-1]


@dataclass(frozen=True)
class TitleBlock:
    """What the title block says."""

    design: str
    sha256: str
    part: str
    material: str
    profile: Profile
    scale: str
    date: str
    units: str = "mm"

    def of_part(self, part: str, material: str, profile: Profile, scale: str) -> "TitleBlock":
        """This design's title block (its name, sha256 and date) for one part's sheet.

        Parameters
        ----------
        part : str
            The part and its file (``"body (fiducial.step)"``).
        material : str
            The part's material.
        profile : {"cnc", "fdm"}
            The manufacturing profile.
        scale : str
            The sheet's scale as written (:func:`scale_text`).

        Returns
        -------
        TitleBlock
            The part's title block, in mm.
        """
        return TitleBlock(self.design, self.sha256, part, material, profile, scale, self.date)


# ---- drawing primitives ------------------------------------------------------------------


class Sheet:
    """One A3 sheet: a paper axes in mm and view axes placed on it at a true scale."""

    def __init__(self, title: str):
        from matplotlib.figure import Figure

        # a bare Figure (no pyplot): no global backend or figure registry is touched
        self.title = title
        self.fig = Figure(figsize=(SHEET[0] / 25.4, SHEET[1] / 25.4))
        self.paper = self.fig.add_axes((0, 0, 1, 1))
        self.paper.set_xlim(0, SHEET[0])
        self.paper.set_ylim(0, SHEET[1])
        self.paper.axis("off")
        W, H = SHEET
        self.paper.add_patch(self._rect(MARGIN, MARGIN, W - 2 * MARGIN, H - 2 * MARGIN, lw=0.7))

    @staticmethod
    def _rect(x, y, w, h, lw=0.4, **kw):
        from matplotlib.patches import Rectangle

        return Rectangle((x, y), w, h, fill=False, lw=lw, **kw)

    def view(self, x: float, y: float, bounds: tuple[float, float, float, float], scale: float, pad: float = 0.0):
        """An axes whose data mm appear at ``scale`` on paper, lower-left corner at (x, y) mm."""
        x0, x1, y0, y1 = bounds
        p = pad / scale
        w, h = (x1 - x0 + 2 * p) * scale, (y1 - y0 + 2 * p) * scale
        ax = self.fig.add_axes((x / SHEET[0], y / SHEET[1], w / SHEET[0], h / SHEET[1]))
        ax.set_xlim(x0 - p, x1 + p)
        ax.set_ylim(y0 - p, y1 + p)
        ax.axis("off")
        ax.set_aspect("equal", adjustable="box")
        return ax

    @staticmethod
    def text(ax, x, y, s, gid=None, size=FONT_PT, **kw):
        """Text ``s`` at (x, y) of ``ax``, its SVG group id ``gid`` (so a test can read it back)."""
        t = ax.text(x, y, s, fontsize=size, **kw)
        if gid:
            t.set_gid(gid)
        return t

    def save(self, svg: Path, pdf: Path, png: Path | None = None, dpi: int = 150) -> None:
        """Write the sheet as SVG and PDF (and PNG when asked)."""
        self.fig.savefig(svg, format="svg", metadata={"Date": None, "Title": self.title})
        self.fig.savefig(pdf, format="pdf", metadata={"CreationDate": None, "ModDate": None, "Title": self.title})
        if png is not None:
            self.fig.savefig(png, format="png", dpi=dpi)


def draw_projection(ax, proj) -> None:
    """Draw a projection's hidden edges (thin, dashed, grey) and then its visible ones."""
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(list(proj.hidden), colors="0.55", linewidths=HID_LW, linestyles=(0, (2, 1.5))))
    ax.add_collection(LineCollection(list(proj.visible), colors="k", linewidths=VIS_LW))


def draw_section(ax, sec) -> None:
    """Draw a section's faces, hatched, each with its holes."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MPath

    for outer, inner in sec.faces:
        verts, codes = [], []
        for loop in (outer, *inner):
            verts += [tuple(p) for p in loop]
            codes += [MPath.MOVETO] + [MPath.LINETO] * (len(loop) - 2) + [MPath.CLOSEPOLY]
        ax.add_patch(PathPatch(MPath(verts, codes), facecolor="none", edgecolor="k", lw=VIS_LW, hatch="////"))


def dim_line(ax, a, b, offset, dim: Dim, part: str, text_side: float = 1.0) -> None:
    """A dimension line between points ``a`` and ``b`` (view mm), moved by ``offset`` (view mm)
    with extension lines, arrows and the value in the middle."""
    a, b, off = np.asarray(a, float), np.asarray(b, float), np.asarray(offset, float)
    a2, b2 = a + off, b + off
    n = off / (np.linalg.norm(off) or 1.0)
    for p, q in ((a, a2), (b, b2)):
        ax.plot(*zip(p + 0.1 * n, q + 0.3 * n), color="k", lw=0.25)
    ax.annotate(
        "",
        xy=tuple(b2),
        xytext=tuple(a2),
        arrowprops={"arrowstyle": "<|-|>", "lw": 0.35, "color": "k", "mutation_scale": 5, "shrinkA": 0, "shrinkB": 0},
    )
    d = b2 - a2
    angle = math.degrees(math.atan2(d[1], d[0]))
    if angle > 90 or angle <= -90:
        angle += 180
    mid = (a2 + b2) / 2
    t = Sheet.text(
        ax,
        *mid,
        dim.text(),
        gid=f"dim.{part}.{dim.key}",
        rotation=angle,
        ha="center",
        va="bottom" if text_side > 0 else "top",
        rotation_mode="anchor",
    )
    if dim.critical:
        t.set_bbox({"boxstyle": "square,pad=0.15", "fc": "white", "ec": "k", "lw": 0.3})


def datum_flag(ax, xy, letter: str, dx: float = 0.0, dy: float = 0.0, gid: str | None = None) -> None:
    """A datum feature symbol: the letter boxed, a leader to a filled triangle on the feature."""
    x, y = xy
    ax.plot([x, x + dx], [y, y + dy], color="k", lw=0.3)
    ax.plot([x], [y], marker="v" if dy > 0 else "^" if dy < 0 else ">" if dx < 0 else "<", color="k", markersize=3)
    Sheet.text(
        ax,
        x + dx,
        y + dy,
        letter,
        gid=gid or f"datum.{letter}",
        size=7,
        ha="center",
        va="center",
        weight="bold",
        bbox={"boxstyle": "square,pad=0.25", "fc": "white", "ec": "k", "lw": 0.4},
    )


def table(
    sheet: Sheet,
    x: float,
    y_top: float,
    widths: list[float],
    header: list[str],
    rows: list[list[Dim | str | None]],
    part: str,
) -> float:
    """A table drawn on the paper (mm); a Dim cell prints its text under its own id.
    Returns the y of the table's bottom edge."""
    ax = sheet.paper
    xs = np.concatenate([[x], x + np.cumsum(widths)])
    y = y_top
    for r, cells in enumerate([header, *rows]):
        y -= ROW_MM
        ax.plot([xs[0], xs[-1]], [y, y], color="k", lw=0.25 if r else 0.5)
        for k, cell in enumerate(cells):
            if cell is None or cell == "":
                continue
            cx, cy = xs[k] + 1.0, y + 1.0
            if isinstance(cell, Dim):
                t = sheet.text(ax, cx, cy, cell.text(), gid=f"dim.{part}.{cell.key}")
                if cell.critical:
                    t.set_fontweight("bold")
            else:
                sheet.text(ax, cx, cy, str(cell), weight="bold" if r == 0 else "normal")
    for xv in xs:
        ax.plot([xv, xv], [y, y_top], color="k", lw=0.25)
    ax.plot([xs[0], xs[-1]], [y_top, y_top], color="k", lw=0.5)
    return y


def title_block(sheet: Sheet, tb: TitleBlock) -> None:
    """The title block in the lower right corner (180 × 36 mm)."""
    ax = sheet.paper
    x0, y0, w = SHEET[0] - MARGIN - 180, MARGIN, 180.0
    rows = [
        ("design", tb.design, "tb.design"),
        ("part", tb.part, "tb.part"),
        ("design file sha256", tb.sha256, "tb.sha256"),
        ("material", tb.material, "tb.material"),
        ("profile", tb.profile, "tb.profile"),
        ("units", tb.units, "tb.units"),
        ("scale", tb.scale, "tb.scale"),
        ("date", tb.date, "tb.date"),
    ]
    h = 4.5
    ax.add_patch(sheet._rect(x0, y0, w, h * len(rows), lw=0.7))
    for k, (label, value, gid) in enumerate(rows):
        y = y0 + h * (len(rows) - 1 - k)
        ax.plot([x0, x0 + w], [y, y], color="k", lw=0.25)
        sheet.text(ax, x0 + 1.5, y + 1.3, label, size=5.5, color="0.3")
        sheet.text(
            ax,
            x0 + 30,
            y + 1.3,
            value,
            gid=gid,
            size=5.5 if label.endswith("sha256") else 7,
            family="monospace" if label.endswith("sha256") else None,
        )
    ax.plot([x0 + 28, x0 + 28], [y0, y0 + h * len(rows)], color="k", lw=0.25)


def notes(
    sheet: Sheet, x: float, y_top: float, tol: DrawingTolerances, lines: list[str], angle_radius: float | None = None
) -> float:
    """The general notes: tolerances (each under its own id), the ◆ legend, then ``lines``."""
    ax = sheet.paper
    y = y_top - ROW_MM
    sheet.text(ax, x, y, "NOTES", weight="bold")
    rows = [
        ("tolerance unless stated (mm)", f"±{tol.general:.3f}", "tol.general"),
        (f"fit-critical {CRITICAL_MARK} and feature positions (mm)", f"±{tol.critical:.3f}", "tol.critical"),
    ]
    if angle_radius is not None:
        rows.append(
            (
                "azimuths A: the critical tolerance as an arc on the outer Ø",
                f"±{tol.angle_deg(angle_radius):.2f}°",
                "tol.angle",
            )
        )
    for label, value, gid in rows:
        y -= ROW_MM
        sheet.text(ax, x, y, label)
        sheet.text(ax, x + 80, y, value, gid=gid)
    for s in [f"{CRITICAL_MARK} fit-critical (press or sliding fit): inspect every part", *lines]:
        y -= ROW_MM
        sheet.text(ax, x, y, s)
    return y


def _today() -> str:
    return _dt.datetime.now(_dt.timezone.utc).date().isoformat()


# ---- the three sheets --------------------------------------------------------------------


def _dims(dims: list[Dim]) -> dict[str, Dim]:
    return {d.key: d for d in dims}


@dataclass(frozen=True)
class _BodyLayout:
    """Where the body sheet's views go: the scales and the room the feature table leaves."""

    s: float  # front view and section
    s_end: float  # end view
    s_u: float  # unrolled surface
    end_room: float  # height between the feature table and the notes, mm of paper

    @classmethod
    def of(cls, plan: BodyPlan, table_rows: int) -> "_BodyLayout":
        R, L2 = plan.outer_radius, plan.half_length
        table_bottom = 287 - ROW_MM * (table_rows + 1)
        end_room = table_bottom - 92  # between the feature table and the notes
        s = next((k for k in SCALES if 2 * (2 * R * k + 24) + 10 <= 210 and 2 * L2 * k + 30 <= 137), SCALES[-1])
        s_end = next((k for k in SCALES if k <= s and 2 * R * k + 24 <= min(end_room, 176)), SCALES[-1])
        return cls(s, s_end, pick_scale(2 * math.pi * R, 2 * L2, 195, 105), end_room)

    def scale_text(self) -> str:
        scales = f"views {scale_text(self.s)}" + (
            f", end view {scale_text(self.s_end)}" if self.s_end != self.s else ""
        )
        return f"{scales}, unrolled {scale_text(self.s_u)}"


def body_sheet(
    design: Design,
    features: Features,
    plan: BodyPlan,
    views: PartViews,
    profile: Profile,
    tb: TitleBlock,
    key_slot: tuple[float, float] | None = None,
) -> Sheet:
    """The body's sheet: front view, section through datum C, end view on B, unrolled surface
    and the feature table.

    Parameters
    ----------
    design, features, plan : Design, Features, BodyPlan
        The design, its features and the body's cut plan (frame F).
    views : PartViews
        The finished body's projections and sections.
    profile, tb
        As :func:`mount_sheet`.
    key_slot : (width, depth) or None
        The slot across face B for the mount's key, mm.

    Returns
    -------
    Sheet
        The drawn sheet.
    """
    tol = drawing_tolerances(profile)
    D = _dims(body_dimensions(design, features, plan, tol, key_slot))
    what_c, a_c = datum_c(design, features)
    rows = _feature_rows(plan, D)
    lay = _BodyLayout.of(plan, len(rows))
    sheet = Sheet(f"{design.name} — body")
    tb = tb.of_part("body (fiducial.step)", design.body.material, profile, lay.scale_text())
    _body_front_and_section(sheet, plan, views, lay.s, D, a_c)
    _body_end_view(sheet, plan, views, lay, a_c)
    # unrolled outer surface: x = R·A (rad), y = z
    _unrolled(sheet, design, features, plan, profile, lay.s_u, D, a_c)
    x_t = SHEET[0] - MARGIN - 180
    table(
        sheet,
        x_t,
        287,
        [20, 38, 38, 42, 42],
        ["feature", "A (°)", "z (mm)", "width / Ø (mm)", "depth (mm)"],
        rows,
        "body",
    )
    notes(
        sheet,
        x_t,
        NOTES_TOP,
        tol,
        [
            f"datum A: the axis (outer Ø); B: the end face at z = −L/2 (seats in the mount); C: {what_c}",
            "A about +z from +x toward +y (4-axis A axis); z from mid-length; depth radially from the outer Ø",
            "groove width normal to the wire; ellipse grooves planar through their top and bottom points",
        ],
        angle_radius=plan.outer_radius,
    )
    title_block(sheet, tb)
    return sheet


def _body_front_and_section(
    sheet: Sheet, plan: BodyPlan, views: PartViews, s: float, D: dict[str, Dim], a_c: float
) -> None:
    """The front view from −y (x right, z up) and, beside it, the section through datums A and C."""
    R, L2 = plan.outer_radius, plan.half_length
    front = views.project(ViewFrame("front", (1, 0, 0), (0, -1, 0)))
    y0 = 287 - 6 - 2 * L2 * s - 24
    ax = sheet.view(20, y0, (-R, R, -L2, L2), s, pad=12)
    draw_projection(ax, front)
    sheet.text(ax, 0, -L2 - 9 / s, "FRONT (from −y)", ha="center", size=6.5, weight="bold")
    dim_line(ax, (-R, -L2), (-R, L2), (-6 / s, 0), D["body.length"], "body")
    dim_line(ax, (-R, L2), (R, L2), (0, 5 / s), D["body.outer_diameter"], "body")
    datum_flag(ax, (R, L2 + 5 / s), "A", dx=7 / s, dy=0)
    datum_flag(ax, (R * 0.5, -L2), "B", dy=-5 / s)
    # section through the axis and datum C (the cut plane contains z and the direction of A_c)
    c = math.radians(a_c)
    cut = ViewFrame("section", (math.cos(c), math.sin(c), 0.0), (math.sin(c), -math.cos(c), 0.0))
    x1 = 20 + 2 * R * s + 24 + 20
    ax = sheet.view(x1, y0, (-R, R, -L2, L2), s, pad=12)
    draw_section(ax, views.section(cut))
    sheet.text(ax, 0, -L2 - 9 / s, "SECTION C–C (plane through datums A and C)", ha="center", size=6.5, weight="bold")
    if "body.bore_diameter" in D:
        dim_line(ax, (-plan.bore_radius, 0), (plan.bore_radius, 0), (0, 0), D["body.bore_diameter"], "body")


def _body_end_view(sheet: Sheet, plan: BodyPlan, views: PartViews, lay: _BodyLayout, a_c: float) -> None:
    """The end view from −z (the B face), in the right column under the feature table."""
    R, s_end = plan.outer_radius, lay.s_end
    end = views.project(ViewFrame("end", (1, 0, 0), (0, 0, -1)))
    size = 2 * R * s_end + 24
    x2 = SHEET[0] - MARGIN - 90 - size / 2
    ax = sheet.view(x2, 88 + max(0.0, (lay.end_room - size) / 2), (-R, R, -R, R), s_end, pad=12)
    draw_projection(ax, end)
    sheet.text(ax, 0, -R - 9 / s_end, "END (from −z, face B)", ha="center", size=6.5, weight="bold")
    # seen from -z the view's y is -y of F: azimuth c points along (cos c, -sin c)
    c = math.radians(a_c)
    u = np.array([math.cos(c), -math.sin(c)])
    ax.plot([0, (R + 4 / s_end) * u[0]], [0, (R + 4 / s_end) * u[1]], color="k", lw=0.3, ls=(0, (6, 2, 1, 2)))
    datum_flag(ax, tuple(R * u), "C", dx=5 / s_end * u[0], dy=5 / s_end * u[1])


def _feature_rows(plan: BodyPlan, D: dict[str, Dim]) -> list[list[Dim | str | None]]:
    """The feature table: two rows per groove (its ends or extremes), one per pocket, datum C."""
    rows: list[list[Dim | str | None]] = []
    for e in plan.ellipse_grooves:
        i = e.feature.id
        rows.append([f"{i} top", D[f"{i}.top.A"], D[f"{i}.top.z"], D[f"{i}.width"], D[f"{i}.depth"]])
        rows.append([f"{i} bottom", D[f"{i}.bottom.A"], D[f"{i}.bottom.z"], None, None])
    for g in plan.line_grooves:
        i = g.feature.id
        rows.append([f"{i} start", D[f"{i}.A"], D[f"{i}.start.z"], D[f"{i}.width"], D[f"{i}.depth"]])
        rows.append([f"{i} end", None, D[f"{i}.end.z"], None, None])
    for p in plan.pockets:
        i = p.feature.id
        rows.append([f"{i} pocket", D[f"{i}.A"], D[f"{i}.z"], D[f"{i}.diameter"], D[f"{i}.depth"]])
    if "key_slot.width" in D:  # across face B, centred on datum C; depth from B
        rows.append(["key slot", None, None, D["key_slot.width"], D["key_slot.depth"]])
    rows.append(["datum C", D["datum_C.A"], None, None, None])
    return rows


def _unrolled(
    sheet: Sheet,
    design: Design,
    features: Features,
    plan: BodyPlan,
    profile: Profile,
    s_u: float,
    D: dict[str, Dim],
    a_c: float,
) -> None:
    from matplotlib.patches import Circle

    R, L2 = plan.outer_radius, plan.half_length
    W = 2 * math.pi * R
    ax = sheet.fig.add_axes((22 / SHEET[0], 24 / SHEET[1], W * s_u / SHEET[0], 2 * L2 * s_u / SHEET[1]))
    ax.set_xlim(0, W)
    ax.set_ylim(-L2, L2)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xticks([R * math.radians(a) for a in range(0, 361, 30)])
    ax.set_xticklabels([f"{a}°" for a in range(0, 361, 30)], fontsize=5.5)
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(nbins=8, integer=True))
    ax.tick_params(labelsize=5.5, length=2, width=0.3)
    for sp in ax.spines.values():
        sp.set_linewidth(0.6)
    ax.set_xlabel("A (°) about +z from +x, seen from outside; x = R·A on the outer surface", fontsize=6)
    ax.set_ylabel("z (mm)", fontsize=6)
    ax.set_title(f"OUTER SURFACE UNROLLED ({scale_text(s_u)} in arc length)", fontsize=6.5, weight="bold", loc="left")
    sock = design.mount.socket_depth
    ax.axhspan(-L2, -L2 + sock, color="0.9", lw=0)
    ax.text(W - 1, -L2 + sock / 2, "held in the mount's socket", fontsize=5, ha="right", va="center", color="0.4")
    ax.axvline(R * math.radians(a_c), color="k", lw=0.3, ls=(0, (6, 2, 1, 2)))
    datum_flag(ax, (R * math.radians(a_c), L2), "C", dy=3.5 / s_u, gid="datum.C.unrolled")
    for p in unwrap_features(features, R, cut_sizes(design, profile)):
        x = R * np.radians(p.theta_deg)
        if p.kind == "pocket":
            ax.add_patch(Circle((x[0], p.z[0]), p.cut_width / 2, fill=False, lw=0.45, color="tab:blue"))
            ax.text(x[0] + p.cut_width * 0.7, p.z[0], p.feature, fontsize=5, va="center", color="tab:blue")
            continue
        ax.plot(x, p.z, color="tab:red", lw=0.3, ls=(0, (4, 2)))
        if p.kind == "line":
            for side in (-1, 1):
                ax.plot(x + side * p.cut_width / 2, p.z, color="k", lw=0.35)
            ax.text(x[0] - p.cut_width, p.z[1], p.feature, fontsize=5.5, ha="right", va="top")
        else:
            t = np.gradient(np.column_stack([x, p.z]), axis=0)
            t /= np.linalg.norm(t, axis=1, keepdims=True)
            for side in (-1, 1):
                half = side * p.cut_width / 2
                ax.plot(x - half * t[:, 1], p.z + half * t[:, 0], color="k", lw=0.35)
            k = int(np.argmax(p.z))
            ax.text(x[k], p.z[k] + 0.8 / s_u * 2, p.feature, fontsize=5.5, ha="center", va="bottom")


def mount_sheet(design: Design, mount_part, views: PartViews, profile: Profile, tb: TitleBlock) -> Sheet:
    """The mount's sheet: top, front and side views, section through the socket, hole table.

    Parameters
    ----------
    design : Design
        The design the mount holds.
    mount_part : ftrac_design.cad.mount.MountPart
        The mount's layout (frame M) and cut sizes.
    views : PartViews
        The mount solid's projections and sections (exact hidden-line removal).
    profile : {"cnc", "fdm"}
        The manufacturing profile (tolerances).
    tb : TitleBlock
        The title block's design name, sha256 and date.

    Returns
    -------
    Sheet
        The drawn sheet.
    """
    tol = drawing_tolerances(profile)
    D = _dims(mount_dimensions(mount_part, tol))
    m = mount_part.layout
    s = next(
        (k for k in SCALES if 2 * (m.width * k + 24) + 20 <= 210 and (m.width + m.height) * k + 80 <= 270), SCALES[-1]
    )
    sheet = Sheet(f"{design.name} — mount")
    tb = tb.of_part("mount (mount.step, frame M)", design.mount.material, profile, scale_text(s))
    _mount_views(sheet, mount_part, views, s, D)
    _mount_tables(sheet, m, tol, D)
    title_block(sheet, tb)
    return sheet


def _mount_views(sheet: Sheet, mount_part, views: PartViews, s: float, D: dict[str, Dim]) -> None:
    """The mount's front, top, section and side views with their dimensions and datums."""
    m = mount_part.layout
    h2 = m.width / 2
    zlo, zhi = -m.base_height, m.socket_depth
    gap = 26
    yb = 287 - 12 - (m.height + m.width) * s - 2 * gap
    # front (from -y): x right, z up
    ax = sheet.view(20, yb, (-h2, h2, zlo, zhi), s, pad=12)
    draw_projection(ax, views.project(ViewFrame("front", (1, 0, 0), (0, -1, 0))))
    sheet.text(ax, 0, zlo - 9 / s, "FRONT (from −y)", ha="center", size=6.5, weight="bold")
    dim_line(ax, (h2, zlo), (h2, zhi), (6 / s, 0), D["block.height"], "mount")
    datum_flag(ax, (0, 0), "B", dx=-h2 - 8 / s, dy=0)
    # top (from +z): x right, y up; above the front view
    ax = sheet.view(20, yb + m.height * s + gap, (-h2, h2, -h2, h2), s, pad=12)
    draw_projection(ax, views.project(ViewFrame("top", (1, 0, 0), (0, 0, 1))))
    sheet.text(ax, 0, -h2 - 9 / s, "TOP (from +z)", ha="center", size=6.5, weight="bold")
    dim_line(ax, (-h2, h2), (h2, h2), (0, 5 / s), D["block.width"], "mount")
    if m.key.height > 0:  # datum C: the key, flagged at its end on the socket's rim
        kd = m.key.direction[:2] * mount_part.socket_diameter / 2
        datum_flag(ax, tuple(kd), "C", dx=float(kd[0]) * 0.3, dy=float(kd[1]) * 0.3 + 4 / s)
    else:  # datum C: the block's +x face
        datum_flag(ax, (h2, h2 / 2), "C", dx=6 / s)
    ax.annotate(
        D["block.chamfer"].text() + " × 45°",
        xy=(h2 - m.chamfer / 2, -h2 + m.chamfer / 2),
        xytext=(h2 + 2 / s, -h2 - 6 / s),
        fontsize=FONT_PT,
        arrowprops={"arrowstyle": "-", "lw": 0.3},
        gid="dim.mount.block.chamfer",
    )
    # section through the socket axis, plane y = 0, seen from -y
    x_sec = 20 + m.width * s + 24 + 20
    ax = sheet.view(x_sec, yb, (-h2, h2, zlo, zhi), s, pad=12)
    draw_section(ax, views.section(ViewFrame("section", (1, 0, 0), (0, -1, 0))))
    sheet.text(ax, 0, zlo - 9 / s, "SECTION A–A (plane y = 0 through datum A)", ha="center", size=6.5, weight="bold")
    r = mount_part.socket_diameter / 2
    dim_line(ax, (-r, zhi), (r, zhi), (0, 5 / s), D["socket.diameter"], "mount")
    dim_line(ax, (h2, 0), (h2, zhi), (5 / s, 0), D["socket.depth"], "mount")
    dim_line(ax, (-h2, zlo), (-h2, 0), (-5 / s, 0), D["block.base"], "mount")
    datum_flag(ax, (-r, zhi), "A", dx=-h2 + r - 4 / s, dy=3 / s)
    # side (from +x): y right, z up
    ax = sheet.view(x_sec, yb + m.height * s + gap, (-h2, h2, zlo, zhi), s, pad=12)
    draw_projection(ax, views.project(ViewFrame("side", (0, 1, 0), (1, 0, 0))))
    sheet.text(ax, 0, zlo - 9 / s, "SIDE (from +x)", ha="center", size=6.5, weight="bold")


def _mount_tables(sheet: Sheet, m, tol: DrawingTolerances, D: dict[str, Dim]) -> None:
    """The mount's hole table, its key and the notes."""
    rows: list[list[Dim | str | None]] = []
    for h in m.holes:
        u, v = [k for k in range(3) if k != h.axis]
        rows.append(
            [
                h.name,
                "xyz"[h.axis],
                D[f"{h.name}.{'xyz'[u]}"],
                D[f"{h.name}.{'xyz'[v]}"],
                D[f"{h.name}.diameter"],
                D.get(f"{h.name}.cbore_diameter"),
                D.get(f"{h.name}.cbore_depth"),
            ]
        )
    x_t = SHEET[0] - MARGIN - 180
    y = table(
        sheet,
        x_t,
        287,
        [12, 10, 30, 30, 32, 34, 32],
        ["hole", "axis", "position 1", "position 2", "Ø (through)", "counterbore Ø", "cbore depth"],
        rows,
        "mount",
    )
    if m.key.height > 0:
        table(
            sheet,
            x_t,
            y - 4,
            [40, 45, 45, 50],
            ["key (datum C)", "width", "height", "direction A"],
            [["key", D["key.width"], D["key.height"], D["key.A"]]],
            "mount",
        )
    c_line = "C: the key" if m.key.height > 0 else "C: the +x face of the block (no key)"
    notes(
        sheet,
        x_t,
        NOTES_TOP,
        tol,
        [
            f"datum A: the socket axis; B: the socket floor (the body's end face seats here); {c_line}",
            "positions in frame M: origin on A at B, axes parallel to the fiducial's F",
            "holes counterbored on the + face of their axis; screws ISO 4762, clearance ISO 273",
        ],
    )


def connector_sheet(design: Design, conn_part, views: PartViews, profile: Profile, tb: TitleBlock) -> Sheet:
    """The connector's sheet: front (pocket face), side and a section through the pocket.

    The parameters are :func:`mount_sheet`'s, for the connector: ``conn_part`` a
    :class:`~ftrac_design.cad.connector.ConnectorPart` (frame T) and ``views`` its solid's; the
    drawn sheet is returned.
    """
    tol = drawing_tolerances(profile)
    D = _dims(connector_dimensions(conn_part, tol))
    k = conn_part.layout
    (x0, y0, z0), (x1, y1, z1) = k.lo, k.hi
    sx, sy, t = float(x1 - x0), float(y1 - y0), float(z1 - z0)
    s = pick_scale(sx + t + 60, sy + 30, 205, 240)
    sheet = Sheet(f"{design.name} — template connector")
    tb = tb.of_part("connector (connector.step, frame T)", design.connector.material, profile, scale_text(s))
    _connector_views(sheet, conn_part, views, s, D)
    _connector_tables(sheet, k, tol, D)
    title_block(sheet, tb)
    return sheet


def _connector_views(sheet: Sheet, conn_part, views: PartViews, s: float, D: dict[str, Dim]) -> None:
    """The connector's front view (the pocket face) and the section through the pocket."""
    k = conn_part.layout
    (x0, y0, z0), (x1, y1, z1) = k.lo, k.hi
    sx, sy = float(x1 - x0), float(y1 - y0)
    yb = 287 - 16 - sy * s - 20
    ax = sheet.view(22, yb, (x0, x1, y0, y1), s, pad=12)
    draw_projection(ax, views.project(ViewFrame("front", (1, 0, 0), (0, 0, 1))))
    sheet.text(
        ax,
        (x0 + x1) / 2,
        y0 - 9 / s,
        "FRONT (from +z, the pocket face; template face behind)",
        ha="center",
        size=6.5,
        weight="bold",
    )
    dim_line(ax, (x0, y1), (x1, y1), (0, 5 / s), D["plate.width"], "connector")
    dim_line(ax, (x0, y0), (x0, y1), (-6 / s, 0), D["plate.height"], "connector")
    pins = [h for h in k.holes if h.kind == "pin"]
    if pins:
        datum_flag(ax, tuple(pins[0].center[:2]), "B", dx=-5 / s, dy=-5 / s)
    if len(pins) > 1:
        datum_flag(ax, tuple(pins[1].center[:2]), "C", dx=5 / s, dy=-5 / s)
    # section through the pocket centre, plane x = pocket x, seen from +x: y right, z up
    xs = 22 + sx * s + 24 + 26
    ax = sheet.view(xs, yb, (y0, y1, z0, z1), s, pad=12)
    cx = float(k.pocket_center[0])
    draw_section(ax, views.section(ViewFrame("section", (0, 1, 0), (1, 0, 0), (cx, 0.0, 0.0))))
    sheet.text(
        ax, (y0 + y1) / 2, z0 - 9 / s, "SECTION P–P (plane x = pocket centre)", ha="center", size=6.5, weight="bold"
    )
    dim_line(ax, (y1, z0), (y1, z1), (6 / s, 0), D["plate.thickness"], "connector")
    pc, ph = float(k.pocket_center[1]), conn_part.pocket_size / 2
    dim_line(ax, (pc - ph, z1), (pc + ph, z1), (0, 5 / s), D["pocket.size"], "connector")
    dim_line(ax, (pc + ph, z1 - k.pocket_depth), (pc + ph, z1), (3 / s, 0), D["pocket.depth"], "connector")
    datum_flag(ax, (y0, z1), "A", dx=-5 / s, dy=4 / s)


def _connector_tables(sheet: Sheet, k, tol: DrawingTolerances, D: dict[str, Dim]) -> None:
    """The connector's hole table, the plate's and pocket's positions and the notes."""
    rows = [[h.name, h.kind, D[f"{h.name}.x"], D[f"{h.name}.y"], D[f"{h.name}.diameter"]] for h in k.holes]
    x_t = SHEET[0] - MARGIN - 180
    y = table(sheet, x_t, 287, [16, 22, 44, 44, 50], ["hole", "kind", "x", "y", "Ø (through)"], rows, "connector")
    table(
        sheet,
        x_t,
        y - 4,
        [44, 44, 44, 44],
        ["plate corner x", "plate corner y", "pocket centre x", "pocket centre y"],
        [[D["plate.x0"], D["plate.y0"], D["pocket.x"], D["pocket.y"]]],
        "connector",
    )
    table(
        sheet,
        x_t,
        y - 4 - 2 * ROW_MM - 4,
        [60, 60],
        ["pocket corner radius", ""],
        [[D["pocket.radius"], None]],
        "connector",
    )
    notes(
        sheet,
        x_t,
        NOTES_TOP,
        tol,
        [
            "datum A: the template face z = 0 of T; B: pin hole 1 (the reference grid hole); C: pin hole 2",
            "positions in frame T: origin on the reference grid hole, x along rows, y up the columns",
            "dowel pins ISO 2338 m6 pressed in; tapped holes take the mount's z screws",
        ],
    )


def sheet_style():
    """The matplotlib settings every sheet is drawn and saved under: SVG text kept as text (so
    a test reads each value back), a fixed hash salt (equal sheets, equal bytes), one font.

    Returns
    -------
    contextlib.AbstractContextManager
        ``matplotlib.rc_context`` with those settings.
    """
    import matplotlib

    return matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "ftrac", "font.family": "DejaVu Sans"})


def title_block_for(design: Design, profile: Profile, date: str | None = None) -> TitleBlock:
    """The title block every sheet of ``design`` starts from (the part, material and scale are
    filled in by each sheet).

    Parameters
    ----------
    design : Design
        The design (its name and file's sha256).
    profile : {"cnc", "fdm"}
        The manufacturing profile.
    date : str or None
        ISO date for the title block (default: today, UTC).

    Returns
    -------
    TitleBlock
        Design, sha256, profile and date set; the rest empty.
    """
    return TitleBlock(
        design.name, design.sha256 or "(in-memory design: no file)", "", "", profile, "", date or _today()
    )


def save_sheet(sheet: Sheet, out_dir: Path, name: str, png: bool = False) -> list[Path]:
    """Write ``drawing_<name>.svg`` and ``.pdf`` (and ``.png`` when asked) into ``out_dir``.

    Parameters
    ----------
    sheet : Sheet
        The drawn sheet.
    out_dir : pathlib.Path
        Where the files go.
    name : str
        The part's name in the file names (``"body"``).
    png : bool
        Also write a PNG (for documentation).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    svg, pdf = out_dir / f"drawing_{name}.svg", out_dir / f"drawing_{name}.pdf"
    pic = out_dir / f"drawing_{name}.png" if png else None
    sheet.save(svg, pdf, pic)
    return [svg, pdf] + ([pic] if pic else [])
