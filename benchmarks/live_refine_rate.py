"""The intensity refinement on the live path: frames per second when every tracked frame of a run
is also refined on its pixels (``serve --refine intensity``, ``track --refine intensity``), beside
tracking alone in the same run (the baseline).

A 1024² C-arm swing of ``--frames`` frames (:func:`live_latency.sweep_frames`) is tracked by the run
tracker; each converged pose is refined with :func:`ftrac_design.intensity.refine_track_result`.
The first two frames (full identifications) are left out of the medians.

    .venv/bin/python benchmarks/live_refine_rate.py [--design ftrac_2005] [--frames 12]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _common import machine  # noqa: E402
from live_latency import sweep_frames  # noqa: E402

from ftrac_design.features import load_features  # noqa: E402
from ftrac_design.intensity import refine_track_result  # noqa: E402
from ftrac_design.tracking import RunTracker  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", default="ftrac_2005")
    ap.add_argument("--frames", type=int, default=12)
    a = ap.parse_args()
    fr = sweep_frames(Path("outputs/bench_refine"), a.design, a.frames, 1024)
    features = load_features(fr.features_path)
    tracker = RunTracker(features, fr.camera)
    track_ms, refine_ms = [], []
    for k, img in enumerate(fr.pixels):
        t0 = time.perf_counter()
        answer = tracker.track_frame(img, fr.camera, float(k))
        t1 = time.perf_counter()
        if answer.result.pose.converged:
            refine_track_result(img, features, fr.camera, answer.result)
        t2 = time.perf_counter()
        track_ms.append(1e3 * (t1 - t0))
        refine_ms.append(1e3 * (t2 - t1))
    t, r = np.median(track_ms[2:]), np.median(refine_ms[2:])
    print(f"{machine()}; {a.design}, {a.frames} frames of a 1024² swing")
    print(f"tracking alone (baseline): median {t:.1f} ms, {1e3 / t:.1f} frames/s")
    print(
        f"with the intensity refinement: median {t + r:.1f} ms ({r:.1f} ms refining), {1e3 / (t + r):.1f} frames/s; "
        f"{(t + r) / t:.1f}× the baseline"
    )


if __name__ == "__main__":
    main()
