"""How ``ftrac-design optimize``'s evaluations scale over executors.

One fixed, seeded batch of candidates (``ftrac_mini``'s default layout space, unit points
drawn around the start with σ = 0.02; about half pass
the CNC rules and are scored at ``--poses`` workspace poses, the rest stop after the
rules) is evaluated:

- in this process, one after another: the **baseline**, the evaluation's own cost c₀;
- on a local process pool with 1 and 2 (``--workers``) processes;
- on an in-process Dask ``LocalCluster`` (``processes=False``, one thread per worker);
- with ``--scheduler tcp://HOST:8786``: on that Dask cluster as well (its worker threads).

For each: evaluations per second (best of ``--rounds``; pools are started and warmed up
before timing), the speed-up over the baseline, and the overhead per evaluation, two ways:
the round trip of a no-op task through the executor (submit → result, best of rounds),
and ``wall × workers / N − c₀`` (what an evaluation costs there beyond its own cost;
negative values mean noise or turbo). Every executor must return the same results as the
baseline (checked: design hashes and figures identical).

Run: ``.venv/bin/python benchmarks/optimize_scaling.py [--evaluations 96] [--poses 2000]
[--rounds 3] [--workers 1 2] [--scheduler tcp://HOST:8786] [--score-images N]``; with
``--score-images`` the feasible candidates are scored on the image-true score (rendered and tracked
images, :mod:`ftrac_design.imagescore`) instead. On a 16-core machine:
``--workers 1 2 4 8 16``; against a cluster, start ``dask scheduler`` and ``dask worker
tcp://HOST:8786 --nthreads 1 --nworkers 16`` (in the same environment) and pass
``--scheduler tcp://HOST:8786``.
"""

from __future__ import annotations

import argparse
import time
import tomllib

import numpy as np
from _common import machine

from ftrac_design.analysis.score import AnalysisSettings
from ftrac_design.design.presets import preset_path
from ftrac_design.optimize import EvalSettings, default_space, evaluate_candidate
from ftrac_design.optimize.execution import SerialExecutor, local_pool


def _noop(i: int) -> int:
    return i


def candidates(n: int, seed: int = 0) -> list[dict]:
    """``n`` candidate designs near the ftrac_mini preset (see module doc)."""
    base = tomllib.loads(preset_path("ftrac_mini").read_text())
    sp = default_space(base)
    rng = np.random.default_rng(seed)
    x0 = sp.start_unit()
    return [sp.candidate(np.clip(x0 + 0.02 * rng.standard_normal(sp.dim), 0, 1)) for _ in range(n)]


def run_batch(executor, cands, settings) -> tuple[float, list[dict]]:
    t = time.perf_counter()
    futs = [executor.submit(evaluate_candidate, c, settings) for c in cands]
    res = [f.result() for f in futs]
    return time.perf_counter() - t, res


def round_trip(executor, n: int = 50) -> float:
    t = time.perf_counter()
    for i in range(n):
        executor.submit(_noop, i).result()
    return (time.perf_counter() - t) / n


def key(results: list[dict]) -> list:
    return [(r["design_sha256"], r["feasible"], r["figures"]) for r in results]


def measure(name: str, executor, workers: int, cands, settings, rounds: int, c0: float | None, ref) -> dict:
    run_batch(executor, cands[: max(2, workers)], settings)  # warm up: every worker imported and cached
    walls, rts = [], []
    for _ in range(rounds):
        wall, res = run_batch(executor, cands, settings)
        walls.append(wall)
        rts.append(round_trip(executor))
        if ref is not None and key(res) != ref:
            raise SystemExit(f"{name}: results differ from the in-process baseline")
    wall = min(walls)
    n = len(cands)
    row = {
        "executor": name,
        "workers": workers,
        "wall_s": wall,
        "eval_per_s": n / wall,
        "round_trip_ms": 1e3 * min(rts),
        "rounds": [round(w, 3) for w in walls],
    }
    if c0 is not None:
        row["speedup"] = (n / wall) / (1 / c0)
        row["overhead_ms"] = 1e3 * (wall * workers / n - c0)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--evaluations", type=int, default=96)
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler address to measure too")
    ap.add_argument(
        "--score-images",
        type=int,
        default=0,
        help="score feasible candidates on this many rendered, tracked images per condition (the image-true "
        "score, as `optimize --score-images`) instead of the feature-level model",
    )
    args = ap.parse_args()
    print(f"machine: {machine()}")
    cands = candidates(args.evaluations)
    trial = None
    if args.score_images:
        from ftrac_design.imagescore import TrialSettings

        trial = TrialSettings(images=args.score_images)
    settings = EvalSettings(("cnc",), AnalysisSettings(poses=args.poses), image_trial=trial)
    base = measure("in-process (baseline)", SerialExecutor(), 1, cands, settings, args.rounds, None, None)
    ref = key(run_batch(SerialExecutor(), cands, settings)[1])
    c0 = base["wall_s"] / len(cands)
    feas = sum(k[1] for k in ref)
    print(
        f"{len(cands)} candidates, {feas} feasible (scored "
        + (f"on {args.score_images} rendered images per condition" if trial else f"at {args.poses} poses")
        + f"); own cost c0 = "
        f"{1e3 * c0:.1f} ms per evaluation (in-process, best of {args.rounds} rounds)"
    )
    rows = [dict(base, speedup=1.0, overhead_ms=0.0)]
    for w in args.workers:
        with local_pool(w) as pool:
            rows.append(measure("local processes", pool, w, cands, settings, args.rounds, c0, ref))
    from distributed import Client, LocalCluster

    nw = max(args.workers)
    with (
        LocalCluster(n_workers=nw, threads_per_worker=1, processes=False, dashboard_address=None) as cl,
        Client(cl) as client,
    ):
        rows.append(
            measure(
                "Dask LocalCluster (in-process threads)",
                client.get_executor(),
                nw,
                cands,
                settings,
                args.rounds,
                c0,
                ref,
            )
        )
    if args.scheduler:
        with Client(args.scheduler) as client:
            n = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
            rows.append(
                measure(
                    f"Dask cluster {args.scheduler}", client.get_executor(), n, cands, settings, args.rounds, c0, ref
                )
            )
    print(
        f"{'executor':40s} {'workers':>7s} {'eval/s':>8s} {'speed-up':>9s} {'overhead ms/eval':>17s} "
        f"{'no-op round trip ms':>20s}  rounds (s)"
    )
    for r in rows:
        print(
            f"{r['executor']:40s} {r['workers']:7d} {r['eval_per_s']:8.1f} {r['speedup']:9.2f} "
            f"{r['overhead_ms']:17.1f} {r['round_trip_ms']:20.2f}  {r['rounds']}"
        )
    print("every executor returned the baseline's results exactly")


if __name__ == "__main__":
    main()
