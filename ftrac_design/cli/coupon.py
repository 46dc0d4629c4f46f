"""``ftrac-design coupon DESIGN [--profile cnc|fdm] [-o DIR]`` (SPEC §5): the press-fit test
coupon; and ``--interference WIRE,BALL --write-design OUT.toml`` to feed the sizes that held
back into the design's profile, so every later build cuts them."""

from __future__ import annotations

from pathlib import Path

import click

from .options import design_argument, optional_option, output_option, post_option, profile_option, shown_option


def _pair(ctx, param, value):
    if value is None:
        return None
    try:
        wire, ball = (float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"two numbers WIRE,BALL in mm, got {value!r}") from None
    if min(wire, ball) < 0:
        raise click.BadParameter(f"values >= 0, got {value!r}")
    return wire, ball


@click.command("coupon")
@design_argument()
@profile_option("manufacturing profile whose groove width and pocket diameter the steps centre on")
@output_option("output directory [default: outputs/<design name>_coupon/]")
@optional_option(
    "--step", type=click.FloatRange(min=0.001, max=0.5), help="mm between sizes [default: 0.01 cnc, 0.05 fdm]"
)
@shown_option("--count", type=click.IntRange(min=1, max=15), default=7, help="sizes of each kind")
@post_option("control the coupon's program is written for (cnc)")
@click.option(
    "--interference",
    callback=_pair,
    default=None,
    metavar="WIRE,BALL",
    help="the fit that held on the coupon, mm (cnc: interference; fdm: gap per side): "
    "writes DESIGN with it to --write-design instead of making a coupon",
)
@optional_option(
    "--write-design",
    "write_design",
    type=click.Path(path_type=Path, dir_okay=False),
    help="where --interference writes the updated design (TOML)",
)
def command(
    design: Path,
    profile: str,
    output: Path | None,
    step: float | None,
    count: int,
    post: str,
    interference: tuple[float, float] | None,
    write_design: Path | None,
) -> int:
    """A press-fit test coupon for DESIGN's wire and balls: groove widths and pocket diameters
    stepped around the profile's values, each engraved with its size.

    Writes coupon.step, coupon.stl, coupon.png, coupon.csv (the steps, with their A position
    and fit: fill in which holds), drawing_coupon.svg/.pdf (the dimensioned drawing), under cnc
    coupon.ngc with its verification, under fdm coupon.3mf and print_settings.json.
    """
    from ..design import load_design
    from ..errors import GoalError, InputError

    d = load_design(design)
    if interference is not None or write_design is not None:
        if interference is None or write_design is None:
            raise InputError(None, None, "--interference and --write-design together", parameter="interference")
        return _feed_back(d, profile, interference, write_design)
    from ..manufacture.coupon import plan_coupon

    try:
        c = plan_coupon(d, profile, step, count)
    except ValueError as exc:
        raise GoalError(f"{d.name}: {exc}") from exc
    out = output or Path("outputs") / f"{d.name}_coupon"
    return _write(d, c, out, post, d.manufacturing.cnc)


def _feed_back(d, profile: str, fit: tuple[float, float], path: Path) -> int:
    from ..design.loader import parse_design
    from ..design.writer import to_toml
    from ..fileio import write_text_atomic

    data = d.model_dump(mode="json", exclude_defaults=True)
    keys = ("wire_interference", "bead_interference") if profile == "cnc" else ("wire_clearance", "bead_clearance")
    prof = data.setdefault("manufacturing", {}).setdefault(profile, {})
    prof[keys[0]], prof[keys[1]] = fit
    data["name"], data["nominal_beam_direction"] = d.name, d.nominal_beam_direction
    parse_design(data, path)  # the written design must load
    write_text_atomic(path, to_toml(data))
    click.echo(f"wrote {path}: [manufacturing.{profile}] {keys[0]} = {fit[0]:g}, {keys[1]} = {fit[1]:g}")
    return 0


def _write(d, c, out: Path, post: str, cnc) -> int:
    from ..errors import GoalError
    from ..fileio import atomic_directory, check_output_dir, write_json_atomic, write_text_atomic
    from ..manufacture.coupon import coupon_program

    check_output_dir(out, "an earlier coupon", lambda p: (p / "coupon.csv").is_file())
    program = None
    with atomic_directory(out) as tmp:
        stl = _write_solid_files(d, c, tmp)
        if c.profile == "cnc":
            program = coupon_program(c, post, cnc)
            write_text_atomic(tmp / program.filename, program.text)
            write_json_atomic(tmp / f"{program.filename}.verify.json", program.verify_document())
        verdict = program.verification if program is not None else None
        if verdict is not None and not verdict.ok:
            raise GoalError(
                f"{c.design} coupon: its program does not cut the coupon (deviation "
                f"{verdict.max_deviation_mm:.4f} mm, {verdict.gouges} gouges)"
            )
    click.echo(f"coupon for {c.design} ({c.profile}, step {c.step_mm:g} mm) -> {out}")
    for s in c.steps:
        click.echo(f"  {s.kind:<6} {s.label} mm at A{s.azimuth * 57.29577951308232:7.2f}  fit {s.fit:+.3f}")
    click.echo(f"  thinnest wall {c.min_wall:.2f} mm; STL {stl.triangles} triangles, watertight {stl.watertight}")
    if verdict is not None:
        click.echo(
            f"  program verified: max deviation {verdict.max_deviation_mm * 1000:.2f} um, "
            f"{verdict.gouges} gouges, volume {verdict.volume_difference:+.3%}"
        )
    return 0


def _write_solid_files(d, c, tmp: Path):
    """The coupon's solid and what is made from it: STEP, STL, the steps' CSV, the render, the
    drawing and, under fdm, the 3MF with its print settings. Returns the STL's report."""
    from ..cad.coupon import build_coupon
    from ..cad.export import BODY_COLOR, export_step, export_stl
    from ..cad.render import render_png
    from ..cad.views import SolidViews
    from ..fileio import write_json_atomic, write_text_atomic
    from ..manufacture.coupon import coupon_csv
    from ..manufacture.coupon_drawing import write_coupon_drawing
    from ..manufacture.fdm import print_settings_document, read_stl_part, write_3mf

    solid = build_coupon(c)
    export_step(solid, tmp / "coupon.step")
    stl = export_stl(solid, tmp / "coupon.stl", 0.005, 0.1)
    write_text_atomic(tmp / "coupon.csv", coupon_csv(c))
    render_png(solid, [], tmp / "coupon.png", title=f"{c.design} press-fit coupon ({c.profile})")
    write_coupon_drawing(d, c, SolidViews(solid, exact=True), tmp)
    if c.profile == "fdm":  # printed: the part as a 3MF with the slicer settings the profile assumes
        part = read_stl_part(tmp / "coupon.stl", "coupon", BODY_COLOR)
        write_3mf(tmp / "coupon.3mf", [part], f"{c.design}_coupon", f"{c.design} press-fit coupon (fdm profile)")
        write_json_atomic(tmp / "print_settings.json", print_settings_document(d))
    return stl
