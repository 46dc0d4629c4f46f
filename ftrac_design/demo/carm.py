"""``make demo`` step: the image path on images as a C-arm hands them over.

:func:`demo_step` writes, under its ``out_dir``:

- ``run.dcm``: a short fluoroscopy run of ftrac_2005, one multi-frame **Enhanced XA** file
  stored as a C-arm exports it (field of view turned 90° clockwise and flipped horizontally,
  8-bit display frames, Pixel Intensity Relationship DISP with the sign of their polarity,
  a Frame Time). Each frame is :func:`ftrac_design.xray.scenario.realistic_image` (a patient
  behind the fiducial, the detector and display chain) at a pose the C-arm reaches by
  turning about its isocentre. Every frame uses the run's one seed, so the patient, detector
  and display settings stay those of one run (the noise is drawn from that seed too, so the
  frames' noise is not independent). ``run.truth.jsonl``: the true pose of each frame (SPEC §4
  objects, no covariance, plus ``frame``, ``time_s``, ``condition``, ``seed``,
  ``polarity``, ``intensifier`` and ``c_arm_angle_deg``).
- ``poses.jsonl`` (+ observations and one overlay per frame): ``ftrac-design track`` run on
  ``run.dcm`` through :func:`ftrac_design.demo.shell.run_cli`, exactly as a user types it.
- ``distortion/``: a bead-grid plate imaged through an intensifier with a 2 mm-at-100 mm
  pincushion (``grid.dcm``), the model ``ftrac-design distortion`` estimates from it
  (``model.json``, ``fit.png``), one raw frame of ftrac_2005 through the same intensifier
  (``frame.dcm``, ``frame.truth.json``) and its poses tracked without and with
  ``--distortion model.json`` (``uncorrected/pose.json``, ``corrected/pose.json``).

It prints, per frame of the run, the frame time, converged or why not, the error against
the truth and the 1σ the pose reports; and for the distorted frame both errors and the
depth σ with and without the model. A frame that is not tracked is reported with the
tracker's reason and the step goes on.

Like every demo step it sits above the command line it drives.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..fileio import write_text_atomic
from ..pose.camera import Camera
from .shell import command_line, relative, run_cli

#: the detector (rows, columns) and the C-arm's intrinsics: the principal point at the image
#: centre, where intake puts it, written as the Position of Isocenter Projection as well
SHAPE = (1024, 1024)
CAMERA = Camera(1000.0, (0.44, 0.44), ((SHAPE[1] - 1) / 2, (SHAPE[0] - 1) / 2))
#: realistic_image conditions whose frames are 8-bit display images (a fluoroscopy monitor's)
DisplayCondition = Literal["display-dark", "display-bright", "round-shutter", "fluoro-dose"]
#: Pixel Intensity Relationship Sign by polarity (PS3.3 C.8.11.3.1.2: +1, dense matter dark)
SIGN = {"dense-dark": 1, "dense-bright": -1}


@dataclass(frozen=True)
class CarmDemoSettings:
    """What the step simulates.

    Attributes
    ----------
    frames : frames in the run.
    step_deg : C-arm rotation between frames, degrees (about the camera's x axis through the
        isocentre).
    isocentre_mm : the isocentre's distance from the source along the beam, mm.
    frame_time_ms : Frame Time of the run, ms (7.5 frames a second).
    condition, seed : the :func:`realistic_image` condition (one that makes 8-bit display
        frames) and seed of every frame.
    pose_seed : the :class:`~ftrac_design.pose.simulate.Workspace` sample of frame 0.
    pincushion_mm : pincushion at 100 mm from the centre, mm at the detector.
    grid_pitch_mm, grid_beads : the dewarping plate: bead pitch (mm) and beads per side.
    field_radius_px : the intensifier's round field, px (360 px of 0.44 mm: a 12-inch field).
    grid_seed : the grid image's noise.
    raw_seed : the :func:`realistic_image` seed of the distorted raw frame.
    """

    frames: int = 4
    step_deg: float = 2.0
    isocentre_mm: float = 667.0
    frame_time_ms: float = 133.3
    condition: DisplayCondition = "display-dark"
    seed: int = 1
    pose_seed: int = 2005
    pincushion_mm: float = 2.0
    grid_pitch_mm: float = 10.0
    grid_beads: int = 33
    field_radius_px: float = 360.0
    grid_seed: int = 7
    raw_seed: int = 3


def c_arm_orbit(
    R: np.ndarray, t: np.ndarray, angles_rad: np.ndarray, isocentre_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Poses of a fiducial seen by a C-arm turned by each of ``angles_rad`` about the axis
    through its isocentre (0, 0, ``isocentre_mm``) parallel to the camera's x axis.

    Parameters
    ----------
    R, t : the pose at angle 0 (F → X, camera frame, mm).
    angles_rad : (n,) the C-arm's rotations, rad.
    isocentre_mm : the isocentre's depth in X, mm.

    Returns
    -------
    (R (n, 3, 3), t (n, 3)) : the poses F → X' in each turned camera frame; the isocentre
    keeps its place in every frame.
    """
    c = np.array([0.0, 0.0, float(isocentre_mm)])
    Rs, ts = [], []
    for a in np.asarray(angles_rad, float):
        ca, sa = math.cos(a), math.sin(a)
        Q = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])  # the camera's turn, in X
        Rs.append(Q.T @ R)
        ts.append(Q.T @ (np.asarray(t, float) - c) + c)
    return np.stack(Rs), np.stack(ts)


