"""``ftrac-design build DESIGN.toml|PRESET [-o DIR] [--profile cnc|fdm] [--force]`` (SPEC §5)."""

from __future__ import annotations

from pathlib import Path

import click

from .options import design_argument, flag_option, output_option, post_option, profile_option


@click.command("build")
@design_argument()
@output_option("output directory [default: outputs/<design name>/]")
@profile_option()
@flag_option("--force", help="build even if the design breaks a manufacturing rule")
@post_option("control the body's 4-axis program (body.ngc / body.nc, cnc profile) is written for")
@flag_option(
    "--report", help="also write report.html (one self-contained page; runs the analysis at the design's settings)"
)
def command(design: Path, output: Path | None, profile: str, force: bool, post: str, report: bool) -> int:
    """Build the fiducial body, wires and beads of DESIGN (a .toml file or a preset's name,
    see `ftrac-design presets`).

    Writes fiducial.step, fiducial.stl, assembly.step (body, wires, beads as named,
    coloured parts), features.json, manifest.json, render.png and the dimensioned drawings
    drawing_{body,mount,connector}.{svg,pdf} into the output directory; under --profile fdm
    also fiducial.3mf (the printed parts) and print_settings.json, under the cnc profile the
    body's 4-axis program (body.ngc; see `ftrac-design gcode` to verify it). Atomically: a
    failed build leaves nothing behind.
    """
    from ..cad.build import build_fiducial
    from ..design import load_design

    d = load_design(design)
    result = build_fiducial(d, output, profile=profile, force=force, post=post)
    m = result.manifest
    vol = m["volumes_mm3"]
    click.echo(f"built {d.name} ({profile}) in {m['build_time_s']:.1f} s -> {result.out_dir}")
    for name, info in m["files"].items():
        click.echo(f"  {name:<15} {info['bytes']:>10,d} bytes")
    click.echo(f"  {'manifest.json':<15}")
    click.echo(
        f"  body {vol['body']:.1f} mm3, wires {vol['wires']:.2f} mm3, beads {vol['beads']:.2f} mm3; "
        f"wire {m['wires']['total_length_mm']:.1f} mm, {m['beads']['count']} beads"
    )
    if report:
        from ..workflows.report import report_for_build

        click.echo(f"  wrote {report_for_build(result.out_dir, design=d)}")
    return 0
