"""Paper Table I: the *basic* algorithm (one local solve, Fig. 5) from random far guesses.

For each feature combination of the paper — 6P+3L+2E, 6P+2E, 6P+3L, 3L+2E, 6P, where 6P
are the six line end-point beads — N workspace images of ftrac_2005 with the paper's
default simulation errors (0.25 mm segmentation error, focal length ±2 mm, principal point
±0.5 mm, pixel size ±1 µm; paper §III.A) are solved once from a random initial guess far
from the truth: the true rotation turned by a random angle uniform in [0°, 90°] about a
random axis, the translation moved by up to ±20 mm across and ±100 mm along the beam.

A run fails when its rotation error exceeds 2° or its translation error 5 mm. Errors are
mean error norms over the runs that did not fail. Beside it, the robust solver (no initial
guess at all) on the same images.

Run: ``.venv/bin/python benchmarks/paper_table1.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine

from ftrac_design.pose import Camera, SolverOptions, refine_pose, so3, solve_batch
from ftrac_design.pose.simulate import PAPER_CALIBRATION_ERROR, Workspace, pose_errors, simulate_observation

PAPER = {  # translation (mm), rotation (deg), failures (%) — paper Table I
    "6P+3L+2E": (1.82, 0.89, 31.40),
    "6P+2E": (1.96, 1.16, 28.00),
    "6P+3L": (2.09, 1.24, 28.80),
    "3L+2E": (2.23, 0.98, 90.60),
    "6P": (2.48, 1.53, 27.00),
}
END_BEADS = {"B1", "B4", "B5", "B7", "B8", "B9"}  # the beads at the three lines' end-points
COMBOS = {
    "6P+3L+2E": END_BEADS | {"L1", "L2", "L3", "E1", "E2"},
    "6P+2E": END_BEADS | {"E1", "E2"},
    "6P+3L": END_BEADS | {"L1", "L2", "L3"},
    "3L+2E": {"L1", "L2", "L3", "E1", "E2"},
    "6P": END_BEADS,
}


def far_guess(R, t, rng):
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = np.radians(rng.uniform(0, 90))
    dt = np.array([rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-100, 100)])
    return so3.exp(axis * angle) @ R, t + dt


def main(n: int = 1000) -> None:
    features = load("ftrac_2005")
    ends = sorted(p.id for p in features.points if p.id in END_BEADS)
    assert len(ends) == 6, ends
    cam = Camera()
    rng = np.random.default_rng(1)
    R, t = Workspace().sample(n, features.nominal_beam_direction, rng)
    print(f"machine: {machine()}")
    print(f"{n} images per combination; basic = one local solve from a far random guess")
    print(
        f"{'features':10s} | {'paper: t mm':>11s} {'rot deg':>7s} {'fail %':>6s} | "
        f"{'basic: t mm':>11s} {'rot deg':>7s} {'fail %':>6s} | {'robust: t mm':>12s} {'rot deg':>7s} {'fail %':>6s}"
    )
    for name, keep in COMBOS.items():
        obs, guesses = [], []
        for i in range(n):
            solve_cam = PAPER_CALIBRATION_ERROR.draw(cam, rng)
            obs.append(simulate_observation(features, cam, R[i], t[i], 0.25, rng, include=keep, solve_camera=solve_cam))
            guesses.append(far_guess(R[i], t[i], rng))
        basic = [refine_pose(features, o, g[0], g[1], max_iterations=50) for o, g in zip(obs, guesses)]
        robust = solve_batch(features, obs, SolverOptions())
        row = [name, *PAPER[name]]
        for poses in (basic, robust):
            Re = np.array([p.rotation for p in poses])
            te = np.array([p.translation_mm for p in poses])
            ok_rows = np.all(np.isfinite(Re.reshape(n, -1)), 1)
            dr, dt = pose_errors(np.where(ok_rows[:, None, None], Re, np.eye(3)), np.nan_to_num(te), R, t)
            ang = np.degrees(np.linalg.norm(dr, axis=1))
            dist = np.linalg.norm(dt, axis=1)
            fail = ~ok_rows | (ang > 2.0) | (dist > 5.0)
            row += [
                dist[~fail].mean() if (~fail).any() else np.nan,
                ang[~fail].mean() if (~fail).any() else np.nan,
                100.0 * fail.mean(),
            ]
        print(
            f"{row[0]:10s} | {row[1]:11.2f} {row[2]:7.2f} {row[3]:6.1f} | {row[4]:11.2f} {row[5]:7.2f} "
            f"{row[6]:6.1f} | {row[7]:12.2f} {row[8]:7.2f} {row[9]:6.1f}"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1000)
