"""``make demo`` / ``python -m ftrac_design.demo``: build the paper's fiducial and summarise.

Each step is a small function returning a plain summary dict, and :func:`main` prints
them, so later steps (scoring, a solved synthetic image) slot in beside :func:`demo_build`.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

#: the repository's models/ folder (the package is installed in editable mode by make)
MODELS = Path(__file__).resolve().parents[1] / "models"
DEFAULT_DESIGN = MODELS / "ftrac_2005.toml"


def demo_build(design_path: str | Path = DEFAULT_DESIGN, out_dir: str | Path | None = None,
               profile: str = "cnc") -> dict[str, Any]:
    """Build ``design_path`` into ``out_dir`` (default ``outputs/<name>/``); return a summary."""
    from .cad.build import build_fiducial
    from .design import load_design

    design = load_design(design_path)
    result = build_fiducial(design, out_dir, profile=profile)
    m = result.manifest
    return {
        "design": design.name,
        "profile": profile,
        "out_dir": str(result.out_dir),
        "files": {name: info["bytes"] for name, info in m["files"].items()},
        "volumes_mm3": m["volumes_mm3"],
        "wire_length_mm": m["wires"]["total_length_mm"],
        "beads": m["beads"]["count"],
        "stl_volume_vs_brep": m["stl"]["volume_vs_brep"],
        "build_time_s": m["build_time_s"],
        "timings_s": m["timings_s"],
    }


def format_build(summary: dict[str, Any]) -> str:
    """A short human-readable block for :func:`demo_build`'s summary."""
    v = summary["volumes_mm3"]
    lines = [f"Built {summary['design']} ({summary['profile']} profile) in {summary['build_time_s']:.1f} s "
             f"-> {summary['out_dir']}/"]
    for name, size in summary["files"].items():
        lines.append(f"  {name:<15} {size / 1024:9.1f} KiB")
    lines.append("  manifest.json   (parameters, sha256 of every file, volumes, timings)")
    lines.append(f"  volumes: body {v['body']:.1f} mm3 (blank {v['blank']:.1f}, grooves and pockets "
                 f"{v['removed']:.1f}), wires {v['wires']:.2f}, beads {v['beads']:.2f}")
    lines.append(f"  wire {summary['wire_length_mm']:.1f} mm in total, {summary['beads']} beads; "
                 f"STL volume {summary['stl_volume_vs_brep']:+.3%} vs the exact solid")
    t = summary["timings_s"]
    lines.append("  time: " + ", ".join(f"{k} {t[k]:.1f} s" for k in ("body", "export_body", "export_assembly", "render")
                                        if k in t))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run every demo step and print its summary; returns the exit code."""
    from .errors import GoalError, InputError

    try:
        print(format_build(demo_build()))
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except GoalError as exc:
        print(f"failed: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
