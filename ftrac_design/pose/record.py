"""A solved pose, and the record of a tracked one: the ``pose.json`` / JSON Lines format written
and read in one place.

:class:`Pose` is the solver's answer (SPEC §4). :class:`TrackedPose` is what a tracked frame
gives out: the pose, its status (:data:`Status`), where the frame came from
(:class:`Provenance`), how long it took (:class:`Timing`) and what the image path saw
(:class:`Diagnostics`). :meth:`TrackedPose.to_dict` / :meth:`TrackedPose.from_dict` are the
format — SPEC §4 and the extensions ``docs/reference/formats.md`` documents — and every writer
and reader of pose files goes through them (``solve``, ``track``, ``serve``, ``push``,
``export``, ``reconstruct``, ``radiograph --pose``).

The keys, in the order written: SPEC §4's (``format`` … ``covariance_order``), ``error`` (no
pose), the solver's diagnostics (``per_feature_residuals_px`` … ``condition_number``),
``observation`` (what was solved), ``segmentation`` (the image path's diagnostics), ``frame``,
``time_s``, ``status``, ``timing``, ``tracking_error``, ``image``, ``camera``,
``camera_source``, ``intake_notes``, ``distortion``, ``expected_view``. A number that is not finite is written
``null`` and read back as NaN.

Reading is strict where a reader acts on a key — ``format``, ``converged``, a converged pose's
``rotation`` (orthonormal, determinant +1), ``translation_mm`` and ``covariance`` (6 × 6,
finite), ``covariance_order``, ``frame``, ``time_s``, ``status``, ``camera`` — each problem an
:class:`~ftrac_design.errors.InputError` naming the file (and line), the key and what was
expected; the diagnostics are taken as written (a value of the wrong kind is left out).
"""

from __future__ import annotations

import json
import math
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from ..errors import InputError
from ..fileio import json_lines, parse_json, read_text_input
from . import so3
from .camera import Camera
from .observation import camera_from_dict
from .problem import NoiseModel

FORMAT = "ftrac-pose"
VERSION = 1
COVARIANCE_ORDER = ["rx", "ry", "rz", "tx", "ty", "tz"]
#: a rotation matrix is accepted when ‖RᵀR − I‖ and |det R − 1| are below this
ROTATION_TOL = 1e-6

#: how a frame's pose was found: from the previous frames' poses (``tracked``), by the full
#: identification with no prior (``re-identified``), not at all (``lost``), or the tracker
#: failed on the frame (``error``: serve's answer to a tracker that raised)
Status = Literal["tracked", "re-identified", "lost", "error"]
STATUSES: tuple[str, ...] = get_args(Status)


def _fin(x: float | None) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


def _mat(a: Any) -> list | None:
    a = np.asarray(a, float)
    return a.tolist() if np.all(np.isfinite(a)) else None


