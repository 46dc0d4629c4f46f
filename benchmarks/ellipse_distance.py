"""What the paper's ellipse distance and diagonal weighting cost in accuracy.

The paper measures a projected model point's distance to the observed conic as K·PᵀMP
(Eq. 8: the algebraic value scaled by one constant per ellipse) and weights every distance
by 1/σ (its fallback task scaling G). We measure it with Sampson's first-order distance
Q/|∇Q| and whiten by each fitted curve's covariance (Gauss–Markov G). All four
combinations, on the same N workspace images of ftrac_2005, no initial guess, perfect
calibration; efficiency = CRLB variance / MSE per axis (1 is the best any unbiased
estimator can do).

Run: ``.venv/bin/python benchmarks/ellipse_distance.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine
from pose_accuracy import crlb

from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_batch
from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation

VARIANTS = [
    ("Sampson distance, Gauss-Markov G (ours)", "sampson", "gauss-markov"),
    ("Sampson distance, diagonal G", "sampson", "diagonal"),
    ("K·PᵀMP (Eq. 8), Gauss-Markov G", "paper", "gauss-markov"),
    ("K·PᵀMP (Eq. 8), diagonal G (the paper)", "paper", "diagonal"),
]


def main(n: int = 2000) -> None:
    features = load("ftrac_2005")
    cam = Camera()
    print(f"machine: {machine()}")
    for e in (0.25, 1.0):
        rng = np.random.default_rng(3)
        R, t = Workspace().sample(n, features.nominal_beam_direction, rng)
        obs = [simulate_observation(features, cam, R[i], t[i], e, rng) for i in range(n)]
        noise = NoiseModel.from_segmentation_error(e)
        bound = crlb(features, cam, R, t) * (e / 0.25) ** 2  # crlb() uses the default 0.25 mm model
        print(f"\n{n} images, segmentation error {e} mm; RMS error and efficiency (CRLB var / MSE)")
        print(
            f"{'variant':42s} {'tz mm':>7s} {'rx deg':>7s} | {'eff tx':>6s} {'ty':>5s} {'tz':>5s} "
            f"{'rx':>5s} {'ry':>5s} {'rz':>5s} | not converged"
        )
        print(f"{'Cramér–Rao bound':42s} {np.sqrt(bound[5]):7.3f} {np.degrees(np.sqrt(bound[0])):7.3f} |")
        for name, distance, scaling in VARIANTS:
            poses = solve_batch(features, obs, SolverOptions(noise=noise, distance=distance, task_scaling=scaling))
            dr, dt = pose_errors(
                np.array([p.rotation for p in poses]), np.array([p.translation_mm for p in poses]), R, t
            )
            mse = np.concatenate([(dr**2).mean(0), (dt**2).mean(0)])
            eff = bound / mse
            print(
                f"{name:42s} {np.sqrt(mse[5]):7.3f} {np.degrees(np.sqrt(mse[0])):7.3f} | "
                f"{eff[3]:6.3f} {eff[4]:5.3f} {eff[5]:5.3f} {eff[0]:5.3f} {eff[1]:5.3f} {eff[2]:5.3f} | "
                f"{sum(not p.converged for p in poses)}"
            )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2000)
