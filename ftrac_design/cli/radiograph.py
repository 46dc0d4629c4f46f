"""``ftrac-design radiograph``: simulated X-ray images of a fiducial with their truth (SPEC §5).

Writes into ``-o DIR`` (atomically: a temporary sibling directory renamed at the end, so a
failed run leaves nothing): ``img_0000.<ext>`` … (the log image, dense = bright, or the raw
detector counts, dense = dark), ``img_0000.truth.json`` … (:mod:`ftrac_design.xray.truth`)
and ``truth.jsonl`` (every truth object, one per line, in image order).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import click
import numpy as np

from ..errors import InputError
from .options import (
    AT_LEAST_ONE,
    FILE,
    OUT_DIR,
    camera_option,
    features_option,
    flag_option,
    imaging_options,
    optional_option,
    output_option,
    shown_option,
)

_EXT = {"png": ".png", "tiff": ".tif", "dicom": ".dcm", "npy": ".npy"}


def read_poses(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (n, 3, 3) and translations (n, 3) from a SPEC §4 pose.json or JSON Lines file
    (:func:`ftrac_design.pose.read_tracked_poses`), each a proper rotation with the fiducial in
    front of the source."""
    from ..pose import read_tracked_poses, so3

    Rs, ts = [], []
    for rec in read_tracked_poses(path):
        R, t = rec.pose.rotation, rec.pose.translation_mm
        if not (so3.is_rotation(R) and np.all(np.isfinite(t))):
            raise InputError(rec.source, "rotation", "a proper rotation matrix (orthonormal, det +1)")
        if t[2] <= 0:
            raise InputError(rec.source, "translation_mm", "the fiducial in front of the source (z > 0)")
        Rs.append(R)
        ts.append(t)
    return np.array(Rs), np.array(ts)


def _parse_occluder(text: str, frame: str):
    from ..xray import Occluder

    try:
        vals = [float(x) for x in text.replace(";", ",").split(",")]
        if len(vals) not in (6, 7) or not all(math.isfinite(v) for v in vals):
            raise ValueError
        return Occluder(tuple(vals[:3]), tuple(vals[3:6]), vals[6] if len(vals) == 7 else 1.27, "steel", frame)
    except ValueError:
        raise InputError(None, "--occluder", f"x0,y0,z0,x1,y1,z1[,diameter] in mm, got {text!r}") from None


