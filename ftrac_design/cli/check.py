"""``ftrac-design check DESIGN.toml|PRESET [--profile cnc|fdm] [--json]`` (SPEC §5): the design-rule
report. Exit 0 when no rule is violated (warnings allowed), 1 on any violation, 2 on bad input.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from ..errors import GoalError
from .options import design_argument, flag_option, profile_option


@click.command("check")
@design_argument()
@profile_option("manufacturing profile whose cut sizes and limits apply")
@flag_option("--json", "as_json", help="print the report as one JSON object instead of a table")
def command(design: Path, profile: str, as_json: bool) -> int:
    """Check DESIGN (a .toml file or a preset's name) against the manufacturing design rules.

    Prints one row per rule: the measured value (the worst case over the design), the
    limit, and the verdict — ok, warn (within the limit, short of the recommended value),
    FAIL (a violation) or n/a. Exits 1 if any rule fails.
    """
    from ..design import load_design
    from ..manufacture.rules import check_design

    d = load_design(design)
    report = check_design(d, profile)
    if as_json:
        click.echo(json.dumps(report.as_dict(), indent=2, allow_nan=False))
    else:
        click.echo(f"check {report.summary}")
        click.echo(report.table())
    if not report.ok:
        names = ", ".join(r.rule for r in report.violations)
        if as_json:
            raise GoalError(f"{len(report.violations)} design rule(s) violated: {names}")
        raise GoalError("; ".join(r.message for r in report.violations))
    return 0
