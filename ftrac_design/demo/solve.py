"""``make demo``'s solve step: one synthetic image of the built fiducial solved with no initial
guess, truth against estimate with the 1σ the pose reports.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def demo_solve(
    features_path: str | Path, out_dir: str | Path, segmentation_error_mm: float = 0.25, seed: int = 2005
) -> dict[str, Any]:
    """Simulate one image of the built fiducial at a random workspace pose, solve it with no
    initial guess, and write ``observation.json`` and ``pose.json`` into ``out_dir``.

    The image uses the paper's segmentation error model (uniform magnitude up to
    ``segmentation_error_mm`` at the detector, random direction) and the default camera
    (f = 1000 mm, 0.44 mm pixels). Returns truth, estimate and errors (camera frame X)."""
    import json

    import numpy as np

    from ..features import load_features
    from ..fileio import write_text_atomic
    from ..pose import Camera, solve_pose
    from ..pose.io import write_poses
    from ..pose.simulate import Workspace, pose_errors, simulate_observation

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    features = load_features(features_path)
    rng = np.random.default_rng(seed)
    R, t = Workspace().sample(1, features.nominal_beam_direction, rng)
    camera = Camera()
    obs = simulate_observation(features, camera, R[0], t[0], segmentation_error_mm, rng)
    write_text_atomic(out_dir / "observation.json", json.dumps(obs.to_dict(), indent=2) + "\n")
    pose = solve_pose(features, obs)
    write_poses(out_dir / "pose.json", [pose])
    rot_err, t_err = pose_errors(pose.rotation, pose.translation_mm, R[0], t[0])
    sd = np.sqrt(np.diag(pose.covariance)) if pose.covariance is not None else np.full(6, np.nan)
    beam = R[0][2]  # camera +z in F
    return {
        "segmentation_error_mm": segmentation_error_mm,
        "beam_off_nominal_deg": float(np.degrees(np.arccos(np.clip(beam @ features.nominal_beam_direction, -1, 1)))),
        "converged": pose.converged,
        "error": pose.error,
        "starts": pose.starts,
        "iterations": pose.iterations,
        "rms_residual_px": pose.rms_residual_px,
        "true_t_mm": t[0].tolist(),
        "est_t_mm": pose.translation_mm.tolist(),
        "t_err_mm": t_err.tolist(),
        "t_sd_mm": sd[3:].tolist(),
        "rot_err_deg": np.degrees(rot_err).tolist(),
        "rot_sd_deg": np.degrees(sd[:3]).tolist(),
        "files": [str(out_dir / "observation.json"), str(out_dir / "pose.json")],
    }


def format_solve(s: dict[str, Any]) -> str:
    """A short block for :func:`demo_solve`'s summary: truth vs estimate, with 1σ."""

    def v3(x, fmt="{:8.3f}"):
        return " ".join(fmt.format(a) for a in x)

    lines = [
        f"Solved one synthetic image ({s['segmentation_error_mm']} mm segmentation error, beam "
        f"{s['beam_off_nominal_deg']:.1f}° off AP), no initial guess: "
        f"{'converged' if s['converged'] else 'FAILED: ' + str(s['error'])}, "
        f"{s['starts']} start(s), {s['iterations']} iterations, RMS {s['rms_residual_px']:.3f} px",
        f"  translation (mm, x y z)  truth    {v3(s['true_t_mm'], '{:9.3f}')}",
        f"                           estimate {v3(s['est_t_mm'], '{:9.3f}')}",
        f"                           error    {v3(s['t_err_mm'], '{:9.3f}')}   (1σ {v3(s['t_sd_mm'], '{:.3f}')})",
        f"  rotation error (deg)              {v3(s['rot_err_deg'], '{:9.3f}')}   (1σ {v3(s['rot_sd_deg'], '{:.3f}')})",
        "  wrote " + ", ".join(s["files"]),
    ]
    return "\n".join(lines)


def demo_step(features_path: str | Path, out_dir: str | Path) -> str:
    """Solve one synthetic image of ``features_path`` into ``out_dir``; the text the demo prints.

    Parameters
    ----------
    features_path : str or pathlib.Path
        The built ``features.json``.
    out_dir : str or pathlib.Path
        Where ``observation.json`` and ``pose.json`` go.

    Returns
    -------
    str
        Truth against estimate (:func:`format_solve`).
    """
    return format_solve(demo_solve(features_path, out_dir))