@click.command("radiograph")
@features_option()
@optional_option(
    "--pose", "pose_path", type=FILE, help="SPEC §4 pose.json (or JSON Lines of poses): one image per pose."
)
@optional_option(
    "--workspace-sample",
    type=AT_LEAST_ONE,
    help="render this many random workspace poses (SPEC §1 workspace, the analysis sampler).",
)
@shown_option("--seed", type=int, default=0, help="seed of the poses, the noise and the anatomy.")
@output_option(
    "output directory (new, or a previous radiograph output, which is replaced).", type=OUT_DIR, required=True
)
@click.option("--format", "fmt", type=click.Choice(list(_EXT)), default="png", show_default=True)
@shown_option(
    "--output-kind",
    "--output-type",
    "kind",
    type=click.Choice(["log", "raw"]),
    default="log",
    help="log: flat-field −ln(I/I0), dense = bright; raw: detector counts, dense = dark.",
)
@imaging_options()
@flag_option("--no-noise", help="noise-free image.")
@shown_option(
    "--bit-depth", type=click.IntRange(8, 16), default=16, help="raw quantisation; files hold 8 bits if ≤ 8, else 16."
)
@shown_option(
    "--image-size",
    type=(click.IntRange(min=8), click.IntRange(min=8)),
    default=(1024, 1024),
    help="image rows and columns.",
    metavar="H W",
)
@click.option(
    "--background",
    default=None,
    metavar="FILE|anatomy",
    help="line-integral image (PNG, TIFF, JPEG, NumPy or DICOM, H × W; its first frame) added in the "
    "log domain, or 'anatomy' for the synthetic anatomy-like background (seeded per image).",
)
@click.option(
    "--occluder",
    multiple=True,
    metavar="x0,y0,z0,x1,y1,z1[,d]",
    help="a steel needle/rod from (x0,y0,z0) to (x1,y1,z1) mm, diameter d (default 1.27); repeatable.",
)
@shown_option(
    "--occluder-frame",
    type=click.Choice(["F", "X"]),
    default="F",
    help="frame of the --occluder coordinates: fiducial F or camera X.",
)
@camera_option("SPEC §3 camera JSON [default: f 1000 mm, 0.44 mm pixels, principal point at (512, 512)].")
@optional_option(
    "--design",
    "design_path",
    type=FILE,
    help="design TOML (or a preset's name) giving the body when features.json does not (its 'body' key "
    "or design.source).",
)
@flag_option("--no-body", help="wires and beads only.")
def command(
    features_path: Path,
    pose_path: Path | None,
    workspace_sample: int | None,
    seed: int,
    output: Path,
    fmt: str,
    kind: str,
    no_noise: bool,
    bit_depth: int,
    image_size,
    background: str | None,
    occluder,
    occluder_frame: str,
    camera_path: Path | None,
    design_path: Path | None,
    no_body: bool,
    energy_kev: float,
    dose: float,
    focal_spot_mm: float,
    detector_blur_px: float,
) -> int:
    """Render simulated radiographs of a fiducial with their truth (pose, camera, projected features).

    Exactly one of --pose and --workspace-sample. Bad input exits 2 with one line and writes nothing.
    """
    from ..features import load_features
    from ..pose.camera import Camera
    from ..pose.observation import read_camera
    from ..pose.simulate import Workspace
    from ..xray import ImagingModel

    if (pose_path is None) == (workspace_sample is None):
        raise click.UsageError("give exactly one of --pose POSE.json and --workspace-sample N")
    features = load_features(features_path)
    camera = read_camera(camera_path) if camera_path else Camera()
    imaging = ImagingModel(
        energy_kev=energy_kev,
        image_shape=tuple(image_size),
        focal_spot_mm=focal_spot_mm,
        detector_blur_px=detector_blur_px,
        photons_per_px=None if no_noise else dose,
        bit_depth=bit_depth,
    )
    scene = _Scene(
        _with_body(features, features_path, design_path, no_body),
        camera,
        imaging,
        [_parse_occluder(o, occluder_frame) for o in occluder],
        _Background.read(background, camera, imaging, seed),
    )
    rng = np.random.default_rng(seed)
    if pose_path is not None:
        Rs, ts = read_poses(pose_path)
    else:
        Rs, ts = Workspace().sample(workspace_sample, features.nominal_beam_direction, rng)
    _write_images(Path(output), scene, Rs, ts, seed, fmt, kind, pose_path or features_path)
    click.echo(
        f"wrote {len(Rs)} {kind} image(s) ({fmt}, {imaging.image_shape[1]}×{imaging.image_shape[0]}) "
        f"with truth to {output}"
    )
    return 0


def _with_body(features, features_path: Path, design_path: Path | None, no_body: bool):
    """The features with the body rendered: none (--no-body), the design file's (--design), or
    the one features.json names (exit 2 without one)."""
    from dataclasses import replace

    from ..design import load_design

    if no_body:
        return replace(features, body=None)
    if design_path is not None:
        return replace(features, body=load_design(design_path).body)
    if features.body is None:
        raise InputError(
            features_path,
            "body",
            "the fiducial's body: a 'body' key, a design.source that can be found, --design DESIGN.toml, or --no-body",
        )
    return features


