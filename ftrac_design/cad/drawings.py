"""The shop drawings of a build: the body's, the mount's and the connector's sheets drawn from
their solids (SVG and PDF).

The sheets themselves — views placed at a true scale, dimensions, tables, notes and the
title block — are :mod:`ftrac_design.manufacture.drawings`; this module builds what they are
drawn from (the finished solids and their hidden-line views, :class:`~.views.SolidViews`) and
writes them, within a build (:func:`write_drawings`) or on their own (:func:`draw_design`).
"""

from __future__ import annotations

from pathlib import Path

from ..design.schema import Design
from ..features.model import Features
from ..manufacture.drawings import (
    DRAWING_FILES,
    body_sheet,
    connector_sheet,
    mount_sheet,
    save_sheet,
    sheet_style,
    title_block_for,
)
from ..manufacture.plan import BodyPlan
from ..manufacture.profiles import Profile, cut_sizes

__all__ = ["DRAWING_FILES", "draw_design", "write_drawings"]


def write_drawings(
    design: Design,
    features: Features,
    plan: BodyPlan,
    body,
    fixture: list,
    profile: Profile,
    out_dir: str | Path,
    date: str | None = None,
    png: bool = False,
) -> list[Path]:
    """Write ``drawing_{body,mount,connector}.{svg,pdf}`` into ``out_dir``.

    Parameters
    ----------
    design, features, plan : Design, Features, BodyPlan
        The design, its features and the body's cut plan.
    body : cadquery.Shape
        The finished body solid (F).
    fixture : list
        The :func:`~ftrac_design.cad.fixture.fixture_parts` (their ``local`` solids are drawn).
    profile : {"cnc", "fdm"}
        The manufacturing profile.
    out_dir : str or pathlib.Path
        Where the files go.
    date : str or None
        ISO date for the title block (default: today, UTC).
    png : bool
        Also write ``drawing_<part>.png`` (for documentation; not part of a build).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    from ..features.mounting import connector_layout, mount_layout
    from .connector import ConnectorPart
    from .mount import MountPart
    from .views import SolidViews

    out_dir = Path(out_dir)
    cuts = cut_sizes(design, profile)
    tb = title_block_for(design, profile, date)
    mlay = mount_layout(design)
    by_kind = {p.kind: p for p in fixture}
    slot = None
    if mlay.key.height > 0:
        slot = (cuts.slide(mlay.key.width), mlay.key.slot_depth)
    written = []
    with sheet_style():
        sheets = {
            "body": body_sheet(design, features, plan, SolidViews(body), profile, tb, slot),
            "mount": mount_sheet(
                design, MountPart(mlay, cuts), SolidViews(by_kind["mount"].local, exact=True), profile, tb
            ),
            "connector": connector_sheet(
                design,
                ConnectorPart(connector_layout(design, mlay), cuts),
                SolidViews(by_kind["connector"].local, exact=True),
                profile,
                tb,
            ),
        }
        for name, sheet in sheets.items():
            written += save_sheet(sheet, out_dir, name, png)
    return written


def draw_design(
    design: Design, out_dir: str | Path, profile: Profile = "cnc", png: bool = False, date: str | None = None
) -> list[Path]:
    """Build the solids of ``design`` (body with its key slot, mount, connector — no exports) and
    write only the drawings into ``out_dir``, atomically.

    Parameters
    ----------
    design : Design
        The design.
    out_dir : str or pathlib.Path
        A new or empty directory, or one that holds earlier drawings.
    profile : {"cnc", "fdm"}
        The manufacturing profile.
    png : bool
        Also write each sheet as PNG.
    date : str or None
        ISO date for the title block (default: today, UTC).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    from ..features import compute_features
    from ..fileio import atomic_directory, check_output_dir
    from ..manufacture.plan import plan_body
    from .body import build_body, single_solid
    from .fixture import fixture_parts
    from .mount import key_slot_tool
    from .occ import occ_errors, require_cad_packages

    require_cad_packages(render=False)
    out_dir = Path(out_dir)
    check_output_dir(out_dir, "earlier drawings", lambda d: (d / "drawing_body.svg").is_file())
    features = compute_features(design)
    plan = plan_body(design, features, cut_sizes(design, profile))
    with atomic_directory(out_dir) as tmp, occ_errors(design.name):
        body = build_body(plan)
        slot = key_slot_tool(design, profile)
        if slot is not None:
            body = single_solid(body.cut(slot), f"{design.name} key slot")
        written = write_drawings(
            design, features, plan, body, fixture_parts(design, features, profile), profile, tmp, date=date, png=png
        )
    return [out_dir / p.name for p in written]
