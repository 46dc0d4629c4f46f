"""Helpers of the reconstruction studies (study_fig7, study_turntable, study_reconstruction,
study_budget): the paper's C-arm error draws, batched simulate-and-solve, seeds.

All studies here use SIMULATED observations (:func:`ftrac_design.pose.simulate.simulate_observation`:
exact projections plus the paper's uniform-magnitude segmentation error), solved with the
robust solver and no initial guess — not rendered images through ``track``.
"""

from __future__ import annotations

import numpy as np
from _common import ROOT  # noqa: F401  (puts the repository on sys.path)

from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_batch
from ftrac_design.pose.simulate import simulate_observation

CAM = Camera()
#: the paper's default C-arm errors (§III.A): focal length ±2 mm, principal point 0.5 mm
#: (magnitude), pixel size ±1 µm
PAPER = {"focal_mm": 2.0, "origin_mm": 0.5, "pixel_mm": 0.001}


def draw_camera(
    rng: np.random.Generator, focal_mm: float, origin_mm: float, pixel_mm: float, camera: Camera = CAM
) -> Camera:
    """A miscalibrated camera in the paper's error model: focal length uniform in ±focal_mm;
    principal point moved by a magnitude uniform in [0, origin_mm] (mm at the detector) in a
    uniform direction; each pixel pitch uniform in ±pixel_mm."""
    mag, ang = rng.uniform(0.0, origin_mm), rng.uniform(0.0, 2 * np.pi)
    px = np.asarray(camera.pixel_size_mm)
    dpp = (mag * np.cos(ang) / px[0], mag * np.sin(ang) / px[1])
    return camera.perturbed(rng.uniform(-focal_mm, focal_mm), tuple(rng.uniform(-pixel_mm, pixel_mm, 2)), dpp)


def solve_images(features, R, t, e_mm, rng, solve_cameras=None, camera: Camera = CAM):
    """Simulate images at poses (n, 3, 3), (n, 3) with the true ``camera`` and solve them with
    ``solve_cameras`` (list, or None: the true one). Returns R_est, t_est (NaN where no pose
    was found), found (n,) bool, covariances (n, 6, 6) (NaN where none), the observations
    and how many found poses the solver flagged as not converged (e.g. residuals that misfit
    under a miscalibrated camera). Flagged poses are still scored, as in paper_table2.py:
    they are the answer the solver gives, and dropping them would hide calibration error."""
    n = len(R)
    obs = [
        simulate_observation(
            features, camera, R[i], t[i], e_mm, rng, solve_camera=None if solve_cameras is None else solve_cameras[i]
        )
        for i in range(n)
    ]
    poses = solve_batch(features, obs, SolverOptions(noise=NoiseModel.from_segmentation_error(max(e_mm, 0.1))))
    Re = np.array([p.rotation for p in poses], float)
    te = np.array([p.translation_mm for p in poses], float)
    ok = np.isfinite(Re).all((1, 2)) & np.isfinite(te).all(1)
    cov = np.array([p.covariance if p.covariance is not None else np.full((6, 6), np.nan) for p in poses])
    flagged = int(sum(not p.converged for p in poses) - (~ok).sum())
    return Re, te, ok, cov, obs, flagged


def seeds(rng: np.random.Generator, n: int, centre=(0.0, 130.0, 75.0), spread_mm: float = 20.0) -> np.ndarray:
    """``n`` seed positions (mm, F) uniform in a cube of side 2·spread about ``centre``: by
    default 15 cm from the fiducial origin toward the source and along the needles, where
    paper §IV puts the prostate."""
    return np.asarray(centre) + rng.uniform(-spread_mm, spread_mm, (n, 3))
