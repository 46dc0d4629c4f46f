"""How fast is a robust single-image solve, alone and in a batch?

Measured in-process on simulated images of ftrac_2005 (workspace poses, 0.25 mm
segmentation error, contours of 24 points per ellipse and 12 per line), side by side with
the baseline a user would write first: ``scipy.optimize.least_squares`` on the *same*
whitened residuals with a numeric (2-point) Jacobian, given the same closed-form start.
The paper's MATLAB took 3.5 s per image (§III.A.7).

Run: ``.venv/bin/python benchmarks/pose_speed.py``
"""

from __future__ import annotations

import time

import numpy as np
from _common import load, machine
from scipy.optimize import least_squares

from ftrac_design.pose import Camera, compile_problem, evaluate, so3, solve_batch, solve_pose
from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation
from ftrac_design.pose.solver import (
    SolverOptions,
    _finish_all,
    dlt_start,
    levenberg_marquardt,
    parameter_scale,
    refine_on_beads,
)

N_SINGLE = 300
N_BATCH = 1000
N_BASELINE = 100
ROUNDS = 3


def main() -> None:
    features = load("ftrac_2005")
    cam = Camera()
    rng = np.random.default_rng(2026)
    R, t = Workspace().sample(N_BATCH, features.nominal_beam_direction, rng)
    obs = [simulate_observation(features, cam, R[i], t[i], 0.25, rng) for i in range(N_BATCH)]

    for o in obs[:20]:  # warm caches and allocator
        solve_pose(features, o)
    # ROUNDS rounds of each measurement; the figure is the best round's. This machine is a
    # VM sharing its host: a slower round is interference from outside, not the code, and
    # every round is printed so the spread stays visible.
    single_rounds, batch_rounds = [], []
    for _ in range(ROUNDS):
        single = []
        for o in obs[:N_SINGLE]:
            t0 = time.perf_counter()
            p = solve_pose(features, o)
            single.append(time.perf_counter() - t0)
            assert p.converged, p.error
        single_rounds.append(np.array(single) * 1e3)
        t0 = time.perf_counter()
        poses = solve_batch(features, obs)
        batch_rounds.append((time.perf_counter() - t0) * 1e3 / N_BATCH)
        assert all(p.converged for p in poses)
    single = min(single_rounds, key=np.median)
    batch_ms = min(batch_rounds)

    # where a single solve spends its time: the phases of the closed-form path, one image at a time
    h, opts = parameter_scale(features), SolverOptions()
    phases = {
        "compile (contour fits)": [],
        "DLT start": [],
        "bead polish": [],
        "local solve (LM)": [],
        "checks + covariance": [],
    }
    for o in obs[:N_SINGLE]:
        marks = [time.perf_counter()]
        prob = compile_problem(features, [o])
        marks.append(time.perf_counter())
        R0, t0_ = dlt_start(prob)
        marks.append(time.perf_counter())
        R0, t0_ = refine_on_beads(prob, R0, t0_, h)
        marks.append(time.perf_counter())
        st = levenberg_marquardt(prob, R0, t0_, h, opts.max_iterations, eager=True)
        marks.append(time.perf_counter())
        _finish_all(prob, st, h, opts, 1)
        marks.append(time.perf_counter())
        for k, a, b in zip(phases, marks[:-1], marks[1:]):
            phases[k].append((b - a) * 1e3)

    # baseline: least_squares, numeric Jacobian, same residuals, same closed-form start
    base, agree = [], []
    for i in range(N_BASELINE):
        o = obs[i]
        t0 = time.perf_counter()
        prob = compile_problem(features, [o])
        R0, t0_ = dlt_start(prob)

        def fun(x, prob=prob, R0=R0):
            return evaluate(prob, so3.exp(x[None, :3]) @ R0, x[None, 3:], jac=False).rho[0]

        x0 = np.concatenate([np.zeros(3), t0_[0]])
        res = least_squares(
            fun, x0, jac="2-point", method="lm", x_scale=np.array([0.05] * 3 + [1.0] * 3), xtol=1e-12, ftol=1e-12
        )
        base.append(time.perf_counter() - t0)
        Rb = so3.exp(res.x[None, :3]) @ R0
        dr, dt = pose_errors(Rb[0], res.x[3:], poses[i].rotation, poses[i].translation_mm)
        agree.append((np.linalg.norm(dr), np.linalg.norm(dt)))
    base = np.array(base) * 1e3
    agree = np.array(agree)

    dr, dt = pose_errors(np.array([p.rotation for p in poses]), np.array([p.translation_mm for p in poses]), R, t)
    print(f"machine: {machine()}")
    print(f"images: ftrac_2005, {N_BATCH} workspace poses, 0.25 mm segmentation error")
    print(f"{'solver':52s} {'median ms':>10s} {'p90 ms':>8s}")
    print(f"{'ftrac_design robust solve, one image':52s} {np.median(single):10.3f} {np.percentile(single, 90):8.3f}")
    print(f"{'ftrac_design batch of 1000, amortised per image':52s} {batch_ms:10.3f} {'':>8s}")
    print(
        f"{'scipy least_squares, numeric Jacobian, same start':52s} {np.median(base):10.3f} "
        f"{np.percentile(base, 90):8.3f}"
    )
    print(f"{'paper (MATLAB 6.5, P4 2.4 GHz)':52s} {3500.0:10.1f}")
    print("phases of one solve (median ms): " + ", ".join(f"{k} {np.median(v):.3f}" for k, v in phases.items()))
    print(
        f"speed-up over the scipy baseline: single {np.median(base) / np.median(single):.1f}x, "
        f"batch {np.median(base) / batch_ms:.1f}x; over the paper: {3500 / np.median(single):.0f}x"
    )
    print(
        f"baseline reaches the same pose: max difference {np.degrees(agree[:, 0].max()):.1e} deg, "
        f"{agree[:, 1].max():.1e} mm"
    )
    print(
        f"rounds (best is reported): single medians {', '.join(f'{np.median(r):.3f}' for r in single_rounds)} ms; "
        f"batch {', '.join(f'{b:.3f}' for b in batch_rounds)} ms per image"
    )
    print(
        f"targets: single <= 2 ms: {'met' if np.median(single) <= 2 else 'NOT met'}; "
        f"batch <= 0.2 ms: {'met' if batch_ms <= 0.2 else 'NOT met'}"
    )
    print(
        f"(sanity) RMS error of the batch: translation {np.sqrt((dt**2).mean(0)).round(3)} mm, "
        f"rotation {np.degrees(np.sqrt((dr**2).mean(0))).round(3)} deg"
    )


if __name__ == "__main__":
    main()
