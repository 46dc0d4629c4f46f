"""``ftrac-design drawings DESIGN.toml|PRESET [-o DIR] [--profile cnc|fdm] [--png]``: only the
shop drawings (the body, the mount and the connector as SVG and PDF), without a full build."""

from __future__ import annotations

from pathlib import Path

import click

from .options import design_argument, flag_option, output_option, profile_option


@click.command("drawings")
@design_argument()
@output_option("output directory [default: outputs/<design name>/drawings/]")
@profile_option("manufacturing profile: sets the cut sizes and tolerances drawn")
@flag_option("--png", help="also write each sheet as PNG")
def command(design: Path, output: Path | None, profile: str, png: bool) -> int:
    """Draw DESIGN (a .toml file or a preset's name): drawing_body, drawing_mount and
    drawing_connector as SVG and PDF (the same sheets `build` writes), atomically."""
    from ..cad.drawings import draw_design
    from ..design import load_design

    d = load_design(design)
    out = output if output is not None else Path("outputs") / d.name / "drawings"
    for p in draw_design(d, out, profile, png=png):
        click.echo(f"  {p}")
    return 0
