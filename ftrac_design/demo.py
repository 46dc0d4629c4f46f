"""``make demo`` / ``python -m ftrac_design.demo``: build the paper's fiducial and summarise:
score it, solve a synthetic observation, render a radiograph and track it from the image,
track a C-arm's DICOM run and an intensifier's distorted frame through the command line
(:mod:`ftrac_design.demo_carm`), reconstruct points from two views, run a tiny design search
and write the one-page report.

Each step is a small function returning a plain summary dict, and :func:`main` prints
them, so later steps (scoring, a solved synthetic image) slot in beside :func:`demo_build`.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from .design.presets import preset_path

#: the paper's fiducial, shipped with the package (ftrac_design/presets/)
DEFAULT_DESIGN = preset_path("ftrac_2005")


def _relative(path: str | Path) -> Path:
    path = Path(path)
    if path.is_absolute() and path.is_relative_to(Path.cwd()):
        return path.relative_to(Path.cwd())
    return path


def demo_build(
    design_path: str | Path = DEFAULT_DESIGN, out_dir: str | Path | None = None, profile: str = "cnc"
) -> dict[str, Any]:
    """Build ``design_path`` into ``out_dir`` (default ``outputs/<name>/``); return a summary."""
    from .cad.build import build_fiducial
    from .design import load_design

    design = load_design(_relative(design_path))  # features.json records the path as given
    result = build_fiducial(design, out_dir, profile=profile)
    m = result.manifest
    return {
        "design": design.name,
        "profile": profile,
        "out_dir": str(result.out_dir),
        "files": {name: info["bytes"] for name, info in m["files"].items()},
        "volumes_mm3": m["volumes_mm3"],
        "wire_length_mm": m["wires"]["total_length_mm"],
        "beads": m["beads"]["count"],
        "stl_volume_vs_brep": m["stl"]["volume_vs_brep"],
        "rules": m["manufacturing"]["rules"],
        "build_time_s": m["build_time_s"],
        "timings_s": m["timings_s"],
    }


def format_build(summary: dict[str, Any]) -> str:
    """A short human-readable block for :func:`demo_build`'s summary."""
    v = summary["volumes_mm3"]
    lines = [
        f"Built {summary['design']} ({summary['profile']} profile) in {summary['build_time_s']:.1f} s "
        f"-> {summary['out_dir']}/"
    ]
    for name, size in summary["files"].items():
        lines.append(f"  {name:<15} {size / 1024:9.1f} KiB")
    lines.append("  manifest.json   (parameters, sha256 of every file, volumes, timings)")
    lines.append(
        f"  volumes: body {v['body']:.1f} mm3 (blank {v['blank']:.1f}, grooves and pockets "
        f"{v['removed']:.1f}), wires {v['wires']:.2f}, beads {v['beads']:.2f}"
    )
    lines.append(
        f"  wire {summary['wire_length_mm']:.1f} mm in total, {summary['beads']} beads; "
        f"STL volume {summary['stl_volume_vs_brep']:+.3%} vs the exact solid"
    )
    r = summary["rules"]
    lines.append(
        f"  design rules ({summary['profile']}): {len(r['results'])} checked, "
        f"{len(r['violations'])} violated, {len(r['warnings'])} warning(s)"
        + "".join(f"\n    warn: {w}" for w in r["warnings"])
    )
    t = summary["timings_s"]
    lines.append(
        "  time: "
        + ", ".join(f"{k} {t[k]:.1f} s" for k in ("body", "export_body", "export_assembly", "render") if k in t)
    )
    return "\n".join(lines)


