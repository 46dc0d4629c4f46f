"""Speed of the conditioning analysis: 50,000 workspace poses of ftrac_2005 (issue 5,
target ≤ 1 s on the 2-core machine).

Timed: :func:`ftrac_design.analysis.analyse_poses` with ``detail=False`` — the information
of every feature (the solver's whitened Jacobian rows), the scaled singular values,
condition number, observability indices and Cramér–Rao standard deviations at every pose.
Median of 5 runs after a warm-up, in-process.

Baseline in the same run: the per-pose loop — the same computation (information, then
metrics) on one pose at a time, without the chunking and threads, timed on 500 poses and
extrapolated to 50,000 (said so in the output). For
information, one full ``score_design`` (20,000 poses with every group, feature and
leave-one-out set) and one ``blind_spot_atlas`` (16,200 + 1,800 directions).

Run: ``.venv/bin/python benchmarks/analysis_speed.py [N]``
"""

from __future__ import annotations

import statistics
import sys
import time

from _common import load, machine

from ftrac_design.analysis import (
    AnalysisSettings, analyse_poses, blind_spot_atlas, feature_layout, pose_metrics, score_design, total_information,
)
from ftrac_design.analysis.sampling import workspace_poses
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.pose.solver import parameter_scale


def _time(fn, repeat: int) -> float:
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t0)
    return statistics.median(runs)


def main(n: int = 50_000) -> None:
    f = load("ftrac_2005")
    print(f"machine: {machine()}")
    R, t = workspace_poses(Workspace(), f.nominal_beam_direction, n, seed=0)
    analyse_poses(f, R[:2000], t[:2000], detail=False)  # warm-up: imports, allocator
    batched = _time(lambda: analyse_poses(f, R, t, detail=False), 5)
    k = 500

    layout, cam, h = feature_layout(f), Camera(), parameter_scale(f)

    def loop() -> None:
        for i in range(k):
            pose_metrics(total_information(layout, cam, R[i:i + 1], t[i:i + 1]), h, layout.solver_rows)

    per_pose = _time(loop, 3) / k
    print(f"\n{n} workspace poses, whole-design metrics (detail=False)")
    print(f"  batched             {batched:8.3f} s   ({batched / n * 1e6:.1f} µs per pose)   target ≤ 1 s: "
          f"{'met' if batched <= 1.0 else 'NOT met'}")
    print(f"  per-pose loop       {per_pose * n:8.1f} s   ({per_pose * 1e6:.0f} µs per pose; timed on {k} poses, "
          f"extrapolated)")
    print(f"  per-pose / batched  {per_pose * n / batched:8.0f} ×")
    s = AnalysisSettings()
    t0 = time.perf_counter()
    score_design(f, s)
    t_score = time.perf_counter() - t0
    t0 = time.perf_counter()
    blind_spot_atlas(f, s)
    t_atlas = time.perf_counter() - t0
    print(f"\nscore_design, {s.poses} poses with groups, features and leave-one-out: {t_score:.2f} s")
    print(f"blind_spot_atlas, 2° sphere grid + workspace cone:                      {t_atlas:.2f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 50_000)
