"""``ftrac-design solve``: the pose of the fiducial in each observed image (SPEC §5)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import InputError
from .options import (
    AT_LEAST_ONE,
    FILE,
    OUT_FILE,
    POSITIVE,
    features_option,
    optional_option,
    output_option,
    shown_option,
)


@click.command("solve")
@features_option()
@click.argument("observations", nargs=-1, required=True, type=FILE)
@output_option(
    "Where to write: pose.json for one observation, JSON Lines for several "
    "(default pose.json / poses.jsonl in the current directory; '-' for stdout).",
    type=OUT_FILE,
)
@shown_option(
    "--segmentation-error-mm",
    type=POSITIVE,
    default=0.25,
    help="Expected segmentation error (the paper's uniform error magnitude, mm at the detector); "
    "sets the relative weights and the noise scale's reference.",
)
@shown_option(
    "--distance",
    type=click.Choice(["sampson", "paper"]),
    default="sampson",
    help="Ellipse residual: first-order geometric (Sampson) or the paper's K·PᵀMP (Eq. 8).",
)
@shown_option(
    "--starts",
    type=AT_LEAST_ONE,
    default=96,
    help="Multi-start seeds used when no closed-form start is possible.",
)
@optional_option(
    "--estimate-intrinsics",
    type=click.Choice(["f", "f,o", "all"]),
    help="Estimate the C-arm intrinsics shared by all images with their poses (f: focal length at "
    "the given pixel pitch; f,o: and the principal point; all: fx, fy, ox, oy); refused (exit 1, "
    "poses solved with the given camera) where the images do not determine them. See "
    "ftrac_design.reconstruct.intrinsics.",
)
def command(
    features_path: Path,
    observations: tuple[Path, ...],
    output: Path | None,
    segmentation_error_mm: float,
    distance: str,
    starts: int,
    estimate_intrinsics: str | None,
) -> int:
    """Solve the 6-DOF pose for each observation (.json, or .jsonl with one per line).

    Writes SPEC §4 pose objects; exits 1 if any image could not be solved (its object says
    why in "error"), 2 on bad input (nothing is written).
    """
    from ..features import load_features
    from ..pose import NoiseModel, SolverOptions, read_observations, solve_batch
    from ..pose.io import write_poses

    features = load_features(features_path)
    obs = [o for path in observations for o in read_observations(path)]
    opts = SolverOptions(
        noise=NoiseModel.from_segmentation_error(segmentation_error_mm), distance=distance, starts=starts
    )
    if estimate_intrinsics is not None:
        return _solve_estimating_intrinsics(features, obs, opts, estimate_intrinsics, output)
    poses = solve_batch(features, obs, opts)
    several = len(obs) > 1 or any(p.suffix.lower() == ".jsonl" for p in observations)
    if output is None:
        output = Path("poses.jsonl" if several else "pose.json")
    if str(output) == "-":
        from ..pose.io import pose_lines

        sys.stdout.write(pose_lines(poses, several))
    else:
        try:
            write_poses(output, poses, jsonl=several)
        except OSError as exc:
            raise InputError(output, None, f"a writable output path ({exc.strerror})") from None
    failed = [p for p in poses if not p.converged]
    out = sys.stderr if str(output) == "-" else sys.stdout
    for p in poses:
        where = p.origin or "observation"
        if p.converged:
            t = p.translation_mm
            click.echo(
                f"{where}: t = ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) mm ± "
                f"({p.std_mm[0]:.2f}, {p.std_mm[1]:.2f}, {p.std_mm[2]:.2f}), "
                f"rms {p.rms_residual_px:.3f} px, {p.iterations} iterations",
                file=out,
            )
        else:
            click.echo(f"{where}: not solved: {p.error}", file=out)
    if str(output) != "-":
        click.echo(f"{len(poses) - len(failed)} of {len(poses)} solved; wrote {output}", file=out)
    return 1 if failed else 0


def _solve_estimating_intrinsics(features, observations, options, which: str, output) -> int:
    """``--estimate-intrinsics WHICH``: joint poses + intrinsics
    (:func:`ftrac_design.reconstruct.intrinsics.estimate`), written as JSON Lines (one SPEC §4
    object per image, the estimated camera under ``"camera"``, an extension); on refusal the
    poses solved with the given camera are written, the reason is printed, and the exit code is 1."""
    import json

    from ..fileio import write_output_text
    from ..reconstruct.intrinsics import PARAMETER_SETS, estimate

    est = estimate(features, observations, None, PARAMETER_SETS[which], options)
    text = "".join(json.dumps(d, allow_nan=False) + "\n" for d in est.pose_dicts())
    output = Path("poses.jsonl") if output is None else Path(output)
    out = write_output_text(output, text)
    if est.ok:
        c = est.camera
        sd = dict(zip(est.params, est.std))
        sx = c.pixel_size_mm[0]
        parts = [f"f = {c.focal_length_mm:.2f} mm" + (f" ± {sd['f'] * sx:.2f}" if "f" in sd else "")]
        if "fx" in sd:
            parts = [
                f"fx = {est.intrinsics[0]:.1f} ± {sd['fx']:.1f} px",
                f"fy = {est.intrinsics[1]:.1f} ± {sd['fy']:.1f} px",
            ]
        if "ox" in sd:
            parts.append(
                f"principal point = ({est.intrinsics[2]:.1f} ± {sd['ox']:.1f}, "
                f"{est.intrinsics[3]:.1f} ± {sd['oy']:.1f}) px"
            )
        click.echo(
            f"intrinsics from {len(est.solved)} images: " + ", ".join(parts) + f" (noise scale {est.noise_scale:.2f})",
            file=out,
        )
    else:
        click.echo(f"intrinsics not estimated: {est.reason}", file=sys.stderr)
    unsolved = sum(not p.converged for p in est.start)
    if str(output) != "-":
        click.echo(f"{len(est.start) - unsolved} of {len(est.start)} solved; wrote {output}", file=out)
    return 0 if est.ok and not unsolved else 1