def demo_score(design_path: str | Path, out_dir: str | Path) -> dict[str, Any]:
    """Score the design over its workspace (``ftrac-design analyze``) into ``out_dir``: the
    image-true score on 50 images per condition and its atlas on a 45° grid, and the paper's model;
    returns the analysis.json object."""
    from .analysis.subject import load_subject, settings_for
    from .imagescore import TrialSettings
    from .imagescore.atlas import AtlasSettings
    from .optimize.execution import open_executor
    from .workflows.analyze import run_analysis

    subject = load_subject(design_path)
    settings, thresholds = settings_for(subject)
    with open_executor() as (executor, _):
        doc, _ = run_analysis(
            subject,
            settings,
            thresholds,
            Path(out_dir),
            trial=TrialSettings(images=50),
            executor=executor,
            image_atlas_settings=AtlasSettings(step_deg=45.0),
        )
    return doc


def format_score(doc: dict[str, Any], out_dir: str | Path) -> str:
    """The analysis summary, headed for the demo."""
    from .workflows.analyze import format_summary

    return (
        f"Scored over the workspace in {doc['time_s']:.1f} s -> {out_dir}/analysis.json, "
        + ", ".join(doc["files"])
        + "\n"
        + format_summary(doc)
    )


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

    from .features import load_features
    from .fileio import write_text_atomic
    from .pose import Camera, solve_pose
    from .pose.io import write_poses
    from .pose.simulate import Workspace, pose_errors, simulate_observation

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


def demo_track(features_path: str | Path, image_dir: str | Path) -> str:
    """Track ``image_dir/radiograph.png`` (written by the radiograph step; camera from the
    PNG's header) as a user would, with no initial guess, write the overlay beside it and
    return truth vs estimate (camera frame X: rotation error deg, translation mm)."""
    import time

    import numpy as np

    from .features import load_features
    from .images import read_image
    from .pose import Camera
    from .pose.simulate import pose_errors
    from .segment.overlay import draw_overlay
    from .segment.pipeline import track_image
    from .xray.truth import read_truth

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
    lines.append(f"  overlay: {_relative(png)}")
    return "\n".join(lines)


def image_and_beyond_steps(out_dir: Path) -> list:
    """The later demo steps (:mod:`ftrac_design.workflows.demo`), each a callable returning the
    text to print: the presets' image clearances, a radiograph of the built fiducial tracked
    from the image with no initial guess (overlay written), the pose refined on its pixels, a
    C-arm's Enhanced XA run and an intensifier's distorted frame tracked with ``ftrac-design
    track`` (``carm/``), 3-D reconstruction from two tracked views, a tiny design search, and
    the one-page report."""
    from .demo_carm import demo_step as carm_step
    from .workflows.demo.intensity import demo_step as intensity_step
    from .workflows.demo.optimize import demo_step as optimize_step
    from .workflows.demo.radiograph import demo_step as radiograph_step
    from .workflows.demo.reconstruct import demo_step as reconstruct_step
    from .workflows.demo.report import demo_step as report_step
    from .workflows.demo.segmentability import demo_step as segmentability_step

    image_dir = out_dir / "radiograph"
    return [
        lambda: segmentability_step(out_dir / "segmentability"),
        lambda: radiograph_step(image_dir),
        lambda: demo_track(out_dir / "features.json", image_dir),
        lambda: intensity_step(out_dir / "intensity"),
        lambda: carm_step(out_dir / "carm", out_dir / "features.json"),
        lambda: reconstruct_step(out_dir / "reconstruct"),
        lambda: optimize_step(out_dir / "optimize_demo"),
        lambda: report_step(out_dir),
    ]


def main(argv: list[str] | None = None) -> int:
    """Run every demo step and print its summary; returns the exit code."""
    from .errors import GoalError, InputError

    try:
        built = demo_build()
        print(format_build(built))
        print()
        score_dir = Path(built["out_dir"]) / "analysis"
        print(format_score(demo_score(_relative(DEFAULT_DESIGN), score_dir), score_dir))
        print()
        print(format_solve(demo_solve(Path(built["out_dir"]) / "features.json", Path(built["out_dir"]) / "synthetic")))
        for step in image_and_beyond_steps(Path(built["out_dir"])):
            print()
            print(step())
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except GoalError as exc:
        print(f"failed: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
