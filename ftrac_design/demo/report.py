"""``make demo``'s report step: the one-page HTML report of the demo's build."""

from __future__ import annotations

from pathlib import Path

from ..workflows.report import report_for_build


def demo_step(out_dir: Path) -> str:
    """``make demo``'s report step: write ``out_dir/report.html`` for the build in ``out_dir``
    (the demo's ``outputs/ftrac_2005/``), using its ``analysis/`` if the demo scored it
    (else a quick 2,000-pose analysis); returns the lines the demo prints."""
    import time

    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    path = report_for_build(out_dir, poses=2000, atlas_step_deg=4.0)
    kb = path.stat().st_size / 1024
    return (
        f"Report -> {path} ({kb:.0f} KB, one self-contained HTML page: render, parameters, features, "
        f"design rules cnc + fdm, score, atlas, bill of materials, wire cut list, file hashes; "
        f"{time.perf_counter() - t0:.1f} s)"
    )
