"""What ``build`` adds for manufacturing: the design-rule gate and the manifest's
``manufacturing`` entry with the bill of materials.

- :func:`enforce_rules` runs :func:`ftrac_design.manufacture.rules.check_design` before
  anything is written; a violation stops the build (exit 1, one line naming the rule, the
  value and the limit) unless ``--force``.
- :func:`manufacturing_manifest` is the manifest's ``manufacturing`` entry: profile, cut
  sizes, the rule verdicts, the frames each file is in, and the bill of materials.

The files themselves (``mount.step``/``.stl``, ``connector.step``/``.stl``, ``grooves.csv``,
``grooves.dxf``) are written by :func:`ftrac_design.cad.export.write_manufacturing_files`.
"""

from __future__ import annotations

from typing import Any

from ..design.schema import Design
from ..errors import GoalError
from ..features.model import Features
from .bom import bill_of_materials
from .profiles import Profile, cut_sizes
from .rules import CheckReport, check_design
from .unwrap import STEP_DEG, chord_error, unwrap_features

#: files written by :func:`ftrac_design.cad.export.write_manufacturing_files`, in order
MANUFACTURING_FILES = ("mount.step", "mount.stl", "connector.step", "connector.stl", "grooves.csv", "grooves.dxf")


def enforce_rules(design: Design, features: Features, profile: Profile, force: bool) -> CheckReport:
    """The design-rule report; raises :class:`GoalError` on a violation unless ``force``."""
    report = check_design(design, profile, features)
    if report.violations and not force:
        first = report.violations[0]
        more = len(report.violations) - 1
        tail = f" (and {more} more rule{'s' * (more != 1)})" if more else ""
        raise GoalError(
            f"design rule violated: {first.message}{tail}; "
            f"see `ftrac-design check --profile {profile}`, or build with --force"
        )
    return report


def manufacturing_manifest(
    design: Design, features: Features, profile: Profile, report: CheckReport, files: dict[str, Any]
) -> dict[str, Any]:
    """The manifest's ``manufacturing`` entry (plain JSON)."""
    paths = unwrap_features(features, design.outer_radius, cut_sizes(design, profile))
    chord = max((chord_error(p, features) for p in paths), default=0.0)
    return {
        "profile": profile,
        "rules": {
            "ok": report.ok,
            "violations": [r.message for r in report.violations],
            "warnings": [r.message for r in report.warnings],
            "results": {
                r.rule: {
                    "measured": r.measured,
                    "limit": r.limit,
                    "comparison": r.comparison,
                    "unit": r.unit,
                    "verdict": r.verdict,
                }
                for r in report.results
            },
        },
        "frames": {
            "fiducial.step": "F",
            "assembly.step": "F",
            "mount.step": "M",
            "connector.step": "T",
            "grooves.csv": "F (theta about +z from +x, z along the axis)",
        },
        "parts": files,
        "grooves": {"step_deg": STEP_DEG, "max_chord_error_mm": chord, **files.get("grooves", {})},
        "bom": bill_of_materials(design, features, profile),
    }
