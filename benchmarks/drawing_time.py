"""What do the shop drawings cost a build, and what does drawing the body on a mesh save?

Each preset is built once (cnc profile, as ``ftrac-design build`` does, render skipped)
after a warm-up build, and the manifest's ``drawings`` stage is printed beside the whole
build. In the same run the body's three views are projected with hidden lines removed on a
0.01 mm mesh (``HLRBRep_PolyAlgo``, the default) and with OpenCASCADE's exact algorithm
(``HLRBRep_Algo``, the baseline), so the ratio is measured on this machine.

Run: ``.venv/bin/python benchmarks/drawing_time.py``
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from _common import machine

PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")


def main() -> None:
    import cadquery as cq

    from ftrac_design.cad.build import build_fiducial
    from ftrac_design.cad.views import ViewFrame, project
    from ftrac_design.design import load_design

    print(f"machine: {machine()}, CadQuery {cq.__version__}")
    tmp = Path(tempfile.mkdtemp(prefix="ftrac-bench-drawings-"))
    frames = [ViewFrame("front", (1, 0, 0), (0, -1, 0)), ViewFrame("end", (1, 0, 0), (0, 0, -1))]
    try:
        build_fiducial(load_design("nine_bead"), tmp / "warm", render=False)
        print(
            f"\n{'preset':<11} {'build s':>8} {'drawings s':>11} {'share':>6} {'mesh HLR s':>11} "
            f"{'exact HLR s':>12} {'exact/mesh':>11}"
        )
        for name in PRESETS:
            res = build_fiducial(load_design(name), tmp / name, render=False)
            total, draw = res.manifest["build_time_s"], res.manifest["timings_s"]["drawings"]
            body = cq.importers.importStep(str(res.out_dir / "fiducial.step")).val()
            t = {}
            for exact in (False, True):
                t0 = time.perf_counter()
                for f in frames:
                    project(body, f, exact=exact)
                t[exact] = time.perf_counter() - t0
            print(
                f"{name:<11} {total:8.2f} {draw:11.2f} {draw / total:6.0%} {t[False]:11.2f} {t[True]:12.2f} "
                f"{t[True] / t[False]:11.1f}"
            )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
