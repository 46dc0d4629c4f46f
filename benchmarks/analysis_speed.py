"""Speed of the conditioning analysis: 50,000 workspace poses of ftrac_2005
(target ≤ 1 s on the 2-core machine).

Timed: :func:`ftrac_design.analysis.analyse_poses` with ``detail=False`` — the information
of the whole design (the solver's whitened Jacobian rows), the scaled singular values,
condition number, observability indices and Cramér–Rao standard deviations at every pose.
Median of 5 runs after a warm-up, in-process; the fastest and slowest run are printed too
because two cores shared with anything else make single runs noisy.

Baselines in the same run, each timed on 500 poses and extrapolated to N (the output says
so — a full per-pose run would take minutes):

- *per-pose API loop*: ``analyse_poses`` called on a batch of one pose, N times — what a
  caller without the batched path would write;
- *per-pose kernel loop*: the same information and metrics on one pose at a time with the
  feature sampling and parameter scaling hoisted out of the loop (no per-call set-up, no
  thread pool) — the stricter baseline, isolating what batching itself buys.

For information, one full ``score_design`` (20,000 poses with every group, feature and
leave-one-out set) and one ``blind_spot_atlas`` (2° sphere grid + workspace cone).

Run: ``.venv/bin/python benchmarks/analysis_speed.py [N]``
"""

from __future__ import annotations

import statistics
import sys
import time

from _common import load, machine

from ftrac_design.analysis import (
    AnalysisSettings,
    analyse_poses,
    blind_spot_atlas,
    feature_layout,
    pose_metrics,
    score_design,
    total_information,
)
from ftrac_design.analysis.sampling import workspace_poses
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.pose.solver import parameter_scale

LOOP_POSES = 500


def _runs(fn, repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def main(n: int = 50_000) -> None:
    f = load("ftrac_2005")
    print(f"machine: {machine()}")
    R, t = workspace_poses(Workspace(), f.nominal_beam_direction, n, seed=0)
    analyse_poses(f, R[:2000], t[:2000], detail=False)  # warm-up: imports, allocator, BLAS threads
    runs = _runs(lambda: analyse_poses(f, R, t, detail=False), 5)
    batched = statistics.median(runs)

    k = min(LOOP_POSES, n)

    def api_loop() -> None:
        for i in range(k):
            analyse_poses(f, R[i : i + 1], t[i : i + 1], detail=False)

    layout, cam, h = feature_layout(f), Camera(), parameter_scale(f)

    def kernel_loop() -> None:
        for i in range(k):
            pose_metrics(total_information(layout, cam, R[i : i + 1], t[i : i + 1]), h, layout.solver_rows)

    api = statistics.median(_runs(api_loop, 3)) / k
    kernel = statistics.median(_runs(kernel_loop, 3)) / k

    print(f"\n{n} workspace poses, whole-design metrics (detail=False)")
    print(
        f"  batched analyse_poses   {batched:8.3f} s   ({batched / n * 1e6:.1f} µs per pose; median of 5, "
        f"runs {min(runs):.3f}–{max(runs):.3f} s)   target ≤ 1 s: {'met' if batched <= 1.0 else 'NOT met'}"
    )
    print(
        f"  per-pose API loop       {api * n:8.1f} s   ({api * 1e6:.0f} µs per pose; timed on {k} poses, "
        f"extrapolated to {n})"
    )
    print(
        f"  per-pose kernel loop    {kernel * n:8.1f} s   ({kernel * 1e6:.0f} µs per pose; timed on {k} poses, "
        f"extrapolated to {n})"
    )
    print(f"  API loop / batched      {api * n / batched:8.0f} ×")
    print(f"  kernel loop / batched   {kernel * n / batched:8.0f} ×")

    s = AnalysisSettings()
    t0 = time.perf_counter()
    score_design(f, s)
    t_score = time.perf_counter() - t0
    t0 = time.perf_counter()
    blind_spot_atlas(f, s)
    t_atlas = time.perf_counter() - t0
    print(f"\n{f'score_design, {s.poses} poses with groups, features and leave-one-out (once):':78s} {t_score:.2f} s")
    print(f"{'blind_spot_atlas, 2° sphere grid + workspace cone (once):':78s} {t_atlas:.2f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 50_000)
