"""The optimiser's winner checked away from the search: fresh workspace poses for the
predicted figures, and the pose solver on simulated observations (Monte Carlo) for the errors
it actually makes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..analysis.score import AnalysisSettings


def verify(data: dict, settings: AnalysisSettings, poses: int, images: int, seed: int) -> dict:
    """Re-score ``data`` on ``poses`` fresh workspace poses (seed ``seed``) and solve
    ``images`` simulated images (seed ``seed + 1``) with the robust solver, no initial guess.

    Returns the predicted p95/worst 1σ errors on the fresh poses and the Monte-Carlo
    errors: RMS and p95 of the 3-D translation (mm) and rotation (°) errors, how many solved.
    """
    from ..analysis.poses import analyse_poses
    from ..analysis.sampling import workspace_poses
    from ..design.loader import parse_design
    from ..features import compute_features
    from ..pose import SolverOptions, solve_batch
    from ..pose.simulate import pose_errors, simulate_observation
    from .evaluate import score_figures

    design = parse_design(data)
    settings = settings.for_parts(design.analysis)  # its own parts' segmentation errors
    f = compute_features(design)
    fresh = score_figures(f, replace(settings, poses=poses, seed=seed))
    out = {"poses": poses, "pose_seed": seed, "predicted": fresh}
    if images:
        R, t = workspace_poses(settings.workspace, f.nominal_beam_direction, images, seed + 1)
        rng = np.random.default_rng(seed + 2)
        obs = [
            simulate_observation(
                f,
                settings.camera,
                R[i],
                t[i],
                settings.segmentation_error_mm,
                rng,
                error_factors=settings.error_factors,
            )
            for i in range(images)
        ]
        sol = solve_batch(f, obs, SolverOptions(noise=settings.noise))
        ok = np.array([p.converged for p in sol])
        Re = np.array([p.rotation if p.converged else np.eye(3) for p in sol])
        te = np.array([p.translation_mm if p.converged else np.zeros(3) for p in sol])
        dr, dt = pose_errors(Re, te, R, t)
        et = np.linalg.norm(dt, axis=1)[ok]
        er = np.degrees(np.linalg.norm(dr, axis=1))[ok]
        # the bound at the same poses: the solver should attain it (efficiency ≈ 1)
        m = analyse_poses(f, R, t, settings.camera, settings.noise, settings.contour, detail=False).overall
        pt = float(np.sqrt(np.mean(m.translation_rms_mm[ok] ** 2)))
        pr = float(np.sqrt(np.mean(m.rotation_rms_deg[ok] ** 2)))
        out["solver"] = {
            "images": images,
            "solved": int(ok.sum()),
            "image_seed": seed + 1,
            "translation_rms_mm": float(np.sqrt(np.mean(et**2))),
            "translation_p95_mm": float(np.percentile(et, 95)),
            "rotation_rms_deg": float(np.sqrt(np.mean(er**2))),
            "rotation_p95_deg": float(np.percentile(er, 95)),
            "predicted_translation_rms_mm": pt,
            "predicted_rotation_rms_deg": pr,
        }
    return out