def truth_object(R: np.ndarray, t: np.ndarray, **extra: Any) -> dict[str, Any]:
    """A true pose as a SPEC §4 object (converged, no covariance) with ``extra`` keys."""
    from ..pose import Pose

    return {**Pose(np.asarray(R, float), np.asarray(t, float), True, 0.0, None, {}, 0).to_dict(), **extra}


def pose_report(pose: dict[str, Any], R_true: np.ndarray, t_true: np.ndarray) -> dict[str, Any]:
    """Error and reported 1σ of a SPEC §4 pose object against the truth.

    Returns
    -------
    dict : ``converged``, ``error`` (the tracker's reason, or None), and for a pose with a
    rotation: ``t_err_mm`` (3,), ``rot_err_deg`` (|log(R_est R_trueᵀ)|), ``t_sd_mm`` (3,)
    and ``rot_sd_deg`` (3,) from the covariance (NaN without one); camera axes.
    """
    from ..pose.simulate import pose_errors

    out: dict[str, Any] = {"converged": bool(pose.get("converged")), "error": pose.get("error")}
    if pose.get("rotation") is None or pose.get("translation_mm") is None:
        return out
    dr, dt = pose_errors(
        np.asarray(pose["rotation"], float),
        np.asarray(pose["translation_mm"], float),
        np.asarray(R_true, float),
        np.asarray(t_true, float),
    )
    cov = pose.get("covariance")
    sd = np.sqrt(np.diag(np.asarray(cov, float))) if cov is not None else np.full(6, np.nan)
    out.update(
        t_err_mm=dt, rot_err_deg=math.degrees(float(np.linalg.norm(dr))), t_sd_mm=sd[3:], rot_sd_deg=np.degrees(sd[:3])
    )
    return out


def format_errors(r: dict[str, Any]) -> str:
    """``converged: error t (…) mm, rotation …°; 1σ t (…) mm, rotation (…)°`` or why not."""

    def v3(x, fmt):
        return "(" + ", ".join(fmt.format(a) for a in x) + ")"

    if not r["converged"] or "t_err_mm" not in r:
        return "NOT converged: " + " ".join(str(r.get("error") or "no pose").split())
    return (
        f"converged: error t {v3(r['t_err_mm'], '{:+.3f}')} mm, rotation {r['rot_err_deg']:.3f}°; "
        f"1σ t {v3(r['t_sd_mm'], '{:.3f}')} mm, rotation {v3(r['rot_sd_deg'], '{:.3f}')}°"
    )


def intake_line(pose: dict[str, Any]) -> str:
    """What intake and the tracker took from the file for one pose object: where each
    intrinsic came from, intake's notes, and the formation and polarity tracked."""
    src = pose.get("camera_source") or {}
    seg = pose.get("segmentation") or {}
    notes = "; ".join(pose.get("intake_notes") or []) or "no intake notes"
    return (
        f"intake: f from {src.get('focal_length')}, pixel from {src.get('pixel_size')}, principal point from "
        f"{src.get('principal_point')}; {notes}; tracked as {seg.get('formation', '?')}, "
        f"{seg.get('polarity', '?')}"
    )


def read_jsonl(path: str | Path) -> list[dict[str, Any]]:
    """The objects of a JSON Lines file, in order."""
    return [json.loads(line) for line in Path(path).read_text("utf-8").splitlines() if line.strip()]


