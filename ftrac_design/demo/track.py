"""``make demo``'s track step: the radiograph step's image tracked as a user would, with no
initial guess, and its overlay.
"""

from __future__ import annotations

from pathlib import Path

from .shell import relative


def demo_step(features_path: str | Path, image_dir: str | Path) -> str:
    """Track ``image_dir/radiograph.png`` (written by the radiograph step; camera from the
    PNG's header) as a user would, with no initial guess, write the overlay beside it and
    return truth vs estimate (camera frame X: rotation error deg, translation mm)."""
    import time

    import numpy as np

    from ..features import load_features
    from ..images import read_image
    from ..pose import Camera
    from ..pose.simulate import pose_errors
    from ..segment.overlay import draw_overlay
    from ..segment.pipeline import track_image
    from ..xray.truth import read_truth

    image_dir = Path(image_dir)
    features = load_features(features_path)
    image, _, meta = read_image(image_dir / "radiograph.png")
    c = meta["camera"]  # our writer notes the camera in the PNG's text chunk
    camera = Camera(float(c["focal_length_mm"]), tuple(c["pixel_size_mm"]), tuple(c["principal_point_px"]))
    truth = read_truth(image_dir / "radiograph.truth.json")
    R = np.asarray(truth["pose"]["rotation"], float)
    t = np.asarray(truth["pose"]["translation_mm"], float)
    t0 = time.perf_counter()
    res = track_image(image, features, camera, polarity_hint=meta.get("polarity_hint"))
    ms = (time.perf_counter() - t0) * 1e3
    png = draw_overlay(
        image_dir / "track_overlay.png", image, features, res, title="ftrac_2005: radiograph.png tracked"
    )
    p = res.pose
    lines = [
        f"track: radiograph.png -> pose with no initial guess in {ms:.0f} ms: "
        + ("converged" if p.converged else f"NOT converged ({p.error})")
    ]
    lines.append(f"  truth     t = ({t[0]:8.3f}, {t[1]:8.3f}, {t[2]:8.3f}) mm")
    if np.all(np.isfinite(p.rotation)):
        dr, dt = pose_errors(p.rotation, p.translation_mm, R, t)
        e, s = p.translation_mm, p.std_mm
        lines.append(
            f"  estimate  t = ({e[0]:8.3f}, {e[1]:8.3f}, {e[2]:8.3f}) mm   (1σ {s[0]:.3f}, {s[1]:.3f}, {s[2]:.3f})"
        )
        lines.append(
            f"  error     translation ({dt[0]:+.3f}, {dt[1]:+.3f}, {dt[2]:+.3f}) mm, "
            f"rotation {np.degrees(np.linalg.norm(dr)):.3f}°"
        )
    lines.append(f"  overlay: {relative(png)}")
    return "\n".join(lines)
