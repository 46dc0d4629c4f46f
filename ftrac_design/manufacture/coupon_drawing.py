"""The press-fit coupon's dimensioned drawing: a front view and an end view projected from the
coupon's solid, and one row per step — its id, A (°) and z (mm), the cut's width or Ø with the
profile's fit-critical tolerance, its depth below the outer surface, the bought part's Ø and the
fit it gives — so the shop can cut it, inspect it and report which step holds.

Values come from the coupon's plan (:class:`~ftrac_design.manufacture.coupon.Coupon`), the same cuts the
solid and the program are made from. Frame and conventions as the body's drawing: azimuth A about
+z from +x toward +y, z from mid-length, depth radially from the outer surface (Ø = datum A).
"""

from __future__ import annotations

import math
from pathlib import Path

from ..design.schema import Design
from .coupon import Coupon
from .dimensions import Dim
from .drawings import Sheet as _Sheet
from .drawings import (
    TitleBlock,
    _dims,
    datum_flag,
    dim_line,
    draw_projection,
    notes,
    pick_scale,
    save_sheet,
    scale_text,
    sheet_style,
    table,
    title_block,
    title_block_for,
)
from .profiles import DrawingTolerances, drawing_tolerances
from .views import PartViews, ViewFrame

PART = "coupon"


def coupon_dimensions(c: Coupon, tol: DrawingTolerances) -> list[Dim]:
    """The coupon's printed dimensions: length and outer Ø, then per step its A, z, size, depth, the
    part's Ø and the fit (part − cut under cnc, gap per side under fdm; reference values).

    Parameters
    ----------
    c : Coupon
        The coupon's plan.
    tol : DrawingTolerances
        The profile's drawing tolerances.

    Returns
    -------
    list of Dim
        Keys ``coupon.length``, ``coupon.outer_diameter`` and ``<step id>.{A,z,size,depth,part,fit}``.
    """
    R, g, crit, ang = c.stock.outer_radius, tol.general, tol.critical, tol.angle_deg(c.stock.outer_radius)
    out = [
        Dim("coupon.length", 2 * c.stock.half_length, "mm", "length", g, label="length"),
        Dim("coupon.outer_diameter", 2 * R, "mm", "diameter", crit, True, "outer Ø (datum A)"),
    ]
    cuts = {s.id: s for s in (*c.plan.slots, *c.plan.pockets)}
    for st in c.steps:
        cut = cuts[st.id]
        if st.kind == "groove":
            z, floor = (cut.z0 + cut.z1) / 2, cut.floor_radius
            size = Dim(f"{st.id}.size", st.size, "mm", "length", crit, True, "groove width")
        else:
            z, floor = cut.z, cut.floor_radius
            size = Dim(f"{st.id}.size", st.size, "mm", "diameter", crit, True, "pocket Ø")
        out += [
            Dim(f"{st.id}.A", math.degrees(st.azimuth) % 360.0, "deg", "angle", ang),
            Dim(f"{st.id}.z", z, "mm", "length", crit),
            size,
            Dim(f"{st.id}.depth", R - floor, "mm", "length", crit, label="depth below datum A"),
            Dim(f"{st.id}.part", st.part_diameter, "mm", "diameter", None, label="bought part"),
            Dim(f"{st.id}.fit", st.fit, "mm", "length", None, label="fit"),
        ]
    return out


def coupon_sheet(design: Design, c: Coupon, views: PartViews, tb: TitleBlock) -> _Sheet:
    """The coupon's sheet: front view (from −y), end view (from +z), the steps' table, notes and
    the title block, for ``design``'s wire and balls; ``c`` the coupon's plan, ``views`` its
    solid's projections (the coupon's frame: axis +z, origin at mid-length), ``tb`` the title
    block's design name, sha256 and date. Returns the drawn sheet.
    """
    tol = drawing_tolerances(c.profile)
    D = _dims(coupon_dimensions(c, tol))
    R, h = c.stock.outer_radius, c.stock.half_length
    s = pick_scale(4 * R, 2 * h, 120, 120)  # the two views side by side across the top left
    sheet = _Sheet(f"{design.name} — press-fit coupon")
    tb = tb.of_part("press-fit coupon (coupon.step)", design.body.material, c.profile, scale_text(s))
    y0 = 287 - 14 - 2 * h * s - 24
    ax = sheet.view(20, y0, (-R, R, -h, h), s, pad=14)
    draw_projection(ax, views.project(ViewFrame("front", (1, 0, 0), (0, -1, 0))))
    sheet.text(ax, 0, -h - 10 / s, "FRONT (from −y)", ha="center", size=6.5, weight="bold")
    dim_line(ax, (R, -h), (R, h), (7 / s, 0), D["coupon.length"], PART)
    dim_line(ax, (-R, h), (R, h), (0, 6 / s), D["coupon.outer_diameter"], PART)
    datum_flag(ax, (0, -h), "B", dx=-R - 8 / s, dy=0)
    ax = sheet.view(20 + 2 * R * s + 44, y0 + 2 * h * s - 2 * R * s, (-R, R, -R, R), s, pad=14)
    draw_projection(ax, views.project(ViewFrame("end", (1, 0, 0), (0, 0, 1))))
    sheet.text(ax, 0, -R - 10 / s, "END (from +z): A = 0 along +x", ha="center", size=6.5, weight="bold")
    datum_flag(ax, (R, 0), "C", dx=6 / s)
    rows = _step_rows(c, D)
    fit = "fit (part − cut)" if c.profile == "cnc" else "gap per side"
    x_t = 20.0
    # the table below the views, the notes below the table
    y = table(
        sheet,
        x_t,
        min(287 - 12, y0 - 24),
        [20, 16, 30, 28, 34, 26, 22, 30, 18],
        ["step", "kind", "A", "z", "width / Ø", "depth", "part Ø", fit, "holds?"],
        rows,
        PART,
    )
    notes(
        sheet,
        x_t,
        y - 4,
        tol,
        [
            "datum A: the coupon's axis (outer Ø); B: the −z end face (the chuck side); C: A = 0, the +x direction",
            f"steps {c.step_mm:g} mm apart; the size is engraved beside each cut on the +z end face (CAD only)",
            "press the design's wire into each groove and a ball into each pocket; mark the steps that hold",
        ],
        angle_radius=R,
    )
    title_block(sheet, tb)
    return sheet


def _step_rows(c: Coupon, D: dict[str, Dim]) -> list[list[Dim | str | None]]:
    """The steps' table: one row per step, its last column (``holds?``) left for the shop."""
    return [
        [
            st.id,
            st.kind,
            D[f"{st.id}.A"],
            D[f"{st.id}.z"],
            D[f"{st.id}.size"],
            D[f"{st.id}.depth"],
            D[f"{st.id}.part"],
            D[f"{st.id}.fit"],
            "",
        ]
        for st in c.steps
    ]


def write_coupon_drawing(
    design: Design, c: Coupon, views: PartViews, out_dir: str | Path, date: str | None = None
) -> list[Path]:
    """Write ``drawing_coupon.svg`` and ``.pdf`` into ``out_dir``; returns the two paths.

    Parameters
    ----------
    design, c, views
        As :func:`coupon_sheet`.
    out_dir : str or pathlib.Path
        The coupon's output directory.
    date : str or None
        ISO date for the title block (default: today, UTC).
    """
    with sheet_style():
        sheet = coupon_sheet(design, c, views, title_block_for(design, c.profile, date))
        return save_sheet(sheet, Path(out_dir), "coupon")
