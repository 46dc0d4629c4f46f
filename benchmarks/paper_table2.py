"""Paper Table II: pose error per axis vs segmentation error, with the paper's C-arm errors.

For each segmentation error e in {0, 0.5, 1, 2, 3} mm (the paper's uniform-magnitude model),
N workspace images of ftrac_2005 are made with the true camera and solved — robustly, with
no initial guess — with a miscalibrated one: focal length ±2 mm, principal point ±0.5 mm,
pixel size ±1 µm, each uniform (paper §III.A). The solver is told the segmentation error
(its noise model; 0.1 mm floor at e = 0, where only calibration error remains).

Reported: mean absolute error per camera axis (translation mm; rotation as the components
of the error rotation vector, deg), for the default contour sampling (24 points per ellipse,
12 per line) and a dense one (96 / 48), beside the paper's numbers. The paper does not say
how many contour points it simulated, nor whether its figures are means or RMS.

Run: ``.venv/bin/python benchmarks/paper_table2.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine

from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_batch
from ftrac_design.pose.simulate import (
    PAPER_CALIBRATION_ERROR,
    ContourSampling,
    Workspace,
    pose_errors,
    simulate_observation,
)

PAPER = {  # e: (tx, ty, tz mm, rx, ry, rz deg) — paper Table II
    0.0: (0.18, 0.19, 0.75, 0.02, 0.02, 0.01),
    0.5: (0.19, 0.18, 0.79, 0.05, 0.06, 0.04),
    1.0: (0.19, 0.19, 0.79, 0.09, 0.11, 0.07),
    2.0: (0.22, 0.22, 0.98, 0.18, 0.22, 0.14),
    3.0: (0.26, 0.26, 1.24, 0.26, 0.32, 0.21),
}


def run(features, n, e, contour, rng):
    cam = Camera()
    R, t = Workspace().sample(n, features.nominal_beam_direction, rng)
    obs = [
        simulate_observation(
            features, cam, R[i], t[i], e, rng, contour=contour, solve_camera=PAPER_CALIBRATION_ERROR.draw(cam, rng)
        )
        for i in range(n)
    ]
    poses = solve_batch(features, obs, SolverOptions(noise=NoiseModel.from_segmentation_error(max(e, 0.1))))
    Re = np.array([p.rotation for p in poses])
    te = np.array([p.translation_mm for p in poses])
    finite = np.all(np.isfinite(Re.reshape(n, -1)), 1) & np.all(np.isfinite(te), 1)
    dr, dt = pose_errors(Re[finite], te[finite], R[finite], t[finite])
    flagged = sum(not p.converged for p in poses)
    return np.abs(dt).mean(0), np.degrees(np.abs(dr).mean(0)), flagged


def main(n: int = 2000) -> None:
    features = load("ftrac_2005")
    rng = np.random.default_rng(2)
    print(f"machine: {machine()}")
    print(f"{n} images per row; mean |error| per camera axis; flagged = reported not converged")
    head = "tx     ty     tz  |  rx     ry     rz"
    print(
        f"{'e mm':>5s} | {'paper: ' + head:42s} | {'ours, 24/12 contour points: ' + head:60s} | "
        f"{'ours, 96/48: ' + head}"
    )
    for e, paper in PAPER.items():
        cols = []
        for contour in (ContourSampling(24, 12), ContourSampling(96, 48)):
            tm, rm, flagged = run(features, n, e, contour, rng)
            cols.append(
                f"{tm[0]:.2f}  {tm[1]:.2f}  {tm[2]:.2f} | {rm[0]:.2f}  {rm[1]:.2f}  {rm[2]:.2f}  (flagged {flagged})"
            )
        p = paper
        print(
            f"{e:5.1f} | {p[0]:.2f}  {p[1]:.2f}  {p[2]:.2f} | {p[3]:.2f}  {p[4]:.2f}  {p[5]:.2f}"
            f"{'':10s} | {cols[0]:45s} | {cols[1]}"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2000)