@dataclass
class Pose:
    """A solved pose (SPEC §4): ``P_X = rotation @ P_F + translation_mm``.

    Attributes
    ----------
    rotation, translation_mm : (3, 3) and (3,) mm, F into X; NaN when no pose was found.
    converged : whether the pose passed every test.
    rms_residual_px : RMS residual (px); NaN when not known.
    covariance : (6, 6) small rotation vector (rad, on the left) then translation (mm), or None.
    per_feature_residuals_px : each feature's RMS residual (px).
    iterations, starts : the solver's iterations and starting poses.
    error : why no pose was given out, or None.
    noise_scale, condition_number, residual_p_value : the solver's checks (see
        :class:`~.solver.SolverOptions`); NaN when not computed.
    origin : the observation it was solved from (written as ``observation``), or "".
    """

    rotation: np.ndarray
    translation_mm: np.ndarray
    converged: bool
    rms_residual_px: float
    covariance: np.ndarray | None
    per_feature_residuals_px: dict[str, float]
    iterations: int
    error: str | None = None
    noise_scale: float = float("nan")
    condition_number: float = float("nan")
    #: probability of pose residuals at least this large if the pose were right (see SolverOptions)
    residual_p_value: float = float("nan")
    starts: int = 1
    origin: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The SPEC §4 object, plus the solver's diagnostics (:meth:`TrackedPose.to_dict` of this
        pose alone)."""
        return TrackedPose(self).to_dict()

    @property
    def std_mm(self) -> np.ndarray:
        """Predicted standard deviation of the translation (3,), mm, camera axes."""
        return np.sqrt(np.diag(self.covariance)[3:]) if self.covariance is not None else np.full(3, np.nan)


def failed_pose(reason: str) -> Pose:
    """A pose that was not found: NaN rotation and translation, ``converged`` False and
    ``reason`` as its error."""
    nan = np.full(3, np.nan)
    return Pose(np.full((3, 3), np.nan), nan, False, math.nan, None, {}, 0, reason)


@dataclass(frozen=True)
class Provenance:
    """Where a tracked frame came from (each None when not known, and then not written).

    Attributes
    ----------
    image : the source file (SPEC §4 ``image``).
    frame : the 0-based index within a run (SPEC §4 ``frame``).
    time_s : the frame's time in the run, s (SPEC §4 ``time_s``).
    camera : the SPEC §3 camera the pose was solved with.
    camera_source : where each intrinsic came from (``{"focal_length": "DistanceSourceToDetector
        (0018,1110)", …}``).
    intake_notes : what intake did that a user should know.
    distortion : the distortion model file the frame was undistorted with.
    expected_view : the view known beforehand that limited the answers (``track --expect-view``):
        ``{"file": its pose file, "within_deg": the angle admitted}``.
    """

    image: str | None = None
    frame: int | None = None
    time_s: float | None = None
    camera: Camera | None = None
    camera_source: dict[str, str] | None = None
    intake_notes: tuple[str, ...] | None = None
    distortion: str | None = None
    expected_view: dict[str, Any] | None = None


@dataclass(frozen=True)
class Timing:
    """How long a frame of a run took: ``elapsed_ms`` tracking it, ``read_ms`` reading and
    decoding it (when known), ``path`` the status it ended with. Written rounded to µs."""

    elapsed_ms: float
    path: Status
    read_ms: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The ``timing`` object."""
        d: dict[str, Any] = {"elapsed_ms": round(self.elapsed_ms, 3), "path": self.path}
        if self.read_ms is not None:
            d["read_ms"] = round(self.read_ms, 3)
        return d


@dataclass(frozen=True)
class IntensityFit:
    """The intensity refinement's account of a pose it refined (``track --refine intensity``):
    whether it converged, its objective at the start and the end, χ² per degree of freedom,
    iterations, the fitted gain, the region fitted (row0, col0, rows, cols), its message, and
    whether its pose was taken (replaced the feature path's) or left (the pose given out is
    the feature path's, the refinement having failed or moved beyond that pose's covariance)."""

    refined: bool
    cost_start: float
    cost_end: float
    chi2_per_dof: float
    iterations: int
    gain: float
    roi: list[int]
    message: str
    #: absent from records written before it was kept: those took every refinement
    taken: bool = True

    def to_dict(self) -> dict[str, Any]:
        """The ``segmentation.intensity`` object."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass
class Diagnostics:
    """What the image path saw on the way to a pose: the ``segmentation`` object of a tracked
    pose. Every field but the first two is None until the path that sets it ran (and is then not
    written); a float that is NaN is written ``null``.

    Attributes
    ----------
    polarity : how dense matter looked ("dense-dark", "dense-bright"; "" when not decided).
    noise_model_mm : the measured segmentation noise σ per feature type (mm at the detector).
    blobs, ridge_points : ball candidates and ridge points found.
    body_subtracted : the body's modelled projection was subtracted.
    alternatives : a rival labelling's and the best's poses (``rotation``, ``translation_mm``,
        ``noise_scale``) when the answer was ambiguous.
    settled_by_pixels : the tied rivals the image's pixels refuted, each as how far it was
        (``rotation_deg``, ``translation_mm``) and by how much the pixels preferred the pose
        given out (``z``, noise units).
    wire_support : each predicted wire's ridge evidence (noise units).
    blur_px : the blur σ the filters were sized for (px).
    hypotheses, labellings_tested : bead-labelling hypotheses, and labellings refined.
    beads_matched, dropped, rejected : balls used; features left out before the solve and
        rejected by their own χ² test, with why.
    pixel_noise : the median local noise σ (density units).
    variance_factor : the residuals' scale against the noise model (NaN: not estimated).
    roi : the region searched (col0, row0, cols, rows).
    beads_resolvable : balls the view can resolve (a view too limited to confirm a labelling).
    detector : "classical" or "learned".
    formation : "linear", "log" or "display".
    work : units of counted work spent (``TrackOptions.max_work``).
    time_budget_spent : the wall-clock safety net stopped the search.
    polarity_tried : the polarities tried, in order, when more than one was.
    detector_tried : the detectors tried, in order, when the classical ones looked again
        after the learned one found no pose (``TrackOptions.detector`` "auto").
    path : how a frame of a run was found (its status).
    moved_px : a tracked frame's balls' RMS move from the prediction (px; NaN: no finite pose).
    rotation_step_deg : a tracked frame's rotation from the prediction (° ; NaN: no finite pose).
    followed : a tracked frame's passes after the first, each from the pose the one before
        moved to (:func:`ftrac_design.tracking.near.track_near`'s ``follow``).
    intensity : the intensity refinement's account (:class:`IntensityFit`).
    """

    polarity: str = ""
    noise_model_mm: NoiseModel | None = None
    blobs: int | None = None
    ridge_points: int | None = None
    body_subtracted: bool | None = None
    alternatives: list[dict[str, Any]] | None = None
    settled_by_pixels: list[dict[str, float]] | None = None
    wire_support: dict[str, float] | None = None
    blur_px: float | None = None
    hypotheses: int | None = None
    labellings_tested: int | None = None
    beads_matched: int | None = None
    dropped: dict[str, str] | None = None
    rejected: dict[str, str] | None = None
    pixel_noise: float | None = None
    variance_factor: float | None = None
    roi: list[int] | None = None
    beads_resolvable: int | None = None
    detector: str | None = None
    formation: str | None = None
    work: int | None = None
    time_budget_spent: bool | None = None
    polarity_tried: list[str] | None = None
    detector_tried: list[str] | None = None
    path: Status | None = None
    moved_px: float | None = None
    rotation_step_deg: float | None = None
    followed: int | None = None
    intensity: IntensityFit | None = None

    def labelled(
        self, beads: int, dropped: dict[str, str], rejected: dict[str, str], pixel_noise: float, vf: float | None
    ) -> None:
        """Record what the labelling given out used: ``beads`` balls, the features it ``dropped``
        and ``rejected`` (with why), the median pixel noise and its variance factor ``vf``
        (None: not estimated)."""
        self.beads_matched, self.dropped, self.rejected = beads, dropped, rejected
        self.pixel_noise = pixel_noise
        self.variance_factor = math.nan if vf is None else vf

    def to_dict(self) -> dict[str, Any]:
        """The ``segmentation`` object (``polarity`` and ``noise_model_mm`` always, the rest where set)."""
        nm = self.noise_model_mm
        d: dict[str, Any] = {
            "polarity": self.polarity,
            "noise_model_mm": None if nm is None else _noise_dict(nm),
        }
        for f in fields(self)[2:]:
            v = getattr(self, f.name)
            if v is None:
                continue
            if isinstance(v, float) and f.name in _NULLABLE:
                v = _fin(v)
            d[f.name] = v.to_dict() if isinstance(v, IntensityFit) else v
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Diagnostics:
        """Inverse of :meth:`to_dict`; unknown keys and values of the wrong kind are left out."""
        out = cls(polarity=str(d.get("polarity") or ""))
        nm = d.get("noise_model_mm")
        if isinstance(nm, dict) and all(_is_number(nm.get(k)) for k in ("point", "line", "ellipse")):
            pts = nm.get("points")
            per_ball = (
                tuple((str(k), float(v)) for k, v in pts.items() if _is_number(v)) if isinstance(pts, dict) else ()
            )
            out.noise_model_mm = NoiseModel(float(nm["point"]), float(nm["line"]), float(nm["ellipse"]), per_ball)
        for f in fields(cls)[2:]:
            if f.name not in d:
                continue
            v = d[f.name]
            if f.name in _NULLABLE and v is None:
                setattr(out, f.name, math.nan)
            elif f.name == "intensity":
                out.intensity = _intensity_fit(v)
            elif _of_kind(v, _KINDS[f.name]):
                setattr(out, f.name, v)
        return out


#: float fields written ``null`` when not finite (present, but not known)
_NULLABLE = {"variance_factor", "moved_px", "rotation_step_deg"}
#: what each field's JSON value is
_KINDS: dict[str, Any] = {
    "blobs": int,
    "ridge_points": int,
    "body_subtracted": bool,
    "alternatives": list,
    "settled_by_pixels": list,
    "wire_support": dict,
    "blur_px": (int, float),
    "hypotheses": int,
    "labellings_tested": int,
    "beads_matched": int,
    "dropped": dict,
    "rejected": dict,
    "pixel_noise": (int, float),
    "variance_factor": (int, float),
    "roi": list,
    "beads_resolvable": int,
    "detector": str,
    "formation": str,
    "work": int,
    "time_budget_spent": bool,
    "polarity_tried": list,
    "detector_tried": list,
    "path": str,
    "moved_px": (int, float),
    "rotation_step_deg": (int, float),
    "followed": int,
}


def _noise_dict(nm: NoiseModel) -> dict[str, Any]:
    """A noise model as the ``noise_model_mm`` object: σ per feature type (``point`` the
    median ball's) and, where balls have their own, ``points`` (bead id → σ)."""
    d: dict[str, Any] = {"point": nm.point_mm, "line": nm.line_mm, "ellipse": nm.ellipse_mm}
    if nm.points:
        d["points"] = dict(nm.points)
    return d


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _of_kind(v: Any, kind: Any) -> bool:
    """Whether a JSON value is of ``kind`` (a bool is no number)."""
    return isinstance(v, bool) if kind is bool else isinstance(v, kind) and not isinstance(v, bool)


def _intensity_fit(v: Any) -> IntensityFit | None:
    if not isinstance(v, dict):
        return None
    try:
        return IntensityFit(**{f.name: v[f.name] for f in fields(IntensityFit) if f.name in v or f.default is MISSING})
    except KeyError:
        return None


@dataclass(frozen=True)
class TrackedPose:
    """A pose as ``solve``, ``track`` and ``serve`` give it out: one object of ``pose.json`` or
    one line of a run's JSON Lines (see the module for the keys and their order).

    Attributes
    ----------
    pose : the pose (converged or not, with the reason).
    status : how a frame's pose was found (:data:`Status`), or None (a pose that is not a frame's).
    diagnostics : what the image path saw (``segmentation``), or None (a pose solved from an
        observation).
    provenance : where the frame came from.
    timing : how long a frame of a run took, or None.
    tracking_error : why a pose tracked from the previous frames was refused, or None.
    source : where a record was read from (``file`` or ``file:line``), for messages; not written.
    """

    pose: Pose
    status: Status | None = None
    diagnostics: Diagnostics | None = None
    provenance: Provenance = field(default_factory=Provenance)
    timing: Timing | None = None
    tracking_error: str | None = None
    source: str = ""

    @classmethod
    def failed(cls, error: str, status: Status | None = None, provenance: Provenance | None = None) -> TrackedPose:
        """A record without a pose (``converged`` false), for ``error``."""
        return cls(failed_pose(error), status, provenance=provenance or Provenance())

    @property
    def has_pose(self) -> bool:
        """Whether it holds a solved pose: converged, with a finite rotation and translation."""
        p = self.pose
        return bool(p.converged and np.all(np.isfinite(p.rotation)) and np.all(np.isfinite(p.translation_mm)))

    def spec_dict(self) -> dict[str, Any]:
        """SPEC §4's own keys, ``format`` to ``covariance_order``."""
        p = self.pose
        return {
            "format": FORMAT,
            "version": VERSION,
            "rotation": _mat(p.rotation),
            "translation_mm": _mat(p.translation_mm),
            "converged": bool(p.converged),
            "rms_residual_px": _fin(p.rms_residual_px),
            "covariance": None if p.covariance is None else _mat(p.covariance),
            "covariance_order": COVARIANCE_ORDER,
        }

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of ``pose.json`` / one line of a run (see the module)."""
        p = self.pose
        d = self.spec_dict()
        if p.error:
            d["error"] = p.error
        d["per_feature_residuals_px"] = {k: _fin(v) for k, v in p.per_feature_residuals_px.items()}
        d["iterations"] = int(p.iterations)
        d["starts"] = int(p.starts)
        d["noise_scale"] = _fin(p.noise_scale)
        d["residual_p_value"] = _fin(p.residual_p_value)
        d["condition_number"] = _fin(p.condition_number)
        if p.origin:
            d["observation"] = p.origin
        if self.diagnostics is not None:
            d["segmentation"] = self.diagnostics.to_dict()
        pv = self.provenance
        if pv.frame is not None:
            d["frame"] = int(pv.frame)
        if pv.time_s is not None:
            d["time_s"] = float(pv.time_s)
        if self.status is not None:
            d["status"] = self.status
        if self.timing is not None:
            d["timing"] = self.timing.to_dict()
        if self.tracking_error:
            d["tracking_error"] = self.tracking_error
        return d | _provenance_dict(pv)

    @classmethod
    def from_dict(cls, d: Any, origin: str | Path) -> TrackedPose:
        """Read one parsed pose object (see the module for what is checked).

        Parameters
        ----------
        d : the parsed JSON value.
        origin : ``file`` or ``file:line``, named in errors and kept as :attr:`source`.

        Returns
        -------
        TrackedPose. Raises InputError on anything that is not a SPEC §4 pose.
        """
        origin = str(origin)
        if not isinstance(d, dict):
            raise InputError(origin, None, f"a JSON object (an ftrac-pose), got {short_json(d)}")
        fmt = d.get("format", FORMAT)
        if fmt != FORMAT:
            raise InputError(origin, "format", f'"{FORMAT}", got {short_json(fmt)}')
        conv = d.get("converged", True)
        if not isinstance(conv, bool):
            raise InputError(origin, "converged", f"true or false, got {short_json(conv)}")
        order = d.get("covariance_order", COVARIANCE_ORDER)
        if order != COVARIANCE_ORDER:
            raise InputError(origin, "covariance_order", json.dumps(COVARIANCE_ORDER))
        R, t, cov = _solution(d, conv, origin)
        error = d.get("error")
        pose = Pose(
            R,
            t,
            conv,
            _float(d.get("rms_residual_px")),
            cov,
            {k: _float(v) for k, v in _mapping(d.get("per_feature_residuals_px")).items()},
            _int(d.get("iterations"), 0),
            None if error is None else str(error),
            _float(d.get("noise_scale")),
            _float(d.get("condition_number")),
            _float(d.get("residual_p_value")),
            _int(d.get("starts"), 1),
            str(d.get("observation") or ""),
        )
        seg = d.get("segmentation")
        tracking_error = d.get("tracking_error")
        return cls(
            pose,
            _status(d, origin),
            Diagnostics.from_dict(seg) if isinstance(seg, dict) else None,
            _provenance(d, origin),
            _timing(d.get("timing")),
            None if tracking_error is None else str(tracking_error),
            origin,
        )


def _provenance_dict(pv: Provenance) -> dict[str, Any]:
    d: dict[str, Any] = {}
    if pv.image is not None:
        d["image"] = pv.image
    if pv.camera is not None:
        d["camera"] = pv.camera.to_dict()
    if pv.camera_source is not None:
        d["camera_source"] = dict(pv.camera_source)
    if pv.intake_notes is not None:
        d["intake_notes"] = list(pv.intake_notes)
    if pv.distortion is not None:
        d["distortion"] = pv.distortion
    if pv.expected_view is not None:
        d["expected_view"] = dict(pv.expected_view)
    return d


def short_json(v: Any) -> str:
    """A JSON value as an error message quotes it: at most 40 characters.

    Parameters
    ----------
    v : any
        The value read.

    Returns
    -------
    str
        Its JSON text (a float's ``repr``), cut to 37 characters and ``...`` when longer.
    """
    s = json.dumps(v) if not isinstance(v, float) else repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def finite_number(v: Any, origin: str, key: str) -> float:
    """A JSON number that must be finite (a bool is not a number).

    Parameters
    ----------
    v : any
        The value read.
    origin, key : str
        Where it was read (file or ``file:line``) and its key, for the error.

    Returns
    -------
    float
        The number.

    Raises
    ------
    InputError
        Anything else.
    """
    if not _is_number(v) or not math.isfinite(v):
        raise InputError(origin, key, f"a finite number, got {short_json(v)}")
    return float(v)


def number_matrix(v: Any, rows: int, cols: int, origin: str, key: str) -> np.ndarray:
    """A JSON matrix: a list of ``rows`` lists of ``cols`` finite numbers.

    Parameters
    ----------
    v : any
        The value read.
    rows, cols : int
        Its shape.
    origin, key : str
        Where it was read and its key, for the error.

    Returns
    -------
    numpy.ndarray
        The (rows, cols) matrix, float.

    Raises
    ------
    InputError
        Any other shape or a value that is not a finite number (named by its index).
    """
    if not isinstance(v, list) or len(v) != rows or not all(isinstance(r, list) and len(r) == cols for r in v):
        raise InputError(
            origin, key, f"a {rows}x{cols} matrix (a list of {rows} rows of {cols} numbers), got {short_json(v)}"
        )
    return np.array([[finite_number(x, origin, f"{key}[{i}][{j}]") for j, x in enumerate(r)] for i, r in enumerate(v)])


def _solution(d: dict, converged: bool, origin: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Rotation, translation and covariance: checked for a converged pose; for one that is not,
    taken where they are well-formed numbers (a refused pose keeps them), else NaN and None."""
    if not converged:
        return (
            _lenient(d.get("rotation"), (3, 3)),
            _lenient(d.get("translation_mm"), (3,)),
            None if d.get("covariance") is None else _lenient(d.get("covariance"), (6, 6)),
        )
    for k in ("rotation", "translation_mm"):
        if k not in d:
            raise InputError(origin, k, "a value (the key is required)")
    R = number_matrix(d["rotation"], 3, 3, origin, "rotation")
    if not so3.is_rotation(R, ROTATION_TOL):
        raise InputError(origin, "rotation", "a rotation matrix (orthonormal, determinant +1)")
    tv = d["translation_mm"]
    if not isinstance(tv, list) or len(tv) != 3:
        raise InputError(origin, "translation_mm", f"a list of 3 numbers, got {short_json(tv)}")
    t = np.array([finite_number(x, origin, f"translation_mm[{i}]") for i, x in enumerate(tv)])
    cov = d.get("covariance")
    return R, t, None if cov is None else number_matrix(cov, 6, 6, origin, "covariance")


def _lenient(v: Any, shape: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.array(v, float)
    except (TypeError, ValueError):
        a = np.empty(0)
    return a if a.shape == shape else np.full(shape, np.nan)


def _float(v: Any) -> float:
    return float(v) if _is_number(v) else math.nan


def _int(v: Any, default: int) -> int:
    return int(v) if isinstance(v, int) and not isinstance(v, bool) else default


def _mapping(v: Any) -> dict:
    return v if isinstance(v, dict) else {}


def _status(d: dict, origin: str) -> Status | None:
    status = d.get("status")
    if status is not None and status not in STATUSES:
        raise InputError(origin, "status", f"one of {', '.join(STATUSES)}, got {short_json(status)}")
    return status


def _provenance(d: dict, origin: str) -> Provenance:
    time_s = None if d.get("time_s") is None else finite_number(d["time_s"], origin, "time_s")
    frame = d.get("frame")
    if frame is not None and (not isinstance(frame, int) or isinstance(frame, bool) or frame < 0):
        raise InputError(origin, "frame", f"a frame index (an integer ≥ 0), got {short_json(frame)}")
    notes = d.get("intake_notes")
    return Provenance(
        image=d["image"] if isinstance(d.get("image"), str) else None,
        frame=frame,
        time_s=time_s,
        camera=camera_from_dict(d["camera"], origin) if d.get("camera") is not None else None,
        camera_source=dict(d["camera_source"]) if isinstance(d.get("camera_source"), dict) else None,
        intake_notes=tuple(str(n) for n in notes) if isinstance(notes, list) else None,
        distortion=d["distortion"] if isinstance(d.get("distortion"), str) else None,
        expected_view=dict(d["expected_view"]) if isinstance(d.get("expected_view"), dict) else None,
    )


def _timing(v: Any) -> Timing | None:
    if not isinstance(v, dict) or not _is_number(v.get("elapsed_ms")) or v.get("path") not in STATUSES:
        return None
    return Timing(float(v["elapsed_ms"]), v["path"], float(v["read_ms"]) if _is_number(v.get("read_ms")) else None)


def read_tracked_poses(path: str | Path) -> list[TrackedPose]:
    """Every pose of a pose file: one JSON object (``pose.json``), or JSON Lines (one per line).

    Parameters
    ----------
    path : ``pose.json`` or ``poses.jsonl`` (``track``'s or ``solve``'s output).

    Returns
    -------
    list[TrackedPose] : in file order; at least one. InputError on a bad file, naming its line.
    """
    text = read_text_input(path)
    if not text.strip():
        raise InputError(path, None, "at least one SPEC §4 pose object; the file is empty")
    try:
        whole = parse_json(text, path)
    except InputError:
        # not one JSON value: JSON Lines, each line's error named by its line
        return [TrackedPose.from_dict(d, origin) for origin, d in json_lines(path, text)]
    return [TrackedPose.from_dict(whole, str(path))]


def with_provenance(record: TrackedPose, **changes: Any) -> TrackedPose:
    """``record`` with some of its provenance's fields changed (``time_s=…``, ``camera=…``)."""
    return replace(record, provenance=replace(record.provenance, **changes))
