"""``ftrac-design track``: X-ray images and runs → segmented observations (SPEC §3) → poses (SPEC §4).

Plumbing only; the steps (validation, the per-frame guard, the pose object's keys, the
atomic outputs) are :mod:`ftrac_design.workflows.track_run`, whose docstring lists the pose
keys this command adds beyond SPEC §4 (extensions: ``camera_source``, ``intake_notes``,
``distortion``).
Overlays are drawn right after each frame is tracked, under temporary names renamed with the
poses at the end; a frame whose tracking raised has none.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from ..errors import InputError
from .options import (
    OUT_FILE,
    camera_option,
    detector_option,
    distortion_option,
    features_option,
    independent_option,
    output_option,
    polarity_option,
    refine_option,
    view_option,
    view_within_option,
)


def _draw(outputs, path: Path, img, setup, res, title: str) -> None:
    """Draw one overlay to a temporary name (renamed with the poses); a picture that cannot
    be drawn is reported and skipped, a disk that cannot take it is bad output (exit 2)."""
    from ..segment.overlay import draw_overlay

    tmp = outputs.temporary(path)
    try:
        draw_overlay(tmp, img, setup.features, res, title=title)
    except OSError as exc:
        raise InputError(path, None, f"a writable output path ({exc.strerror or exc})") from None
    except Exception as exc:  # noqa: BLE001 — the pose is kept; only its picture is missing
        from ..workflows.track_run import one_line

        click.echo(f"{path}: overlay not drawn: {type(exc).__name__}: {one_line(exc)}", err=True)


def _output_paths(output: Path | None, several: bool) -> tuple[Path, str, Path]:
    """The pose file (default pose.json, or poses.jsonl for several frames), its stem, and the
    observations file beside it."""
    if output is None:
        output = Path("poses.jsonl" if several else "pose.json")
    stem = output.name[: -len(output.suffix)] if output.suffix else output.name
    return output, stem, output.with_name(f"{stem}.observations.jsonl" if several else f"{stem}.observation.json")


@click.command("track")
@features_option()
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@camera_option("SPEC §3 camera object (JSON) used for every frame; overrides what the files say.")
@distortion_option(
    "ftrac-distortion model (from `ftrac-design distortion`): each frame is undistorted onto the "
    "pinhole grid before tracking; frames must have the model's image_shape. 'none': the detector "
    "does not distort (a flat panel). Without it an image intensifier's distortion of up to ~2 mm "
    "at 100 mm is allowed for in each pose's covariance (DX/CR DICOM images excepted)."
)
@output_option(
    "pose.json when there is one frame in all, else JSON Lines, one pose per frame in order "
    "(default pose.json / poses.jsonl). The segmented observations go beside it "
    "(<stem>.observation.json / <stem>.observations.jsonl).",
    type=OUT_FILE,
)
@click.option(
    "--overlay",
    is_flag=True,
    help="Also write <stem>_<image stem>[_<frame>]_overlay.png per frame beside OUT (the frame index for runs).",
)
@polarity_option(
    "How dense matter looks (dense-dark: raw detector counts; dense-bright: "
    "log/display image); overrides the file's. auto: the file's, else found."
)
@refine_option("intensity: refine the pose on the image intensities (needs ftrac_design.intensity).")
@detector_option()
@independent_option(
    "Track every frame of a run alone with the full identification, no prior (default: each frame "
    "from the previous frames' poses, identified from scratch only where that is not confirmed)."
)
@view_option()
@view_within_option()
def command(
    features_path: Path,
    images: tuple[Path, ...],
    camera_path: Path | None,
    distortion_path: Path | None,
    output: Path | None,
    overlay: bool,
    polarity: str,
    refine: str,
    independent: bool,
    detector: str,
    view_path: Path | None,
    view_within_deg: float,
) -> int:
    """Segment, identify and solve the fiducial's pose in each frame of each IMAGE, no initial guess.

    IMAGE is a file (PNG/TIFF/JPEG, a workstation's or grabber's BMP/GIF/WebP, NumPy .npy, DICOM:
    XA, RF, DX, CR, Enhanced XA/XRF, a video: MP4/AVI/MKV/MOV/WebM) or a directory of them (a run,
    natural order of names); multi-frame DICOM, multi-page TIFF, animated GIF/WebP, (n, H, W) .npy
    and video are runs: one pose per frame, in order, with "frame", "time_s", "status" (tracked /
    re-identified / lost) and "timing". A run's frames are tracked from the previous frames' poses
    and identified from scratch where that is not confirmed (--independent: every frame from
    scratch). The camera comes from --camera, else from each file (DICOM geometry tags, our own
    note in PNG/TIFF); the polarity and formation from the file where it says (DICOM Pixel
    Intensity Relationship and Sign), --polarity overriding.

    Every input is read and checked before anything is tracked: bad input anywhere exits 2
    with one line naming the file and what was expected, and writes nothing. A frame whose
    tracking fails never stops the others: its pose object says why (converged false), and
    the command exits 1; 0 when every frame converged.
    """
    from tqdm import tqdm

    from ..images import read_frames
    from ..tracking import RunTracker
    from ..workflows.track_run import TrackOutputs, TrackSetup, overlay_name, track_frame, validate_inputs

    setup = TrackSetup.from_options(
        features_path, camera_path, distortion_path, polarity, refine, detector, view_path, view_within_deg
    )
    inputs = validate_inputs(list(images), setup.camera, setup.distortion, setup.distortion_path)
    total = sum(i.frames for i in inputs)
    several = total > 1
    output, stem, obs_path = _output_paths(output, several)
    lines: list[tuple[bool, str]] = []
    with (
        TrackOutputs(output, obs_path) as outputs,
        tqdm(
            total=total, desc="track", unit="frame", file=sys.stderr, disable=total <= 3 or not sys.stderr.isatty()
        ) as bar,
    ):
        for inp in inputs:
            # one tracker per run: its frames in order, nothing carried from one IMAGE to the next
            tracker = (
                RunTracker(setup.features, setup.camera, setup.options, independent=independent) if inp.run else None
            )
            frames = read_frames(inp.path, setup.camera)
            while True:
                t0 = time.perf_counter()
                frame = next(frames, None)
                if frame is None:
                    break
                read_ms = 1000 * (time.perf_counter() - t0)
                outcome, img, res = track_frame(frame, inp, setup, several, tracker, read_ms)
                if overlay and res is not None:
                    title = Path(frame.source).name + (f" frame {frame.index}" if inp.run else "")
                    _draw(outputs, output.with_name(overlay_name(stem, inp, frame)), img, setup, res, title)
                outputs.add(outcome)
                lines.append((outcome.converged, outcome.line))
                del frame, img, res  # one frame's pixels at a time
                bar.update()
        outputs.commit()
    failed = sum(not ok for ok, _ in lines)
    for ok, line in lines:
        click.echo(line, err=not ok)
    if several or not failed:
        click.echo(
            f"{total - failed} of {total} tracked; wrote {output}, {obs_path}" + (" and overlays" if overlay else "")
        )
    return 1 if failed else 0
