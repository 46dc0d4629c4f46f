"""``demo_step``: render one radiograph of the default fiducial, track it, compare."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def demo_step(out_dir: Path, seed: int = 7) -> str:
    """Render ``ftrac_2005`` at a random workspace pose (the xray simulator, default imaging
    model), track the raw image with no initial guess, write ``track_overlay.png`` into
    ``out_dir`` and return the text to print: truth vs estimate."""
    from ..design import load_design
    from ..design.presets import preset_path
    from ..features import compute_features
    from ..pose import Camera
    from ..pose.simulate import Workspace, pose_errors
    from ..xray import Body, render
    from .overlay import draw_overlay
    from .pipeline import track_image

    design = load_design(preset_path("ftrac_2005"))
    features = compute_features(design)
    body = Body.from_design(design)
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(seed))
    rad = render(features, R[0], t[0], Camera(), rng=np.random.default_rng(seed), body=body)
    res = track_image(rad.raw, features, Camera(), body=body)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    png = draw_overlay(out_dir / "track_overlay.png", rad.raw, features, res, title="ftrac_2005, simulated raw image")
    p = res.pose
    lines = ["track: ftrac_2005 radiograph at a workspace pose (default imaging model), no initial guess"]
    lines.append(f"  truth     t = ({t[0][0]:.2f}, {t[0][1]:.2f}, {t[0][2]:.2f}) mm")
    if np.all(np.isfinite(p.rotation)):
        dr, dt = pose_errors(p.rotation, p.translation_mm, R[0], t[0])
        tt = p.translation_mm
        lines.append(f"  estimate  t = ({tt[0]:.2f}, {tt[1]:.2f}, {tt[2]:.2f}) mm ± "
                     f"({p.std_mm[0]:.3f}, {p.std_mm[1]:.3f}, {p.std_mm[2]:.3f}), converged {p.converged}")
        lines.append(f"  error     rotation {np.degrees(np.linalg.norm(dr)):.3f}°, translation "
                     f"({dt[0]:+.3f}, {dt[1]:+.3f}, {dt[2]:+.3f}) mm")
    if not p.converged:
        lines.append(f"  not converged: {p.error}")
    lines.append(f"  overlay: {png}")
    return "\n".join(lines)
