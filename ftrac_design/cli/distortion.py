"""``ftrac-design distortion``: a bead-grid image → the intensifier's distortion model (JSON)."""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import click

from ..errors import InputError
from ..fileio import atomic_file
from .options import FILE, OUT_FILE, camera_option, optional_option, output_option, polarity_option, shown_option


@click.command("distortion")
@click.argument("grid_image", type=FILE)
@click.option(
    "--pitch",
    "pitch_mm",
    type=float,
    required=True,
    help="Grid pitch of the dewarping plate, mm (centre to centre of neighbouring beads).",
)
@optional_option(
    "--pixel-mm", "pixel_mm", type=float, help="Detector pixel pitch, mm (else from --camera or the image's header)."
)
@camera_option("SPEC §3 camera object (JSON); its pixel size is used.")
@shown_option("--degree", type=int, default=5, help="Degree of the distortion polynomial (1–8).")
@polarity_option()
@optional_option(
    "--bead-mm", "bead_mm", type=float, help="Bead diameter on the plate, mm (default: measured on the image)."
)
@output_option(
    "Where to write the ftrac-distortion model.", type=OUT_FILE, default=Path("distortion.json"), show_default=True
)
@optional_option(
    "--plot",
    "plot_path",
    type=FILE,
    help="Also write a PNG of the measured and fitted displacements and the residuals.",
)
def command(
    grid_image: Path,
    pitch_mm: float,
    pixel_mm: float | None,
    camera_path: Path | None,
    degree: int,
    polarity: str,
    bead_mm: float | None,
    output: Path,
    plot_path: Path | None,
) -> int:
    """Estimate the image-intensifier distortion from GRID_IMAGE, an image of a regular square
    bead grid (a dewarping plate on the intensifier's face).

    Writes an ftrac-distortion JSON model (ideal pinhole pixels → pixels as imaged) for
    `track --distortion`; prints the number of beads and the fit's residuals. Exit 2 on bad
    input (nothing is written).
    """
    from ..calibration.gridcal import estimate_distortion
    from ..images.distortion import write_distortion
    from ..pose.observation import camera_from_dict, read_camera
    from ..xray import read_image

    for key, v in (("--pitch", pitch_mm), ("--pixel-mm", pixel_mm), ("--bead-mm", bead_mm)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise InputError(None, key, f"a positive number of millimetres, got {v!r}")
    if pixel_mm is not None and camera_path is not None:
        raise click.UsageError("give --pixel-mm or --camera, not both")
    cam = read_camera(camera_path) if camera_path is not None else None
    img, cam, meta = read_image(grid_image, cam)
    if cam is None and isinstance(meta.get("camera"), dict):
        cam = camera_from_dict(meta["camera"], grid_image)
    if pixel_mm is None:
        if cam is None:
            raise InputError(
                grid_image,
                "--pixel-mm",
                "the detector pixel pitch: --pixel-mm MM or --camera C.json "
                f"(a {meta.get('format', 'image').upper()} file carries none)",
            )
        pixel_mm = float(sum(cam.pixel_size_mm) / 2)
    if polarity == "auto":
        polarity = {"dense_dark": "dense-dark", "dense_bright": "dense-bright"}.get(
            meta.get("polarity_hint") or "", "auto"
        )
    try:
        model, report = estimate_distortion(
            img, pitch_mm, pixel_mm, polarity=polarity, degree=degree, bead_diameter_mm=bead_mm, origin=str(grid_image)
        )
    except InputError as exc:
        # the library names its arguments; the user typed options
        option = {
            "pitch_mm": "--pitch",
            "pixel_mm": "--pixel-mm",
            "bead_diameter_mm": "--bead-mm",
            "degree": "--degree",
        }.get(exc.key or "")
        if option is None:
            raise
        raise InputError(None, option, exc.expected) from None
    try:
        with contextlib.ExitStack() as stack:
            if plot_path is not None:
                from ..calibration.gridplot import draw_grid_fit

                # drawn under a temporary name, renamed only once the model is written too
                tmp = stack.enter_context(atomic_file(plot_path))
                draw_grid_fit(tmp, img, report, title=f"{grid_image.name}: degree {degree}")
            write_distortion(output, model)
    except OSError as exc:
        raise InputError(plot_path, None, f"a writable output path ({exc.strerror or exc})") from None
    click.echo(report.summary())
    click.echo(
        f"degree {degree}: max displacement {model.max_displacement_px:.2f} px within "
        f"{model.support_radius_px:.0f} px of the centre; wrote {output}"
        + (f" and {plot_path}" if plot_path is not None else "")
    )
    return 0
