"""``ftrac-design track``: X-ray image(s) → segmented observation (SPEC §3) → pose (SPEC §4)."""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile
from pathlib import Path

import click

from ..errors import InputError


def _tmp_beside(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    return Path(tmp)


@click.command("track")
@click.option("--features", "features_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="features.json written by `ftrac-design build`.")
@click.argument("images", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--camera", "camera_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="SPEC §3 camera object (JSON); overrides what the image header says.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="pose.json for one image, JSON Lines for several (default pose.json / poses.jsonl). "
                   "The segmented observations go beside it (<stem>.observation.json / .observations.jsonl).")
@click.option("--overlay", is_flag=True, help="Also write <stem>_<image>_overlay.png per image beside OUT.")
@click.option("--polarity", type=click.Choice(["auto", "dense-dark", "dense-bright"]), default="auto",
              show_default=True, help="dense-dark: raw detector counts; dense-bright: log/display image.")
@click.option("--refine", type=click.Choice(["none", "intensity"]), default="none", show_default=True,
              help="intensity: refine the pose on the image intensities (needs ftrac_design.intensity).")
def command(features_path: Path, images: tuple[Path, ...], camera_path: Path | None, output: Path | None,
            overlay: bool, polarity: str, refine: str) -> int:
    """Segment, identify and solve the fiducial's pose in each X-ray IMAGE, no initial guess.

    Reads PNG/TIFF (8/16-bit), NumPy and DICOM images; the camera comes from the DICOM tags,
    from our own simulator's note in PNG/TIFF files, or from --camera. Exits 1 if any pose
    was not found (its SPEC §4 object says why), 2 on bad input (nothing is written).
    """
    from tqdm import tqdm

    from ..features import load_features
    from ..pose.observation import read_camera
    from ..segment.pipeline import TrackOptions, track_image
    from ..xray import read_image
    from ..xray.scene import body_from_features_file

    features = load_features(features_path)
    body = body_from_features_file(features_path)
    if body is None:
        from ..xray.scene import body_from_source
        body = body_from_source(features.source, features_path.parent)
    cam_override = read_camera(camera_path) if camera_path is not None else None
    refine_fn = None
    if refine == "intensity":
        try:
            from ..intensity import refine_track_result as refine_fn
        except ImportError:
            raise InputError(None, "--refine", "intensity refinement, which this installation does not have "
                                               "(ftrac_design.intensity); use --refine none") from None
    several = len(images) > 1
    if output is None:
        output = Path("poses.jsonl" if several else "pose.json")
    stem = output.name[: -len(output.suffix)] if output.suffix else output.name
    obs_path = output.with_name(f"{stem}.observations.jsonl" if several else f"{stem}.observation.json")
    opts = TrackOptions(polarity=polarity)
    results = []
    temps: list[tuple[Path, Path]] = []
    try:
        bar = tqdm(images, desc="track", unit="image", disable=len(images) < 4 or not sys.stderr.isatty())
        for path in bar:
            img, cam, meta = read_image(path, cam_override)
            if cam is None and isinstance(meta.get("camera"), dict):
                from ..xray.imagefiles import _camera_from_dict
                cam = _camera_from_dict(meta["camera"])
            if cam is None:
                raise InputError(path, "camera", f"camera intrinsics: a --camera C.json (SPEC §3 camera object); "
                                                 f"a {meta.get('format', 'image').upper()} file carries none")
            res = track_image(img, features, cam, opts, polarity_hint=meta.get("polarity_hint"), body=body)
            if refine_fn is not None and res.pose.converged:
                # the converged pose refined on the pixels (ftrac_design.intensity), its
                # covariance from the pixel information; the observation stays the segmented one
                res = refine_fn(img, features, cam, res, body=body)
            results.append((path, img, res))
            if overlay:
                png = output.with_name(f"{stem}_{path.stem}_overlay.png")
                tmp = _tmp_beside(png)
                temps.append((tmp, png))
                from ..segment.overlay import draw_overlay
                draw_overlay(tmp, img, features, res, title=path.name)
        pose_dicts = []
        obs_dicts = []
        for path, _, res in results:
            d = res.pose_dict()
            d["image"] = str(path)
            pose_dicts.append(d)
            od = res.observation_dict() or {"format": "ftrac-observation", "version": 1,
                                            "camera": None, "points": {}, "lines": {}, "ellipses": {}}
            od["image"] = str(path)
            obs_dicts.append(od)
        for final, payload in ((output, pose_dicts), (obs_path, obs_dicts)):
            tmp = _tmp_beside(final)
            temps.append((tmp, final))
            text = ("".join(json.dumps(x, allow_nan=False) + "\n" for x in payload) if several
                    else json.dumps(payload[0], indent=2, allow_nan=False) + "\n")
            tmp.write_text(text, encoding="utf-8")
        for tmp, final in temps:
            os.replace(tmp, final)
        temps = []
    except OSError as exc:
        raise InputError(output, None, f"a writable output path ({exc.strerror or exc})") from None
    finally:
        for tmp, _ in temps:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
    failed = 0
    for path, _, res in results:
        p = res.pose
        if p.converged:
            t = p.translation_mm
            click.echo(f"{path}: t = ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) mm ± "
                       f"({p.std_mm[0]:.2f}, {p.std_mm[1]:.2f}, {p.std_mm[2]:.2f}), rms {p.rms_residual_px:.3f} px, "
                       f"{len(res.observation.points)} beads, {len(res.observation.lines)} lines, "
                       f"{len(res.observation.ellipses)} ellipses")
        else:
            failed += 1
            click.echo(f"{path}: pose not found: {' '.join(str(p.error).split())}", err=True)
    if several or not failed:
        click.echo(f"{len(results) - failed} of {len(results)} tracked; wrote {output}, {obs_path}"
                   + (" and overlays" if overlay else ""))
    return 1 if failed else 0
