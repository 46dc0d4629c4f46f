"""How long does ``build`` take per preset, and where does the time go?

Each preset is built once (cnc profile, everything ``ftrac-design build`` writes, render
included) after a warm-up build that pays CadQuery's import and OCC's first-use costs, and
the manifest's per-stage timings are printed. In the same run the body alone is cut with
the default ``staged`` boolean (ellipse grooves first, then line grooves and pockets) and
with the baseline a first version would use — one boolean with every tool (``single``) —
so the ratio is measured on this machine, not quoted. Target: default build ≤ 15 s.

Run: ``.venv/bin/python benchmarks/build_time.py``
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from _common import machine

PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")
REPEATS = 3


def main() -> None:
    import cadquery as cq

    from ftrac_design.cad.body import build_body
    from ftrac_design.cad.build import build_fiducial
    from ftrac_design.design import load_design
    from ftrac_design.features import compute_features
    from ftrac_design.manufacture.plan import plan_body
    from ftrac_design.manufacture.profiles import cut_sizes

    print(f"machine: {machine()}, CadQuery {cq.__version__}")
    tmp = Path(tempfile.mkdtemp(prefix="ftrac-bench-build-"))
    try:
        build_fiducial(load_design("nine_bead"), tmp / "warm")
        print(f"\n{'preset':<11} {'total s':>8} {'body':>6} {'exports':>8} {'mount+conn':>10} {'render':>7}")
        for name in PRESETS:
            res = build_fiducial(load_design(name), tmp / name)
            t = res.manifest["timings_s"]
            print(
                f"{name:<11} {res.manifest['build_time_s']:8.2f} {t['body']:6.2f} "
                f"{t['export_body'] + t['export_assembly']:8.2f} {t.get('mount_connector', 0.0):10.2f} "
                f"{t['render']:7.2f}"
            )

        print(f"\nbody boolean only, best of {REPEATS}: staged (default) vs one boolean with every tool")
        print(f"{'preset':<11} {'staged s':>9} {'single s':>9} {'single/staged':>14}")
        for name in ("ftrac_2005", "ftrac_mini"):
            d = load_design(name)
            plan = plan_body(d, compute_features(d), cut_sizes(d, "cnc"))
            best = {}
            for strategy in ("staged", "single"):
                times = []
                for _ in range(REPEATS):
                    t0 = time.perf_counter()
                    build_body(plan, strategy)
                    times.append(time.perf_counter() - t0)
                best[strategy] = min(times)
            print(f"{name:<11} {best['staged']:9.2f} {best['single']:9.2f} {best['single'] / best['staged']:14.2f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
