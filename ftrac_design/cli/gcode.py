"""``ftrac-design gcode DESIGN [--profile cnc|fdm] [--post linuxcnc|fanuc] [-o FILE] [--check PROGRAM]``.

Writes the body's 4-axis program for the grooves and pockets and verifies it by simulated
material removal against the cuts the CAD makes; or, with ``--check``, verifies a program
someone else wrote or edited. Exit 1 when the verification fails.
"""

from __future__ import annotations

from pathlib import Path

import click

from ..machining.post import POSTS
from ..machining.simulate import GRID, TOLERANCE
from .options import (
    OUT_FILE,
    POSITIVE,
    design_argument,
    optional_option,
    output_option,
    post_option,
    profile_option,
    shown_option,
)


def _table(v, cycle: dict[str, float] | None) -> list[str]:
    lines = [
        f"  max deviation   {v.max_deviation_mm * 1000:8.2f} um  (overcut {v.max_overcut_mm * 1000:.2f}, "
        f"undercut {v.max_undercut_mm * 1000:.2f}; limit {v.tolerance_mm * 1000:g})",
        f"  gouges          {v.gouges:8d}",
        f"  removed volume  {v.removed_mm3:8.3f} mm3 vs {v.reference_mm3:.3f} mm3 in the CAD "
        f"({v.volume_difference:+.3%}; limit {v.volume_tolerance:.0%})",
        f"  grid {v.grid_mm:g} mm, scallop <= {v.scallop_mm * 1000:.2f} um, simulated in {v.run_time_s:.1f} s",
    ]
    if cycle:
        lines.insert(
            0,
            f"  cycle time      {cycle['total_s'] / 60:8.1f} min  (cutting {cycle['feed_s'] / 60:.1f}, "
            f"rapids {cycle['rapid_s'] / 60:.2f}, tool changes {cycle['tool_change_s'] / 60:.2f})",
        )
    lines += [f"  {f}" for f in v.gouge_examples + v.rapid_faults + v.program_faults]
    return lines


@click.command("gcode")
@design_argument()
@profile_option()
@post_option()
@output_option(
    "program file [default: <design name>_body.ngc (.nc for fanuc)]; the check goes beside it as <file>.verify.json",
    type=OUT_FILE,
)
@optional_option(
    "--check",
    "check",
    type=click.Path(path_type=Path, dir_okay=False),
    help="verify this program (T1 groove, T2 pocket end mill of the design) instead of writing one",
)
@shown_option(
    "--grid",
    type=click.FloatRange(min=0.002, max=0.1),
    default=GRID,
    help="dexel spacing of the simulation at the outer surface, mm",
)
@shown_option(
    "--tolerance",
    type=POSITIVE,
    default=TOLERANCE,
    help="largest deviation from the CAD's cuts that passes, mm",
)
def command(
    design: Path, profile: str, post: str, output: Path | None, check: Path | None, grid: float, tolerance: float
) -> int:
    """Write and verify the body's 4-axis program for DESIGN (a .toml file or a preset's name).

    The program cuts every groove and pocket with an A-axis wrap (machine convention in
    docs/guide/machining.md); it is read back, the tools are swept through the stock and
    the result is compared with the CAD's cuts: max deviation, gouges, removed volume.
    """
    from ..design import load_design
    from ..errors import GoalError, InputError
    from ..fileio import read_text_input, write_json_atomic, write_text_atomic
    from ..machining.gcode import cycle_time, parse_gcode
    from ..machining.simulate import verify
    from ..manufacture.gcode import body_program

    d = load_design(design)
    try:
        bp = body_program(d, profile, post, check=False)
    except ValueError as exc:
        raise GoalError(f"{d.name}: {exc}") from exc
    if check is not None:
        if not check.is_file():
            raise InputError(check, None, "a G-code file")
        parsed = parse_gcode(read_text_input(check), check)
        cycle = cycle_time(parsed)
        target = check
    else:
        parsed = parse_gcode(bp.text, "the generated program")
        cycle = bp.cycle
        target = output or Path(f"{d.name}_body{POSTS[post].suffix}")
        if target.exists() and target.is_dir():
            raise InputError(target, None, "a file name for the program, got a directory", parameter="output")
    tools = {bp_tool.number: bp_tool.diameter for bp_tool in _tools(d, profile)}
    try:
        v = verify(parsed, bp.plan, tools=tools, grid_mm=grid, tolerance=tolerance)
    except ValueError as exc:
        raise InputError(target, None, str(exc)) from exc
    if check is None:
        write_text_atomic(target, bp.text)
    report = {
        "design": d.name,
        "profile": profile,
        "program": str(target),
        "post": post if check is None else None,
        "cycle_time_s": cycle,
        **v.as_dict(),
    }
    write_json_atomic(Path(str(target) + ".verify.json"), report)
    click.echo(f"{'checked' if check else 'wrote'} {target} ({d.name}, {profile}): {'PASS' if v.ok else 'FAIL'}")
    for line in _table(v, cycle):
        click.echo(line)
    if not v.ok:
        raise GoalError(f"{target}: the program does not cut what the CAD cuts (see {target}.verify.json)")
    return 0


def _tools(design, profile: str):
    from ..machining.model import tooling
    from ..manufacture.profiles import cut_sizes

    t = tooling(design.manufacturing.cnc, cut_sizes(design, profile).pocket_diameter or None)
    return (t.groove,) if t.pocket is t.groove else (t.groove, t.pocket)