def write_run(out_dir: Path, features_path: Path, s: CarmDemoSettings) -> tuple[Path, Path]:
    """Render the run and write ``run.dcm`` and ``run.truth.jsonl`` into ``out_dir``.

    Returns
    -------
    (the DICOM file, the truth file).
    """
    from ..features import load_features
    from ..images import write_dicom
    from ..pose.simulate import Workspace
    from ..xray.scenario import realistic_image

    features = load_features(features_path)
    cam = CAMERA  # the file's geometry tags give it back to `track`
    # frame 0 at the workspace pose the demo's radiograph step draws from the same seed
    R0, t0 = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(s.pose_seed))
    angles = np.radians(s.step_deg) * np.arange(s.frames)
    R, t = c_arm_orbit(R0[0], t0[0], angles, s.isocentre_mm)
    frames, truth = [], []
    for k in range(s.frames):
        img, info = realistic_image(features, R[k], t[k], cam, s.condition, s.seed, shape=SHAPE)
        if info["formation"] != "display" or (truth and info["polarity"] != truth[0]["polarity"]):
            # one seed draws one display chain, so every frame shares the file's one sign
            raise ValueError(
                f"condition {s.condition!r}: display frames of one polarity expected, got "
                f"{info['formation']} {info['polarity']}"
            )
        frames.append(img)
        truth.append(
            truth_object(
                R[k],
                t[k],
                frame=k,
                time_s=k * s.frame_time_ms / 1e3,
                condition=s.condition,
                seed=s.seed,
                polarity=info["polarity"],
                intensifier=bool(info["intensifier"]),
                c_arm_angle_deg=float(np.degrees(angles[k])),
            )
        )
    dcm = write_dicom(
        out_dir / "run.dcm",
        np.stack(frames),
        cam,
        kind="enhanced-xa",
        relationship="DISP",
        relationship_sign=SIGN[truth[0]["polarity"]],
        fov_rotation_deg=90,
        fov_horizontal_flip=True,
        frame_time_ms=s.frame_time_ms,
        bits_stored=8,
        isocenter_projection_px=cam.principal_point_px,
    )
    truth_path = write_text_atomic(out_dir / "run.truth.jsonl", "".join(json.dumps(d) + "\n" for d in truth))
    return dcm, truth_path


def run_lines(out_dir: Path, features_path: Path, s: CarmDemoSettings) -> list[str]:
    """Write the run, track it with ``ftrac-design track … --overlay`` and return the lines
    printed for it (one per frame)."""
    dcm, truth_path = write_run(out_dir, features_path, s)
    poses_path = out_dir / "poses.jsonl"
    args = ["track", "--features", Path(features_path), dcm, "-o", poses_path, "--overlay"]
    rc, so, se = run_cli(args)
    truth = read_jsonl(truth_path)
    lines = [
        f"C-arm run: {s.frames} frames of ftrac_2005 ({s.condition}, seed {s.seed}), the C-arm turning "
        f"{s.step_deg:g}° a frame about its isocentre -> {relative(dcm)} (Enhanced XA, 8-bit DISP "
        f"{SIGN[truth[0]['polarity']]:+d}, field of view turned 90° and flipped, frame time "
        f"{s.frame_time_ms:g} ms) + {relative(truth_path)}",
        "  " + command_line(args) + f"   (exit {rc})",
    ]
    if rc not in (0, 1):
        lines.append("  track refused the run: " + " ".join(se.split()))
        return lines
    poses = read_jsonl(poses_path)
    for d in poses:
        k = int(d.get("frame", 0))
        r = pose_report(d, np.asarray(truth[k]["rotation"]), np.asarray(truth[k]["translation_mm"]))
        ts = d.get("time_s")
        lines.append(f"  frame {k} (time {ts:.3f} s): " if ts is not None else f"  frame {k}: ")
        # how the run tracker found it: from the frame before, or identified from scratch
        lines[-1] += format_errors(r) + f" [{d.get('status', 'lost')}]"
    if poses:
        lines.insert(2, "  " + intake_line(poses[0]))
    tracked = sum(bool(d.get("converged")) for d in poses)
    near = sum(d.get("status") == "tracked" for d in poses)
    lines.append(
        f"  {tracked} of {len(poses)} frames tracked ({near} from the frame before, "
        f"{tracked - near} identified from scratch) -> {relative(poses_path)} "
        f"(+ observations, overlays {relative(out_dir)}/poses_run_<frame>_overlay.png)"
    )
    lines.append(
        "  (no --distortion given: an XA run may come from an image intensifier, so each 1σ allows for "
        "its unmodelled distortion, mostly in depth; these frames were rendered undistorted)"
    )
    return lines


