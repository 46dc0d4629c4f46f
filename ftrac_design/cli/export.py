"""``ftrac-design export``: poses and points as 3D Slicer, ITK and PLUS read them, and a whole
Slicer scene of a tracked run.

Plumbing only; the formats and their conventions are :mod:`ftrac_design.igt` (.tfm,
.mrk.json, .seq.mha, the scene).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import click

from ..errors import InputError
from .options import COUNT, DIR, FILE, OUT_FILE, features_option, link_options, optional_option, output_option

ExportFormat = Literal["tfm", "mrk", "mha"]
#: output suffix → format
SUFFIXES: dict[str, ExportFormat] = {".tfm": "tfm", ".mrk.json": "mrk", ".seq.mha": "mha", ".mha": "mha"}
#: what a .seq.nrrd output is told: Slicer would not load it as what it is
NRRD_REFUSED = (
    "an output ending .tfm, .mrk.json or .seq.mha: 3D Slicer reads a .seq.nrrd as a sequence of images or "
    "grid transforms, not of linear transforms; write the run as .seq.mha (Slicer's and PLUS's)"
)


def _format_of(output: Path, fmt: str | None) -> ExportFormat:
    if fmt is not None:
        return fmt  # type: ignore[return-value]
    name = output.name.lower()
    if name.endswith(".nrrd"):
        raise InputError(output, None, NRRD_REFUSED, parameter="output")
    for suffix, f in SUFFIXES.items():
        if name.endswith(suffix):
            return f
    raise InputError(
        output, None, "an output ending .tfm, .mrk.json or .seq.mha (or give --format)", parameter="output"
    )


def _export_markups(input_path: Path, output: Path) -> None:
    from ..igt.markups import points_from_file, write_markups

    points, frame = points_from_file(input_path)
    write_markups(output, points, Path(input_path).stem, f"{frame} frame, LPS mm")
    click.echo(f"wrote {output}: {len(points)} points ({frame} frame, LPS)")


def _export_tfm(input_path: Path, output: Path, index: int | None, name: str) -> None:
    from ..igt.frames import pose_matrix
    from ..igt.tfm import write_tfm
    from ..pose import read_tracked_poses

    poses = read_tracked_poses(input_path)
    if index is None and len(poses) > 1:
        raise InputError(input_path, None, f"one pose, or --index K to pick one of its {len(poses)}", parameter="index")
    k = index or 0
    if k >= len(poses):
        raise InputError(
            input_path, None, f"at least {k + 1} poses for --index {k}, got {len(poses)}", parameter="index"
        )
    p = poses[k].pose
    if not p.converged:
        why = p.error or "converged: false"
        raise InputError(poses[k].source, "converged", f"a solved pose to export, got none ({why})")
    write_tfm(output, pose_matrix(p.rotation, p.translation_mm), name, note=f"from {poses[k].source}")
    click.echo(f"wrote {output}: {name} from {poses[k].source}")


def _export_sequence(input_path: Path, output: Path, name: str, space: str) -> None:
    from ..igt.frames import in_space, pose_matrix
    from ..igt.sequence import SequenceFrame, write_sequence
    from ..pose import read_tracked_poses

    poses = read_tracked_poses(input_path)
    frames = [
        SequenceFrame(
            in_space(pose_matrix(p.pose.rotation, p.pose.translation_mm), space) if p.pose.converged else None,
            p.provenance.time_s if p.provenance.time_s is not None else float(k),
        )
        for k, p in enumerate(poses)
    ]
    write_sequence(output, frames, name, "mha", space)
    ok = sum(p.pose.converged for p in poses)
    click.echo(f"wrote {output}: {len(poses)} frames ({ok} OK, {len(poses) - ok} INVALID), {name}, {space.upper()}")


def _export_scene(input_path: Path, scene: Path, features: Path | None, model: Path | None, name: str) -> None:
    from ..workflows.scene import write_scene

    if features is None:
        raise InputError(
            None,
            None,
            "the fiducial's features.json (its beads; its build's fiducial.stl beside it)",
            parameter="features",
        )
    result = write_scene(input_path, scene, features, model, name)
    click.echo(
        f"wrote {result.scene_file}: the fiducial's model, {result.beads} beads and {result.frames} frames of "
        f"{name} ({result.left_out} without a pose left out); open it in 3D Slicer and play the browser "
        f"{result.run_name!r}"
    )


@click.command("export")
@click.argument("input_path", metavar="INPUT", type=FILE)
@output_option("The file to write; its suffix picks the format: .tfm, .mrk.json, .seq.mha.", type=OUT_FILE)
@optional_option(
    "--scene",
    "scene_dir",
    type=DIR,
    help="Instead of -o: a 3D Slicer scene folder (scene.mrml, the model, the beads, the run and a sequence "
    "browser) of the run INPUT; needs --features.",
)
@features_option(
    "--scene: the build's features.json (the beads); the model is fiducial.stl beside it unless --model.",
    required=False,
    default=None,
)
@optional_option(
    "--model",
    "model_path",
    type=FILE,
    help="--scene: the fiducial's STL in F (default: fiducial.stl beside --features, as `build` writes it).",
)
@optional_option(
    "--format", "fmt", type=click.Choice(["tfm", "mrk", "mha"]), help="The format, when the suffix does not say."
)
@optional_option(
    "--index",
    type=COUNT,
    help=".tfm from a JSON Lines run: the 0-based line of the pose to write (required for a run).",
)
@link_options(
    "Sequence files: the matrices' coordinates, ras for 3D Slicer (default) or lps (SPEC §4's numbers).",
    "The transform's PLUS name <From>To<To> (.tfm comment, sequence field <name>Transform, scene node).",
)
def command(
    input_path: Path,
    output: Path | None,
    scene_dir: Path | None,
    features_path: Path | None,
    model_path: Path | None,
    fmt: str | None,
    index: int | None,
    name: str,
    space: str,
) -> int:
    """Write INPUT as a 3D Slicer / ITK / PLUS file, or a run as a whole Slicer scene.

    \b
    .tfm       one pose (pose.json, or --index K of a JSON Lines run): ITK AffineTransform_double_3_3
               in LPS, ITK's resampling direction (the file holds the inverse of F -> X); Slicer
               loads it as the transform FiducialToCArm.
    .seq.mha   a run (JSON Lines): PLUS/Slicer linear-transform sequence, Seq_FrameNNNN_<name>Transform,
               ...TransformStatus (OK / INVALID), Timestamp (time_s, else the line index).
    .mrk.json  points: a reconstruction (`reconstruct`'s JSON) or a features.json's beads, as a
               Slicer point list in LPS.
    --scene    a run, with --features: scene.mrml, fiducial.stl, beads.mrk.json, run.seq.mha; in
               Slicer the model and the beads move under FiducialToCArm as the browser plays.
    """
    from ..igt.frames import check_transform_name

    check_transform_name(name, "name")
    if (scene_dir is None) == (output is None):
        raise InputError(None, None, "either -o FILE or --scene DIR", parameter="output")
    if scene_dir is not None:
        if space != "ras":
            raise InputError(None, None, "ras for a Slicer scene (its transforms are RAS)", parameter="space")
        _export_scene(input_path, scene_dir, features_path, model_path, name)
        return 0
    fmt = _format_of(output, fmt)
    if fmt == "mrk":
        _export_markups(input_path, output)
    elif fmt == "tfm":
        _export_tfm(input_path, output, index, name)
    else:
        _export_sequence(input_path, output, name, space)
    return 0
