"""``ftrac-design push``: send the poses of a ``track`` run to a listening OpenIGTLink server
(3D Slicer's OpenIGTLinkIF) as TRANSFORM messages. Plumbing only: :func:`ftrac_design.workflows.serve.push_poses`."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from .options import FILE, NON_NEGATIVE, POSITIVE, host_option, link_options, optional_option, port_option, shown_option


@click.command("push")
@click.argument("poses_path", metavar="POSES", type=FILE)
@host_option("The OpenIGTLink server (3D Slicer).")
@port_option()
@link_options("The matrix's coordinates: ras for 3D Slicer, lps for the SPEC §4 pose unchanged.")
@optional_option(
    "--rate",
    "rate_hz",
    type=POSITIVE,
    help="Frames per second [default: the poses' time_s, else 30].",
)
@shown_option(
    "--header-version",
    type=click.Choice(["1", "2"]),
    default="2",
    help="OpenIGTLink header version until the server sends a message (then the version it speaks): 2 for "
    "3D Slicer 4.8+ and PLUS 2.6+ (metadata: TransformStatus, full-precision pose); 1 for the reference "
    "library 1.x (a pose without a solution is then a STATUS NoPose, not a TRANSFORM).",
)
@shown_option(
    "--timeout",
    "timeout_s",
    type=NON_NEGATIVE,
    default=10.0,
    help="Seconds to wait for the server to accept the connection.",
)
def command(
    poses_path: Path,
    host: str,
    port: int,
    name: str,
    space: str,
    rate_hz: float | None,
    timeout_s: float,
    header_version: str,
) -> int:
    """Send each pose of POSES (pose.json or JSON Lines from `track`/`solve`) as a TRANSFORM.

    The client connects to HOST:PORT (in 3D Slicer: OpenIGTLinkIF, a server connector on port
    18944), then sends one TRANSFORM per pose, in order, paced by the poses' time_s (or --rate):
    Slicer shows the run as a moving transform --name. A pose without a solution is sent as the
    identity with TransformStatus INVALID (header version 2), or as a STATUS NoPose (version 1).
    Messages go in the header version the server speaks once it has sent one, --header-version
    before. Exit 2 when POSES is bad or no server answers.
    """
    from tqdm import tqdm

    from ..pose import read_tracked_poses
    from ..workflows import serve as serve_mod

    # the link's settings first: without the live extra nothing else is worth reading
    options = serve_mod.PushOptions(
        host=host,
        port=port,
        name=name,
        space=space,
        rate_hz=rate_hz,
        connect_timeout_s=timeout_s,
        header_version=int(header_version),
    )
    poses = read_tracked_poses(poses_path)
    with tqdm(
        total=len(poses), desc="push", unit="pose", file=sys.stderr, disable=len(poses) <= 3 or not sys.stderr.isatty()
    ) as bar:
        sent = serve_mod.push_poses(poses, options, progress=lambda k: bar.update(k - bar.n))
    click.echo(f"sent {sent} TRANSFORM {name} to {host}:{port}")
    return 0
