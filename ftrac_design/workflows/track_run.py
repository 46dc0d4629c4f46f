"""``ftrac-design track`` as steps: validate every input, then track frame by frame.

**Inputs are validated whole before anything is tracked.** Each IMAGE argument (a file or a
directory of frames) is read through :func:`ftrac_design.images.read_frames` once, every
frame decoded and dropped: its header, pixels and camera (``--camera``, else the file's own)
must be good, and its shape the ``--distortion`` model's. Any bad frame is bad input for the
whole command (:class:`~ftrac_design.errors.InputError`: exit 2, nothing written). The price is
decoding each frame twice, milliseconds against the tracker's ~0.1–0.5 s a frame.

**A failure inside one frame never loses the batch.** Tracking (undistortion, segmentation,
``--refine``, the JSON of its answer) runs under a guard per frame: an exception becomes that
frame's SPEC §4 object with ``converged: false`` and ``error: "internal error: <type>:
<message>"``, and the next frame is tracked.

**Memory.** Frames are read lazily and one frame's pixels are held at a time; each frame's
answer is kept only as its JSON text and a summary line.

Each pose object carries SPEC §4's optional ``image`` (the source file), ``frame`` (0-based
index within the run; only for a directory or a multi-frame file), ``time_s`` (where the
file gives one) and ``camera`` (the SPEC §3 camera used), and four **extensions** (readers
ignore keys they do not know):

- ``camera_source``: ``{"focal_length", "pixel_size", "principal_point"}`` → where each
  intrinsic came from (a DICOM tag such as ``"DistanceSourceToDetector (0018,1110)"``,
  ``"--camera"``, ``"ftrac note"`` or ``"image centre"``);
- ``intake_notes``: what intake did that a user should know (:attr:`Frame.notes`);
- ``distortion``: the ``--distortion`` model file the frame was undistorted with;
- ``expected_view``: ``{"file", "within_deg"}``, the ``--expect-view`` pose file and angle that
  limited the answers (a wrong one gives a wrong answer: the pose says it rests on it).

A frame of a run (a directory or a multi-frame file) is tracked by the run's
:class:`~ftrac_design.tracking.RunTracker` and its pose object also carries ``status``
(``"tracked"``: from the previous frames' poses; ``"re-identified"``: by the full
identification with no prior; ``"lost"``: no pose), ``timing`` (``read_ms`` reading and
decoding the frame, ``elapsed_ms`` tracking it, ``path`` the status) and, where a tracked
pose was tried and refused, ``tracking_error`` (why).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Literal

import numpy as np

from ..errors import InputError
from ..features import Features, load_features
from ..fileio import temporary_file
from ..images import DistortionModel, Frame, read_distortion, read_frames, undistort_image
from ..pose import Camera, Provenance, TrackedPose, read_tracked_poses
from ..pose.io import pose_text
from ..pose.observation import read_camera
from ..segment import TrackOptions, TrackResult, ViewPrior, track_image
from ..segment.options import Polarity
from ..tracking import FrameAnswer, RunTracker

#: the observation written for a frame that has none (nothing segmented)
EMPTY_OBSERVATION = {
    "format": "ftrac-observation",
    "version": 1,
    "camera": None,
    "points": {},
    "lines": {},
    "ellipses": {},
}


@dataclass(frozen=True)
class ImageInput:
    """One IMAGE argument, validated.

    Attributes
    ----------
    path : the file or directory given.
    frames : how many frames it holds.
    run : a directory or a multi-frame file (its poses carry ``frame``).
    name : the name its overlays use (``<out stem>_<name>[_<frame>]_overlay.png``): the
        argument's stem, made unique among the arguments by ``-2``, ``-3``, …
    """

    path: Path
    frames: int
    run: bool
    name: str


#: DICOM modalities whose images no intensifier distorts (digital and computed radiography)
FLAT_MODALITIES = ("DX", "CR", "MG")


def read_view_prior(path: str | Path, within_deg: float) -> ViewPrior:
    """The view as known beforehand (:class:`~ftrac_design.segment.ViewPrior`) from a SPEC §4
    pose file holding one pose with a proper rotation (its translation is not used), within
    ``within_deg`` degrees (0–180]. InputError (exit 2) naming the file and key otherwise."""
    records = read_tracked_poses(path)
    if len(records) != 1:
        raise InputError(path, None, f"one pose (the view expected), got {len(records)}")
    if not 0.0 < within_deg <= 180.0:
        raise InputError(None, "--view-within-deg", f"an angle in (0, 180] degrees, got {within_deg!r}")
    try:
        return ViewPrior(records[0].pose.rotation, math.radians(within_deg))
    except ValueError:
        raise InputError(path, "rotation", "a proper rotation matrix (orthonormal, det +1)") from None


@dataclass(frozen=True)
class TrackSetup:
    """What every frame is tracked with, each setting resolved once (:meth:`from_options`).

    Attributes
    ----------
    features : the fiducial (mm, frame F), its body included where known.
    options : the tracker's settings (``--polarity``; no distortion prior when the frames are
        undistorted or the detector does not distort).
    camera : ``--camera`` intrinsics overriding the files', or None.
    distortion : the ``--distortion`` model, or None.
    distortion_path : its file (recorded in each pose as ``distortion``).
    expected_view : ``--expect-view``'s file and ``--view-within-deg`` (recorded in each pose as
        ``expected_view``), or None.
    refine : ``--refine intensity``'s ``refine_track_result``, or None.
    """

    features: Features
    options: TrackOptions
    camera: Camera | None = None
    distortion: DistortionModel | None = None
    distortion_path: str | None = None
    refine: Callable[..., TrackResult] | None = None
    expected_view: dict[str, Any] | None = None

    @classmethod
    def from_options(
        cls,
        features_path: str | Path,
        camera_path: str | Path | None = None,
        distortion_path: str | Path | None = None,
        polarity: Polarity = "auto",
        refine: Literal["none", "intensity"] = "none",
        detector: Literal["auto", "learned", "classical"] = "auto",
        view_path: str | Path | None = None,
        view_within_deg: float = 45.0,
    ) -> TrackSetup:
        """The setup of ``track`` and ``serve`` from their options, each file read once.

        Parameters
        ----------
        features_path : ``--features``: features.json, its body with it.
        camera_path : ``--camera``: a SPEC §3 camera for every frame, or None.
        distortion_path : ``--distortion``: an ftrac-distortion model the frames are undistorted
            with, ``"none"`` (the detector does not distort: a flat panel), or None (an
            intensifier's distortion, unknown, is allowed for in each pose's covariance).
        polarity : ``--polarity``: how dense matter looks ("auto": the file's, else found).
        refine : ``--refine``: "intensity" refines each converged pose on the pixels.
        detector : ``--detector``: what finds the features (:attr:`TrackOptions.detector`).
        view_path, view_within_deg : ``--expect-view`` and ``--view-within-deg``: the view as
            known beforehand (:func:`read_view_prior`), or None.

        Returns
        -------
        TrackSetup. InputError (exit 2) on any bad file or option.
        """
        features = load_features(features_path)
        camera = read_camera(camera_path) if camera_path is not None else None
        # "none": the detector does not distort (a flat panel); a model: the frames are corrected.
        # Either way no unmodelled distortion is left for the pose covariance to carry
        flat = distortion_path is not None and str(distortion_path) == "none"
        model_path = None if flat or distortion_path is None else str(distortion_path)
        model = read_distortion(model_path) if model_path is not None else None
        prior = {"distortion_prior_mm": 0.0} if flat or model is not None else {}
        view = read_view_prior(view_path, view_within_deg) if view_path is not None else None
        options = TrackOptions(polarity=polarity, detector=detector, view=view, **prior)
        expected = None if view is None else {"file": str(view_path), "within_deg": float(view_within_deg)}
        return cls(features, options, camera, model, model_path, _refiner(refine), expected)

    def options_for(self, frame: Frame) -> TrackOptions:
        """The settings ``frame`` is tracked with: :attr:`options`, with no distortion prior for a
        DICOM image from a flat panel or a storage plate (:data:`FLAT_MODALITIES`)."""
        if str(frame.meta.get("modality", "")).upper() in FLAT_MODALITIES:
            # a DX or CR image comes from a flat panel or a storage plate: nothing distorts it
            return replace(self.options, distortion_prior_mm=0.0)
        return self.options


def _refiner(refine: str) -> Callable[..., TrackResult] | None:
    """``--refine``'s step: None, or the intensity path's ``refine_track_result`` (InputError
    where this installation does not have it)."""
    if refine != "intensity":
        return None
    try:
        from ..intensity import refine_track_result
    except ImportError:
        raise InputError(
            None,
            "--refine",
            "intensity refinement, which this installation does not have (ftrac_design.intensity); use --refine none",
        ) from None
    return refine_track_result


@dataclass(frozen=True)
class FrameOutcome:
    """One frame's answer as it is written: the pose and observation JSON text (one line each
    for JSON Lines, indented for a single pose.json), whether it converged and the line to
    print (stdout when converged, else stderr)."""

    pose_text: str
    observation_text: str
    converged: bool
    line: str


def one_line(text: Any) -> str:
    """``text`` with all runs of whitespace (newlines included) as single spaces."""
    return " ".join(str(text).split())


def check_distortion_shape(frame: Frame, model: DistortionModel | None, model_path: str | None) -> None:
    """InputError unless ``frame``'s pixels have the shape ``model`` was made for.

    Parameters
    ----------
    frame : a frame as read (detector grid).
    model, model_path : the ``--distortion`` model and its file; None checks nothing.
    """
    if model is None or tuple(frame.pixels.shape) == tuple(model.image_shape):
        return
    H, W = model.image_shape
    h, w = frame.pixels.shape
    where = f"frame {frame.index}: " if frame.index else ""
    raise InputError(
        frame.source,
        "image shape",
        f"{where}{H} × {W} pixels (rows × columns), the image_shape of "
        f"the distortion model {model_path}; got {h} × {w}",
    )


def validate_inputs(
    paths: list[Path],
    camera: Camera | None = None,
    distortion: DistortionModel | None = None,
    distortion_path: str | None = None,
) -> list[ImageInput]:
    """Read every frame of every IMAGE argument once (decoded, then dropped) so that bad
    input is found before anything is tracked.

    Parameters
    ----------
    paths : the IMAGE arguments (files or directories), in order.
    camera : ``--camera`` intrinsics, or None (each frame's file must then give its own).
    distortion, distortion_path : the ``--distortion`` model (each frame must have its shape).

    Returns
    -------
    list[ImageInput] : one per argument, in order.

    Raises
    ------
    InputError : the first unreadable frame, missing camera or wrong shape, naming its file.
    """
    inputs: list[ImageInput] = []
    taken: set[str] = set()
    for path in paths:
        n = 0
        for fr in read_frames(path, camera):
            check_distortion_shape(fr, distortion, distortion_path)
            n += 1
        if n == 0:
            raise InputError(path, None, "an image file or directory holding at least one frame")
        stem = path.name if path.is_dir() else path.stem
        name, k = stem, 1
        while name in taken:
            k += 1
            name = f"{stem}-{k}"
        taken.add(name)
        inputs.append(ImageInput(path, n, path.is_dir() or n > 1, name))
    return inputs


def overlay_name(out_stem: str, inp: ImageInput, frame: Frame) -> str:
    """``<out stem>_<input name>[_<frame>]_overlay.png`` (the frame index for runs only)."""
    return f"{out_stem}_{inp.name}" + (f"_{frame.index}" if inp.run else "") + "_overlay.png"


def frame_label(inp: ImageInput, frame: Frame) -> str:
    """How a frame is named in printed lines: its file, and ``frame k`` within a run."""
    return frame.source + (f" frame {frame.index}" if inp.run else "")


def provenance(frame: Frame, inp: ImageInput, setup: TrackSetup) -> Provenance:
    """What every pose of ``frame`` says of where it came from (see the module): ``image``,
    ``frame`` (runs), ``time_s`` (where known), ``camera``, ``camera_source``,
    ``intake_notes``, ``distortion`` (with ``--distortion``) and ``expected_view`` (with
    ``--expect-view``)."""
    return Provenance(
        image=frame.source,
        frame=int(frame.index) if inp.run else None,
        time_s=float(frame.time_s) if frame.time_s is not None and math.isfinite(frame.time_s) else None,
        camera=frame.camera,
        camera_source=dict(frame.camera_source),
        intake_notes=tuple(frame.notes),
        distortion=setup.distortion_path,
        expected_view=setup.expected_view,
    )


def to_json(obj: dict[str, Any], lines: bool) -> str:
    """``obj`` as one JSON line (``lines``) or indented JSON, newline-terminated; strict
    (a NaN raises ValueError)."""
    return (json.dumps(obj, allow_nan=False) if lines else json.dumps(obj, indent=2, allow_nan=False)) + "\n"


def summary_line(label: str, result: TrackResult) -> str:
    """One line for a tracked frame: the translation ± its σ (mm), the RMS residual (px) and
    the features used, or why no pose was found."""
    p = result.pose
    if not p.converged:
        return f"{label}: pose not found: {one_line(p.error)}"
    t, s, obs = p.translation_mm, p.std_mm, result.observation
    counts = (
        f"{len(obs.points)} beads, {len(obs.lines)} lines, {len(obs.ellipses)} ellipses"
        if obs is not None
        else "no observation"
    )
    return (
        f"{label}: t = ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) mm ± ({s[0]:.2f}, {s[1]:.2f}, {s[2]:.2f}), "
        f"rms {p.rms_residual_px:.3f} px, {counts}"
    )


def track_pixels(
    frame: Frame, setup: TrackSetup, tracker: RunTracker | None = None
) -> tuple[np.ndarray, TrackResult, FrameAnswer | None]:
    """Track one frame: undistort (``setup.distortion``), :func:`track_image` with the
    frame's polarity and formation as hints (``TrackOptions.polarity`` overrides) — or, for
    a frame of a run, the run's ``tracker`` (:class:`~ftrac_design.tracking.RunTracker`) — then
    ``setup.refine`` on a converged pose.

    Returns
    -------
    (pixels tracked (H, W), TrackResult, the tracker's FrameAnswer or None). Raises whatever
    the steps raise.
    """
    img = frame.pixels if setup.distortion is None else undistort_image(frame.pixels, setup.distortion)
    options = setup.options_for(frame)
    answer = None
    if tracker is not None:
        answer = tracker.track_frame(
            img,
            frame.camera,
            frame.time_s,
            frame=frame.index,
            options=options,
            polarity_hint=frame.polarity,
            formation_hint=frame.formation,
        )
        res = answer.result
    else:
        res = track_image(
            img,
            setup.features,
            frame.camera,
            options,
            polarity_hint=frame.polarity,
            formation_hint=frame.formation,
        )
    if setup.refine is not None and res.pose.converged:
        # the converged pose refined on the pixels; the observation stays the segmented one
        res = setup.refine(img, setup.features, frame.camera, res)
        if answer is not None:
            answer.result = res
    return img, res, answer


def track_frame(
    frame: Frame,
    inp: ImageInput,
    setup: TrackSetup,
    lines: bool,
    tracker: RunTracker | None = None,
    read_ms: float | None = None,
) -> tuple[FrameOutcome, np.ndarray | None, TrackResult | None]:
    """Track one frame under a guard: any exception becomes this frame's failed pose.

    Parameters
    ----------
    frame, inp : the frame and the argument it came from.
    setup : what it is tracked with.
    lines : JSON Lines output (True) or a single indented pose.json (False).
    tracker : the run's :class:`~ftrac_design.tracking.RunTracker` (frames of a run), or None (the
        frame alone). With a tracker the pose object also carries ``status`` ("tracked",
        "re-identified", "lost") and ``timing`` (``read_ms``, ``elapsed_ms``, ``path``).
    read_ms : how long reading the frame took (ms), recorded in ``timing``.

    Returns
    -------
    (FrameOutcome, pixels tracked, TrackResult); the last two are None when tracking raised
    (the outcome then says ``internal error: <type>: <message>``; with a tracker, status "lost").
    """
    prov = provenance(frame, inp, setup)
    where = {"image": prov.image} | ({"frame": prov.frame} if prov.frame is not None else {})
    label = frame_label(inp, frame)
    try:
        img, res, answer = track_pixels(frame, setup, tracker)
        record = replace(answer.record() if answer is not None else res.record(), provenance=prov)
        if record.timing is not None and read_ms is not None:
            record = replace(record, timing=replace(record.timing, read_ms=read_ms))
        obs = (res.observation_dict() or dict(EMPTY_OBSERVATION)) | where
        line = summary_line(label, res) + (f" [{answer.status}, {answer.elapsed_ms:.0f} ms]" if answer else "")
        outcome = FrameOutcome(pose_text(record, lines), to_json(obs, lines), bool(res.pose.converged), line)
        return outcome, img, res
    except Exception as exc:  # noqa: BLE001 — one frame's failure of any kind must not lose the batch
        error = f"internal error: {type(exc).__name__}: {one_line(exc)}"
        if tracker is not None:
            # nothing carried past a frame that raised
            tracker.forget()
        record = TrackedPose.failed(error, "lost" if tracker is not None else None, prov)
        obs = EMPTY_OBSERVATION | where
        return FrameOutcome(pose_text(record, lines), to_json(obs, lines), False, f"{label}: {error}"), None, None


class TrackOutputs:
    """The command's output files, written under temporary names beside their final ones and
    renamed only by :meth:`commit`; :meth:`discard` (or leaving the ``with`` block on an
    exception) removes them. OSError while writing is an InputError naming the output.

    Parameters
    ----------
    poses, observations : the final paths of the pose and observation files.
    """

    def __init__(self, poses: Path, observations: Path):
        self.poses, self.observations = Path(poses), Path(observations)
        self._temps: list[tuple[Path, Path]] = []
        self._files: dict[Path, Any] = {}

    def __enter__(self) -> TrackOutputs:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.discard()

    def temporary(self, final: Path) -> Path:
        """A fresh temporary file beside ``final`` (same suffix), renamed to it by :meth:`commit`."""
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = temporary_file(final)
        except OSError as exc:
            raise InputError(final, None, f"a writable output path ({exc.strerror or exc})") from None
        os.close(fd)
        self._temps.append((tmp, final))
        return tmp

    def add(self, outcome: FrameOutcome) -> None:
        """Append one frame's pose and observation text."""
        for final, text in ((self.poses, outcome.pose_text), (self.observations, outcome.observation_text)):
            if final not in self._files:
                self._files[final] = open(self.temporary(final), "w", encoding="utf-8")  # noqa: SIM115
            try:
                self._files[final].write(text)
            except OSError as exc:
                raise InputError(final, None, f"a writable output path ({exc.strerror or exc})") from None

    def commit(self) -> None:
        """Close the files and rename every temporary file to its final name."""
        try:
            for fh in self._files.values():
                fh.close()
            self._files.clear()
            for tmp, final in self._temps:
                os.replace(tmp, final)
        except OSError as exc:
            raise InputError(self.poses, None, f"a writable output path ({exc.strerror or exc})") from None
        self._temps.clear()

    def discard(self) -> None:
        """Close and remove whatever was not committed."""
        for fh in self._files.values():
            with contextlib.suppress(OSError):
                fh.close()
        self._files.clear()
        for tmp, _ in self._temps:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        self._temps.clear()
