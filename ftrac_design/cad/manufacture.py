"""What ``build`` adds for manufacturing: the design-rule gate, the mount and connector
files, the 4-axis groove export and the manifest's bill of materials.

- :func:`enforce_rules` runs :func:`ftrac_design.cad.rules.check_design` before anything is
  written; a violation stops the build (exit 1, one line naming the rule, the value and the
  limit) unless ``--force``.
- :func:`write_manufacturing_files` writes ``mount.step``/``.stl`` (frame M),
  ``connector.step``/``.stl`` (frame T), ``grooves.csv`` and ``grooves.dxf``.
- :func:`manufacturing_manifest` is the manifest's ``manufacturing`` entry: profile, cut
  sizes, the rule verdicts, the frames each file is in, and the bill of materials.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..design.schema import Design
from ..errors import GoalError
from ..features.model import Features
from .bom import bill_of_materials
from .profiles import Profile, cut_sizes
from .rules import CheckReport, check_design

#: files written by :func:`write_manufacturing_files`, in order
MANUFACTURING_FILES = ("mount.step", "mount.stl", "connector.step", "connector.stl", "grooves.csv", "grooves.dxf")

#: absolute chord tolerance (mm) and angular tolerance (rad) of the mount and connector STLs
STL_TOLERANCE = (0.01, 0.1)


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


def write_manufacturing_files(
    design: Design, features: Features, profile: Profile, out_dir: Path, parts: list | None = None
) -> dict[str, Any]:
    """Write the mount, connector and groove files into ``out_dir``; returns per-file facts.

    ``parts``: the :func:`~ftrac_design.cad.fixture.fixture_parts` already built for the
    assembly (built here when omitted).
    """
    from .body import CadError
    from .export import export_step, export_stl
    from .fixture import fixture_parts
    from .unwrap import unwrap_features, write_grooves_csv, write_grooves_dxf

    parts = parts if parts is not None else fixture_parts(design, features, profile)
    info: dict[str, Any] = {}
    for p in parts:
        if p.kind not in ("mount", "connector"):
            continue
        export_step(p.local, out_dir / f"{p.name}.step")
        stl = export_stl(p.local, out_dir / f"{p.name}.stl", *STL_TOLERANCE)
        vol = float(p.local.Volume())
        rel = stl.volume / vol - 1.0
        if not stl.watertight or abs(rel) > 0.005:
            raise CadError(f"{p.name}.stl: watertight={stl.watertight}, volume off by {rel:+.3%} from the B-rep")
        bb = p.local.BoundingBox()
        info[p.name] = {
            "frame": p.frame,
            "volume_mm3": round(vol, 4),
            "bbox_mm": [
                [round(bb.xmin, 6), round(bb.ymin, 6), round(bb.zmin, 6)],
                [round(bb.xmax, 6), round(bb.ymax, 6), round(bb.zmax, 6)],
            ],
            "stl": {"triangles": stl.triangles, "watertight": stl.watertight, "volume_vs_brep": rel},
        }
    paths = unwrap_features(features, design.outer_radius, cut_sizes(design, profile))
    write_grooves_csv(out_dir / "grooves.csv", paths)
    write_grooves_dxf(
        out_dir / "grooves.dxf", paths, design.outer_radius, design.half_length, design.mount.socket_depth
    )
    info["grooves"] = {
        "polylines": sum(p.kind != "pocket" for p in paths),
        "pockets": sum(p.kind == "pocket" for p in paths),
    }
    return info


def manufacturing_manifest(
    design: Design, features: Features, profile: Profile, report: CheckReport, files: dict[str, Any]
) -> dict[str, Any]:
    """The manifest's ``manufacturing`` entry (plain JSON)."""
    from .unwrap import STEP_DEG, chord_error, unwrap_features

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
