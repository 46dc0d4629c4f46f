"""``ftrac-design reconstruct``: 3-D points from several tracked images (SPEC §5; format in
:mod:`ftrac_design.reconstruct.io`)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .options import FILE as _FILE
from .options import (
    NON_NEGATIVE,
    OUT_FILE,
    POSITIVE,
    camera_option,
    features_option,
    optional_option,
    output_option,
    shown_option,
)


@click.command("reconstruct")
@features_option("features.json (its frames.template_from_fiducial gives the template frame).")
@click.option(
    "--poses",
    "poses_path",
    required=True,
    type=_FILE,
    help="JSON Lines of SPEC §4 poses, one per image (e.g. from `ftrac-design solve`/`track`).",
)
@click.option(
    "--points",
    "points_path",
    required=True,
    type=_FILE,
    help="JSON Lines, one {id: [u, v]} object per image, in the order of --poses.",
)
@camera_option(
    'SPEC §3 camera object for every image; overrides a "camera" key in a pose or points '
    "line (an extension of SPEC §4/§5)."
)
@shown_option(
    "--to",
    "to",
    type=click.Choice(["fiducial", "template"]),
    default="fiducial",
    help="Output frame: F, or the template frame T through features.json's template_from_fiducial.",
)
@optional_option(
    "--transform",
    "transform_path",
    type=_FILE,
    help="A further rigid 4x4 from the --to frame (e.g. template -> ultrasound): a list of 4 rows, or "
    '{"matrix": …, "name": …, "covariance": 6x6}; applied last.',
)
@optional_option(
    "--noise-px",
    type=POSITIVE,
    help="Image-point noise, pixels per axis [default: 0.102 mm at the detector, the paper's "
    "0.25 mm uniform segmentation error, in each image's pixels].",
)
@shown_option(
    "--min-parallax-deg",
    type=NON_NEGATIVE,
    default=2.0,
    help="Refuse a point whose widest angle between two views' rays is below this.",
)
@shown_option(
    "--template-sigma-mm",
    type=NON_NEGATIVE,
    default=0.0,
    help="Machining tolerance of the template connector, σ mm per axis, added to the uncertainty with --to template.",
)
@output_option(
    "Where to write the ftrac-reconstruction JSON ('-' for stdout).",
    type=OUT_FILE,
    default=Path("reconstruction.json"),
    show_default=True,
)
def command(
    features_path: Path,
    poses_path: Path,
    points_path: Path,
    camera_path: Path | None,
    to: str,
    transform_path: Path | None,
    noise_px: float | None,
    min_parallax_deg: float,
    template_sigma_mm: float,
    output: Path,
) -> int:
    """Triangulate the labelled points of several tracked images into 3-D, with covariances.

    Each point seen in ≥ 2 images from views at least --min-parallax-deg apart is placed by
    maximum likelihood (linear start, Gauss–Newton on the reprojection error, the poses'
    covariances counted as extra image noise) and reported in the --to frame (then through
    --transform); the others are listed with the reason they were refused. Exits 1 if no
    point could be reconstructed, 2 on bad input (nothing is written).
    """
    from ..features import load_features
    from ..fileio import write_output_text
    from ..pose.observation import read_camera
    from ..reconstruct.io import read_points, read_poses, read_transform
    from ..reconstruct.pipeline import reconstruct

    features = load_features(features_path)
    poses = read_poses(poses_path)
    points = read_points(points_path)
    camera = read_camera(camera_path) if camera_path is not None else None
    transform = read_transform(transform_path, to) if transform_path is not None else None
    result = reconstruct(
        features,
        poses,
        points,
        camera,
        to,
        transform,
        noise_px,
        min_parallax_deg,
        template_sigma_mm,
        str(poses_path),
        str(points_path),
        str(features_path),
    )
    text = json.dumps(result, indent=2, allow_nan=False) + "\n"
    out = write_output_text(output, text)
    for s in result["images_skipped"]:
        click.echo(f"image {s['index']}: not used: {s['reason']}", file=out)
    for pid, e in result["points"].items():
        if "refused" in e:
            click.echo(f"{pid}: refused: {e['refused']}", file=out)
        else:
            p, s = e["position_mm"], e["std_mm"]
            click.echo(
                f"{pid}: ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) mm ± ({s[0]:.2f}, {s[1]:.2f}, {s[2]:.2f}) "
                f"in {e['frame']}, {len(e['views'])} views, rms {e['rms_reprojection_px']:.3f} px",
                file=out,
            )
    msg = f"{result['reconstructed']} of {len(result['points'])} points reconstructed"
    click.echo(msg + ("" if str(output) == "-" else f"; wrote {output}"), file=out)
    return 0 if result["reconstructed"] else 1
