"""``ftrac-design serve``: an OpenIGTLink server, IMAGE messages in, TRANSFORM messages out.

Plumbing only; the server is :mod:`ftrac_design.workflows.serve`, the messages' contents
:mod:`ftrac_design.igt.link` (metadata keys read and written), the conventions
:mod:`ftrac_design.igt`. Needs the ``live`` extra (pyigtl).
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from .options import (
    AT_LEAST_ONE,
    camera_option,
    detector_option,
    distortion_option,
    features_option,
    host_option,
    independent_option,
    link_options,
    polarity_option,
    port_option,
    refine_option,
    shown_option,
    view_option,
    view_within_option,
)


@click.command("serve")
@features_option()
@camera_option(
    "SPEC §3 camera object (JSON) for every frame; overrides what a frame's metadata says. Without "
    "it each IMAGE must carry metadata 'camera' (JSON) or 'focal_length_mm' (the pixel pitch is then "
    "the message's spacing)."
)
@port_option("TCP port (0: any free one, printed).", type=click.IntRange(0, 65535))
@host_option(
    "Address to listen on: 127.0.0.1 accepts this machine only; 0.0.0.0 every interface (the "
    "C-arm's network: the link is neither authenticated nor encrypted)."
)
@link_options(
    "The TRANSFORM matrix's coordinates: ras for 3D Slicer (our LPS numbers converted), lps for the "
    "SPEC §4 pose unchanged. The metadata carry the SPEC §4 pose either way."
)
@shown_option(
    "--queue",
    type=AT_LEAST_ONE,
    default=1,
    help="Frames that may wait for the tracker; a frame arriving at a full queue drops the oldest "
    "(counted in the metadata 'dropped').",
)
@click.option(
    "--valid-only",
    is_flag=True,
    help="Send no TRANSFORM for a frame without a pose (PLUS's SendValidTransformsOnly); by default it "
    "gets the identity with TransformStatus INVALID and the reason (a header-version-1 client: a STATUS "
    "NoPose either way).",
)
@distortion_option(
    "ftrac-distortion model: every frame is undistorted before tracking (as for `track`); 'none': "
    "the detector does not distort."
)
@polarity_option("How dense matter looks in the frames (as for `track`).")
@refine_option("intensity: refine each pose on the image intensities (slower).")
@detector_option()
@independent_option(
    "Track every frame alone with the full identification (no prior), as `track --independent`; "
    "by default each frame starts from the previous frame's pose."
)
@view_option()
@view_within_option()
def command(
    features_path: Path,
    camera_path: Path | None,
    port: int,
    host: str,
    name: str,
    space: str,
    queue: int,
    valid_only: bool,
    distortion_path: Path | None,
    polarity: str,
    refine: str,
    independent: bool = False,
    detector: str = "auto",
    view_path: Path | None = None,
    view_within_deg: float = 45.0,
) -> int:
    """Track the fiducial in every IMAGE an OpenIGTLink client sends; answer each with a TRANSFORM.

    A client (PLUS Server's OpenIGTLink output, a frame grabber's software, 3D Slicer, a script)
    connects to HOST:PORT and sends IMAGE messages. Each frame is tracked from the previous
    frame's pose as `track` tracks a run (the full identification when the fiducial is lost or
    jumps; --independent: every frame alone), and answered by a TRANSFORM named --name
    (default FiducialToCArm: the pose, fiducial frame F into C-arm frame X), stamped with the
    IMAGE's timestamp. Each client is answered in the OpenIGTLink header version it speaks (the
    highest it has sent, as PLUS does): in version 2 the TRANSFORM's metadata carry
    TransformStatus, the full-precision pose, covariance, frame index, drops and timings; in
    version 1 (no metadata) a frame without a pose gets a STATUS NoPose of the same name and
    timestamp instead of a TRANSFORM. A malformed message is answered by a STATUS
    error and the server goes on; a client may disconnect and reconnect. Ctrl-C stops it and
    prints a summary.
    """
    from dataclasses import replace

    from ..workflows import serve as serve_mod
    from ..workflows.track_run import TrackSetup

    # the link's settings first: without the live extra nothing else is worth reading
    options = serve_mod.ServeOptions(host=host, port=port, name=name, space=space, queue=queue, valid_only=valid_only)
    setup = TrackSetup.from_options(
        features_path, camera_path, distortion_path, polarity, refine, detector, view_path, view_within_deg
    )
    options = replace(options, camera=setup.camera)
    factory = serve_mod.frame_by_frame_tracker if independent else serve_mod.run_tracker
    summary = serve_mod.serve(setup, options, factory=factory, log=sys.stdout)
    click.echo(f"stopped: {summary.line()}")
    return 0