@dataclass(frozen=True)
class _Background:
    """What is added behind the fiducial: a line-integral image read once, the seeded anatomy
    (one per image), or nothing."""

    source: str | None
    image: np.ndarray | None
    seed: int
    pixel_mm: float
    energy_kev: float
    shape: tuple[int, int]

    @classmethod
    def read(cls, background: str | None, camera, imaging, seed: int) -> "_Background":
        from ..images import read_frame

        image = None
        if background and background != "anatomy":
            # modality values: the linear map our PNG/TIFF/DICOM record is applied on reading
            image = read_frame(background, 0, camera, need_camera=False).pixels.astype(np.float64)
            if image.shape != imaging.image_shape:
                raise InputError(
                    background,
                    "pixels",
                    f"a background of {imaging.image_shape[0]} × {imaging.image_shape[1]} pixels, got {image.shape}",
                )
        return cls(background, image, seed, min(camera.pixel_size_mm), imaging.energy_kev, imaging.image_shape)

    def for_image(self, i: int) -> tuple[np.ndarray | None, str | None]:
        """Image ``i``'s background and how the truth file names it."""
        if self.source != "anatomy":
            return self.image, (str(self.source) if self.source else None)
        from ..xray import anatomy

        s = self.seed * 100003 + i
        return anatomy(self.shape, seed=s, pixel_mm=self.pixel_mm, energy_kev=self.energy_kev), f"anatomy seed {s}"


@dataclass(frozen=True)
class _Scene:
    """Everything an image of the run shares."""

    features: object
    camera: object
    imaging: object
    occluders: list
    background: _Background


def _write_images(output: Path, scene: _Scene, Rs, ts, seed: int, fmt: str, kind: str, pose_source: Path) -> None:
    """Render every pose into ``output`` atomically: the images, their truth files and truth.jsonl."""
    from tqdm import tqdm

    from ..fileio import atomic_directory, check_output_dir, write_text_atomic
    from ..xray import write_truth

    check_output_dir(output, "a previous radiograph output", lambda d: (d / "truth.jsonl").exists(), parameter=None)
    lines = []
    try:
        with atomic_directory(output) as tmp:
            for i in tqdm(range(len(Rs)), desc="radiograph", unit="image", disable=len(Rs) < 4):
                name = f"img_{i:04d}{_EXT[fmt]}"
                img = _render_one(scene, Rs[i], ts[i], seed, i, name, pose_source)
                img.truth["output"] = kind
                _write_image(tmp / name, img, scene, fmt, kind)
                write_truth(tmp / f"img_{i:04d}.truth.json", img.truth)
                lines.append(json.dumps(img.truth, allow_nan=False))
            write_text_atomic(tmp / "truth.jsonl", "".join(line + "\n" for line in lines))
    except OSError as exc:
        raise InputError(output, None, f"a writable output directory ({exc.strerror})") from None


def _render_one(scene: _Scene, R, t, seed: int, i: int, name: str, pose_source: Path):
    """Image ``i`` at pose (R, t), its background noted in its truth (exit 2 for a pose that cannot be imaged)."""
    from ..xray import render

    bg, bg_desc = scene.background.for_image(i)
    try:
        img = render(
            scene.features,
            R,
            t,
            scene.camera,
            scene.imaging,
            rng=np.random.default_rng([seed, i]),
            background=bg,
            occluders=scene.occluders,
            image_name=name,
        )
    except ValueError as exc:
        raise InputError(pose_source, f"pose {i + 1}", f"a pose that can be imaged ({exc})") from None
    img.truth["background"] = bg_desc
    return img


def _write_image(path: Path, img, scene: _Scene, fmt: str, kind: str) -> None:
    """One image as the log image (dense = bright) or the raw counts (dense = dark)."""
    from ..images import write_image

    if kind == "log":
        write_image(
            path,
            img.log_image,
            scene.camera,
            polarity="dense_bright",
            bit_depth=16 if scene.imaging.bit_depth > 8 else 8,
            value_range=None if fmt == "npy" else (0.0, 6.0),
            quantity="log",
        )
    else:
        write_image(path, img.raw, scene.camera, polarity="dense_dark", quantity="raw")