def distortion_lines(out_dir: Path, features_path: Path, s: CarmDemoSettings) -> list[str]:
    """The distortion workflow on one frame (see the module); returns the lines printed."""
    from ..calibration.gridplate import grid_plate, render_grid
    from ..features import load_features
    from ..images import distort_image, read_distortion, write_dicom
    from ..images.distortion import radial
    from ..pose.simulate import Workspace
    from ..xray import ImagingModel
    from ..xray.scenario import realistic_image

    d_dir = out_dir / "distortion"
    d_dir.mkdir(parents=True, exist_ok=True)
    cam = CAMERA
    true_model = radial(SHAPE, (s.pincushion_mm, 100.0), cam.pixel_size_mm[0])
    plate = grid_plate(s.grid_pitch_mm, s.grid_beads, s.grid_beads, 1.5)
    with np.errstate(over="ignore"):
        # the field's soft edge is a logistic whose exp overflows far outside it, to the right 0
        gi = render_grid(
            plate,
            true_model,
            camera=cam,
            imaging=ImagingModel(image_shape=SHAPE),
            field_radius_px=s.field_radius_px,
            rng=np.random.default_rng(s.grid_seed),
        )
    grid = write_dicom(d_dir / "grid.dcm", gi.raw, cam, kind="xa", relationship="LIN", relationship_sign=1)
    model_path, plot = d_dir / "model.json", d_dir / "fit.png"
    args = ["distortion", grid, "--pitch", f"{s.grid_pitch_mm:g}", "-o", model_path, "--plot", plot]
    rc, so, se = run_cli(args)
    lines = [
        f"distortion: a {s.grid_beads}×{s.grid_beads} bead-grid plate ({s.grid_pitch_mm:g} mm pitch) through an "
        f"intensifier with a {s.pincushion_mm:g} mm-at-100 mm pincushion -> {relative(grid)}",
        "  " + command_line(args) + f"   (exit {rc})",
    ]
    if rc != 0:
        lines.append("  distortion refused the grid: " + " ".join(se.split()))
        return lines
    model = read_distortion(model_path)
    g = model.pixel_grid(8)
    err = np.hypot(*(model.distort(g) - true_model.distort(g)).T)
    lines.append(
        f"  model: degree {model.degree}, residual RMS {model.rms_residual_px:.3f} px "
        f"(max {model.max_residual_px:.3f} px), max displacement {model.max_displacement_px:.2f} px; "
        f"vs the true pincushion {np.sqrt(np.mean(err**2)):.3f} px RMS within "
        f"{model.support_radius_px:.0f} px of the centre"
    )

    features = load_features(features_path)
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(s.pose_seed + 1))
    raw, _ = realistic_image(features, R[0], t[0], cam, "raw", s.raw_seed, shape=SHAPE)
    frame = write_dicom(
        d_dir / "frame.dcm", distort_image(raw, true_model), cam, kind="xa", relationship="LIN", relationship_sign=1
    )
    write_text_atomic(
        d_dir / "frame.truth.json",
        json.dumps(truth_object(R[0], t[0], condition="raw", seed=s.raw_seed), indent=2) + "\n",
    )
    lines.append(
        f"  one raw frame of ftrac_2005 through the same intensifier -> {relative(frame)} (+ frame.truth.json)"
    )
    for name, extra in (("uncorrected", []), ("corrected", ["--distortion", model_path])):
        pose_path = d_dir / name / "pose.json"
        args = ["track", "--features", Path(features_path), frame, *extra, "-o", pose_path]
        rc, so, se = run_cli(args)
        lines.append("  " + command_line(args) + f"   (exit {rc})")
        if not pose_path.is_file():
            lines.append("    refused: " + " ".join(se.split()))
            continue
        r = pose_report(json.loads(pose_path.read_text("utf-8")), R[0], t[0])
        lines.append(f"    {name}: " + format_errors(r))
        if "t_sd_mm" in r:
            lines.append(f"    depth error {r['t_err_mm'][2]:+.3f} mm, depth 1σ {r['t_sd_mm'][2]:.3f} mm")
    return lines


def demo_step(out_dir: str | Path, features_path: str | Path, settings: CarmDemoSettings = CarmDemoSettings()) -> str:
    """Write a C-arm's fluoroscopy run of ftrac_2005 and an intensifier's grid and frame into
    ``out_dir``, track them through the command line and return the text the demo prints
    (see the module).

    Parameters
    ----------
    out_dir : where everything goes (created).
    features_path : the built ``features.json`` of ftrac_2005.
    settings : what is simulated.

    Returns
    -------
    str : the printed block; paths relative to the working directory where inside it.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    features_path = Path(features_path)
    return "\n".join(run_lines(out_dir, features_path, settings) + distortion_lines(out_dir, features_path, settings))
