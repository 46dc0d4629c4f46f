"""The body's 4-axis program verified by simulated material removal, for the three presets
under both profiles: max deviation from the CAD's cuts, gouges, removed-volume difference,
cycle time, and how long planning and the check take.

"CAD B-rep" is blank minus body as OpenCASCADE computes it (``cad.body.build_body``, the
solid ``build`` exports): an independent check that the reference cuts cast onto the rays
are the cuts the CAD makes. The fdm rows mill the fdm profile's cut sizes (wider grooves, side passes) with the cnc
tools; a printed body is not milled, but the rows exercise the planner on wider cuts.

    .venv/bin/python benchmarks/gcode_verification.py [GRID_MM]
"""

from __future__ import annotations

import sys
import time

from _common import machine

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.machining.gcode import parse_gcode
from ftrac_design.machining.simulate import GRID, verify
from ftrac_design.manufacture.gcode import body_program
from ftrac_design.manufacture.plan import plan_body
from ftrac_design.manufacture.profiles import cut_sizes

PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")


def brep_removed(design, profile: str) -> float:
    """Blank minus body (mm³) of the CAD's solid, by OpenCASCADE."""
    from ftrac_design.cad.body import blank, build_body, volume

    plan = plan_body(design, compute_features(design), cut_sizes(design, profile))
    return volume(blank(plan)) - volume(build_body(plan))


def main(grid: float = GRID) -> None:
    print(f"machine: {machine()}")
    print(f"grid {grid} mm at the outer surface; limits: deviation <= 10 um, no gouge, volume within 1 %\n")
    print(
        "| preset | profile | tools (mm) | lines | cycle time (min) | max deviation (um) | overcut / undercut (um) "
        "| gouges | removed vs CAD rays (mm3) | volume diff | CAD B-rep (mm3) | removed vs B-rep | plan + post (s) "
        "| check (s) | check / plan | pass |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in PRESETS:
        d = load_design(name)
        for profile in ("cnc", "fdm"):
            t0 = time.perf_counter()
            bp = body_program(d, profile, check=False)
            t_plan = time.perf_counter() - t0
            parsed = parse_gcode(bp.text)
            tools = sorted({m.tool for m in parsed.moves if m.tool is not None})
            sizes = "/".join(f"{parsed.tools[t]:g}" for t in tools)
            v = verify(parsed, bp.plan, grid_mm=grid)
            brep = brep_removed(d, profile)
            print(
                f"| `{name}` | {profile} | {sizes} | {len(bp.text.splitlines())} | {bp.cycle['total_s'] / 60:.1f} "
                f"| {v.max_deviation_mm * 1000:.2f} | {v.max_overcut_mm * 1000:.2f} / {v.max_undercut_mm * 1000:.2f} "
                f"| {v.gouges} | {v.removed_mm3:.3f} vs {v.reference_mm3:.3f} | {v.volume_difference:+.3%} "
                f"| {brep:.3f} | {v.removed_mm3 / brep - 1:+.3%} "
                f"| {t_plan:.2f} | {v.run_time_s:.1f} | {v.run_time_s / t_plan:.0f}x | {'yes' if v.ok else 'NO'} |",
                flush=True,
            )


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else GRID)
