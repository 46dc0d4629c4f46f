"""Do the analysis's predicted errors come true? Predicted vs the solver's Monte-Carlo errors.

For each preset, N workspace poses (default 1,000), one simulated image each at 0.25 mm
segmentation error (the paper's model: uniform magnitude, random direction — its per-axis
σ = e/√6 is the analysis's noise model), default contour sampling, perfect calibration;
each image solved by the robust solver with no initial guess. Per axis (translation
x, y, z mm and rotation about x, y, z, camera axes) the Monte-Carlo RMS error is compared
with the predicted RMS — the root of the mean predicted variance from
:func:`ftrac_design.analysis.analyse_poses` at the same poses. Target: every
ratio predicted / actual within 20 % (0.8–1.25). With N = 1,000 the RMS itself carries
about ±4.5 % (1σ) of sampling error.

Run: ``.venv/bin/python benchmarks/analysis_validation.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine

from ftrac_design.analysis import analyse_poses
from ftrac_design.analysis.sampling import workspace_poses
from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_batch
from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation

E_MM = 0.25
AXES = ("tx mm", "ty mm", "tz mm", "rx °", "ry °", "rz °")


def validate(name: str, n: int, seed: int = 5) -> bool:
    """Print the comparison for one preset; True when every axis is within 20 %."""
    f = load(name)
    cam = Camera()
    noise = NoiseModel.from_segmentation_error(E_MM)
    R, t = workspace_poses(Workspace(), f.nominal_beam_direction, n, seed)
    rng = np.random.default_rng(seed + 1)
    obs = [simulate_observation(f, cam, R[i], t[i], E_MM, rng) for i in range(n)]
    poses = solve_batch(f, obs, SolverOptions(noise=noise))
    ok = np.array([p.converged for p in poses])
    Re = np.array([p.rotation if p.converged else np.eye(3) for p in poses])
    te = np.array([p.translation_mm if p.converged else np.zeros(3) for p in poses])
    dr, dt = pose_errors(Re, te, R, t)
    err = np.concatenate([dt, np.degrees(dr)], 1)[ok]
    actual = np.sqrt(np.mean(err**2, 0))
    m = analyse_poses(f, R, t, cam, noise, detail=False).overall
    pred_sd = np.concatenate([m.translation_std_mm, np.degrees(m.rotation_std_rad)], 1)[ok]
    predicted = np.sqrt(np.mean(pred_sd**2, 0))
    ratio = predicted / actual
    # share of errors inside the predicted ±1σ per axis (0.683 if Gaussian)
    inside = np.mean(np.abs(err) <= pred_sd, 0)
    passed = bool(np.all((ratio >= 0.8) & (ratio <= 1.25)))
    print(f"\n{name}: {n} images, {int(ok.sum())} solved, segmentation error {E_MM} mm")
    print(f"{'axis':8s} {'predicted RMS':>14s} {'actual RMS':>11s} {'pred/actual':>12s} {'within ±1σ':>11s}")
    for i, ax in enumerate(AXES):
        print(f"{ax:8s} {predicted[i]:14.4f} {actual[i]:11.4f} {ratio[i]:12.3f} {inside[i]:11.3f}")
    print(f"every axis within 20 %: {'yes' if passed else 'NO'}")
    return passed


def main(n: int = 1000) -> None:
    print(f"machine: {machine()}")
    results = [validate(name, n) for name in ("ftrac_2005", "ftrac_mini", "nine_bead")]
    print(f"\nall presets within 20 %: {'yes' if all(results) else 'NO'}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1000)
