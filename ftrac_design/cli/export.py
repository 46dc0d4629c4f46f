"""``ftrac-design export``: poses and points as 3D Slicer, ITK and PLUS read them.

Plumbing only; the formats and their conventions are :mod:`ftrac_design.igt` (.tfm,
.mrk.json, .seq.mha / .seq.nrrd).
"""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import InputError
from .options import FILE, OUT_FILE, link_options, output_option

#: output suffix → format
SUFFIXES = {".tfm": "tfm", ".mrk.json": "mrk", ".seq.mha": "mha", ".mha": "mha", ".seq.nrrd": "nrrd", ".nrrd": "nrrd"}


def _format_of(output: Path, fmt: str | None) -> str:
    if fmt is not None:
        return fmt
    name = output.name.lower()
    for suffix, f in SUFFIXES.items():
        if name.endswith(suffix):
            return f
    raise InputError(
        output, None, "an output ending .tfm, .mrk.json, .seq.mha or .seq.nrrd (or give --format)", parameter="output"
    )


@click.command("export")
@click.argument("input_path", metavar="INPUT", type=FILE)
@output_option(
    "The file to write; its suffix picks the format: .tfm, .mrk.json, .seq.mha, .seq.nrrd.",
    type=OUT_FILE,
    required=True,
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["tfm", "mrk", "mha", "nrrd"]),
    default=None,
    help="The format, when the suffix does not say.",
)
@click.option(
    "--index",
    type=click.IntRange(min=0),
    default=None,
    help=".tfm from a JSON Lines run: the 0-based line of the pose to write (required for a run).",
)
@link_options(
    "Sequence files: the matrices' coordinates, ras for 3D Slicer (default) or lps (SPEC §4's numbers).",
    "The transform's PLUS name <From>To<To> (.tfm comment, sequence field <name>Transform).",
)
def command(input_path: Path, output: Path, fmt: str | None, index: int | None, name: str, space: str) -> int:
    """Write INPUT as a 3D Slicer / ITK / PLUS file.

    \b
    .tfm       one pose (pose.json, or --index K of a JSON Lines run): ITK AffineTransform_double_3_3
               in LPS, ITK's resampling direction (the file holds the inverse of F -> X); Slicer
               loads it as the transform FiducialToCArm.
    .seq.mha   a run (JSON Lines): PLUS/Slicer sequence header, Seq_FrameNNNN_<name>Transform,
    .seq.nrrd  ...TransformStatus (OK / INVALID), Timestamp (time_s, else the line index).
    .mrk.json  points: a reconstruction (`reconstruct`'s JSON) or a features.json's beads, as a
               Slicer point list in LPS.
    """
    from ..igt.frames import check_transform_name, in_space, pose_matrix

    fmt = _format_of(output, fmt)
    check_transform_name(name, "name")
    if fmt == "mrk":
        from ..igt.markups import points_from_file, write_markups

        points, frame = points_from_file(input_path)
        write_markups(output, points, Path(input_path).stem, f"{frame} frame, LPS mm")
        click.echo(f"wrote {output}: {len(points)} points ({frame} frame, LPS)")
        return 0
    from ..igt.poses import read_pose_records

    poses = read_pose_records(input_path)
    if fmt == "tfm":
        from ..igt.tfm import write_tfm

        if index is None and len(poses) > 1:
            raise InputError(
                input_path, None, f"one pose, or --index K to pick one of its {len(poses)}", parameter="index"
            )
        k = index or 0
        if k >= len(poses):
            raise InputError(
                input_path, None, f"at least {k + 1} poses for --index {k}, got {len(poses)}", parameter="index"
            )
        p = poses[k]
        if not p.converged:
            raise InputError(
                p.origin, "converged", f"a solved pose to export, got none ({p.error or 'converged: false'})"
            )
        write_tfm(output, pose_matrix(p.R, p.t), name, note=f"from {p.origin}")
        click.echo(f"wrote {output}: {name} from {p.origin}")
        return 0
    from ..igt.sequence import SequenceFrame, write_sequence

    frames = [
        SequenceFrame(
            in_space(pose_matrix(p.R, p.t), space) if p.converged else None,
            p.time_s if p.time_s is not None else float(k),
        )
        for k, p in enumerate(poses)
    ]
    write_sequence(output, frames, name, fmt, space)
    ok = sum(p.converged for p in poses)
    click.echo(f"wrote {output}: {len(poses)} frames ({ok} OK, {len(poses) - ok} INVALID), {name}, {space.upper()}")
    return 0
