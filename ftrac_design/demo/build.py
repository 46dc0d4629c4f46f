"""``make demo``'s first step: build the paper's fiducial (``ftrac-design build``) and summarise
what the build wrote.

Without the ``cad`` extra the build is skipped; :func:`demo_step` still writes the design's
``features.json``, which the later steps read, before it reports the missing extra.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..design.presets import preset_path
from .shell import relative

#: the paper's fiducial, shipped with the package (``models/``, the presets)
DEFAULT_DESIGN = preset_path("ftrac_2005")


def demo_build(
    design_path: str | Path = DEFAULT_DESIGN, out_dir: str | Path | None = None, profile: str = "cnc"
) -> dict[str, Any]:
    """Build ``design_path`` into ``out_dir`` (default ``outputs/<name>/``); return a summary."""
    from ..cad.build import build_fiducial
    from ..design import load_design

    design = load_design(relative(design_path))  # features.json records the path as given
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
        "rules": m["manufacturing"]["rules"],
        "build_time_s": m["build_time_s"],
        "timings_s": m["timings_s"],
    }


def format_build(summary: dict[str, Any]) -> str:
    """A short human-readable block for :func:`demo_build`'s summary."""
    v = summary["volumes_mm3"]
    lines = [
        f"Built {summary['design']} ({summary['profile']} profile) in {summary['build_time_s']:.1f} s "
        f"-> {summary['out_dir']}/"
    ]
    for name, size in summary["files"].items():
        lines.append(f"  {name:<15} {size / 1024:9.1f} KiB")
    lines.append("  manifest.json   (parameters, sha256 of every file, volumes, timings)")
    lines.append(
        f"  volumes: body {v['body']:.1f} mm3 (blank {v['blank']:.1f}, grooves and pockets "
        f"{v['removed']:.1f}), wires {v['wires']:.2f}, beads {v['beads']:.2f}"
    )
    lines.append(
        f"  wire {summary['wire_length_mm']:.1f} mm in total, {summary['beads']} beads; "
        f"STL volume {summary['stl_volume_vs_brep']:+.3%} vs the exact solid"
    )
    r = summary["rules"]
    lines.append(
        f"  design rules ({summary['profile']}): {len(r['results'])} checked, "
        f"{len(r['violations'])} violated, {len(r['warnings'])} warning(s)"
        + "".join(f"\n    warn: {w}" for w in r["warnings"])
    )
    t = summary["timings_s"]
    lines.append(
        "  time: "
        + ", ".join(f"{k} {t[k]:.1f} s" for k in ("body", "export_body", "export_assembly", "render") if k in t)
    )
    return "\n".join(lines)


def demo_step(out_dir: str | Path | None = None, design_path: str | Path = DEFAULT_DESIGN) -> str:
    """Build ``design_path`` into ``out_dir`` (default ``outputs/<name>/``) and return the text
    the demo prints.

    Parameters
    ----------
    out_dir : str, pathlib.Path or None
        The build's directory.
    design_path : str or pathlib.Path
        The design file.

    Returns
    -------
    str
        The build's summary (:func:`format_build`).

    Raises
    ------
    MissingDependencyError
        When the ``cad`` extra is missing; ``features.json`` is written into ``out_dir`` first.
    """
    from ..errors import MissingDependencyError

    try:
        return format_build(demo_build(design_path, out_dir))
    except MissingDependencyError:
        write_design_features(design_path, out_dir)
        raise


def write_design_features(design_path: str | Path, out_dir: str | Path | None = None) -> Path:
    """``features.json`` of ``design_path`` in ``out_dir`` (default ``outputs/<name>/``), as a
    build writes it, for the steps that read it when the build cannot run.

    Parameters
    ----------
    design_path : str or pathlib.Path
        The design file.
    out_dir : str, pathlib.Path or None
        The build's directory.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    from ..design import load_design
    from ..features import compute_features, write_features

    design = load_design(relative(design_path))
    out = Path(out_dir) if out_dir is not None else Path("outputs") / design.name
    out.mkdir(parents=True, exist_ok=True)
    return write_features(out / "features.json", compute_features(design))
