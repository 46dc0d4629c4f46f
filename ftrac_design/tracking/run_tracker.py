"""A run of frames tracked at video rate: each frame from the previous frames' poses, the
full identification where that is not confirmed.

:class:`RunTracker` is stateful: one instance per run (a cine, a live feed), frames given
in order. For each frame:

1. **Predict.** From the last two accepted poses of consecutive frames, constant velocity
   (the rotation step R_b R_aᵀ and the translation step repeated, scaled by the time or
   frame step); from one, constant pose; from none, no prediction.
2. **Track** (:func:`ftrac_design.tracking.near.track_near`): the model is projected at
   the prediction, the balls and wires are measured around their projections, the pose is
   solved from the prediction and kept only if the full path's tests pass (per-feature χ²,
   wire support, evidence) and the balls did not move farther from the prediction than
   they were matched within. A pose that passed every test but moved farther is tracked
   again from where it moved to and kept when that pass confirms it (``RunOptions.follow``);
   a frame that is not confirmed is tracked once more with its balls looked for farther
   out — from the prediction over dropped frames, else from the last pose (the C-arm
   started, stopped or turned) — then confirmed the same way (``RunOptions.wide_search``).
   Status ``tracked``.
3. **Re-identify** otherwise — the first frame, after a lost frame, or whenever the
   tracked pose was refused (a jump, a shuffled or foreign frame, a residual test that
   failed): :func:`ftrac_design.segment.track_image` with no prior, as for a single image.
   Status ``re-identified`` when it converges, ``lost`` when not.

**A confident wrong pose is never carried along.** Only a pose that passed every test
becomes the next frame's prior; a refused tracked pose is dropped, and after a lost frame
the history is empty, so the next frame is identified from scratch.

**What is done once per run** (:class:`~ftrac_design.tracking.near.RunContext`), from
the last frame the full identification tracked, and renewed at every re-identification:
the polarity and the formation (a property of the detector chain and the file, not of the
view), the blur the filters are sized for and the balls' fitted blur (the focal spot and the
detector), and the noise level function (set by the dose and the chain). Each is checked by
every tracked frame's tests: a wrong polarity or formation leaves no ball or wire to fit,
a wrong blur or noise level moves the per-feature χ² and the wire evidence — and a refused
frame is re-identified, which renews them. Where the image cannot be read (collimator
blades, saturation) is not shared: it moves with the C-arm and the patient, and each
frame's crop finds it again against the frame's own clip levels.

The tight stage alone (:func:`~ftrac_design.segment.labelling.evaluate` from stage 2) is
used when the previous tracked frame's prediction was within ``RunOptions.tight_start_px``
of its answer and this frame follows it directly; otherwise (a prediction over dropped
frames, too) the wide stage first.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from ..features import Features
from ..pose import Camera, Provenance, Status, Timing, TrackedPose, so3
from ..segment import TrackOptions, TrackResult, track_image
from .near import RunContext, run_context, track_near


@dataclass(frozen=True)
class RunOptions:
    """Settings of :class:`RunTracker`.

    Attributes
    ----------
    prediction : "velocity" (constant velocity from the last two accepted poses, constant
        pose from one) or "pose" (always the last accepted pose).
    tight_start_px : the tracked solve starts at the tight stage when the previous tracked
        frame's balls were within this (px, RMS) of their prediction.
    max_extrapolation : a velocity prediction is made over at most this many of the last
        steps (a longer gap predicts the last pose).
    follow : how many times a tracked pose refused only for moving farther from the
        prediction than its balls were matched within is taken as the prediction and the
        frame tracked again (:func:`~ftrac_design.tracking.near.track_near`); 0: refused.
    wide_search : when a frame's prediction is not confirmed, it is tracked once more,
        moved first by the image shift within this many matching tolerances that lays the
        most balls on blobs (:func:`~ftrac_design.tracking.near.shift_votes`), then followed:
        from the prediction where it spans more than one step (frames dropped or skipped),
        else from the last accepted pose (the C-arm started, stopped or turned); 1: no such
        pass.
    """

    prediction: Literal["velocity", "pose"] = "velocity"
    tight_start_px: float = 0.5
    max_extrapolation: float = 6.0
    follow: int = 1
    wide_search: float = 25.0


@dataclass
class FrameAnswer:
    """One frame's answer.

    Attributes
    ----------
    result : what was found (the pose, converged or not, the observation, diagnostics).
    status : "tracked", "re-identified" or "lost" (of :data:`ftrac_design.pose.Status`).
    frame : the frame's index in the run.
    time_s : its time (s) where known, else None.
    elapsed_ms : wall time spent on it (ms), from the call to the answer.
    tracking_error : why the tracked pose was refused, when it was tried and refused.
    """

    result: TrackResult
    status: Status
    frame: int
    time_s: float | None
    elapsed_ms: float
    tracking_error: str | None = None

    def record(self) -> TrackedPose:
        """The frame's pose as it is written (:class:`~ftrac_design.pose.TrackedPose`): the
        result's, with ``frame``, ``time_s`` (where known), ``status``, ``timing``
        (``elapsed_ms``, ``path``) and, when a tracked pose was refused, ``tracking_error``."""
        time_s = self.time_s if self.time_s is not None and math.isfinite(self.time_s) else None
        return replace(
            self.result.record(self.status),
            provenance=Provenance(frame=int(self.frame), time_s=time_s),
            timing=Timing(self.elapsed_ms, self.status),
            tracking_error=self.tracking_error,
        )


@dataclass
class _Accepted:
    frame: int
    time_s: float | None
    R: np.ndarray
    t: np.ndarray


@dataclass
class _State:
    history: list[_Accepted] = field(default_factory=list)
    context: RunContext | None = None
    #: the last tracked frame's balls' RMS distance from their prediction (px)
    last_moved_px: float = math.inf
    next_frame: int = 0


class RunTracker:
    """Tracks the frames of one run in order (see the module).

    Parameters
    ----------
    features : the design's features (mm, frame F), their body (``features.body``) included
        where known.
    camera : the intrinsics used when a frame comes without its own (SPEC §1), or None.
    options : the image path's settings (:class:`~ftrac_design.segment.TrackOptions`).
    run_options : :class:`RunOptions`.
    independent : track every frame alone with the full identification (no prior), as
        ``track --independent`` does; the answers carry the same keys.

    Examples
    --------
    >>> tracker = RunTracker(features, camera)                        # doctest: +SKIP
    >>> pose = tracker.track(pixels, time_s=0.033)                     # doctest: +SKIP
    >>> pose["status"], pose["converged"], pose["timing"]["elapsed_ms"]  # doctest: +SKIP
    """

    def __init__(
        self,
        features: Features,
        camera: Camera | None = None,
        options: TrackOptions | None = None,
        *,
        run_options: RunOptions | None = None,
        independent: bool = False,
    ):
        self.features = features
        self.camera = camera
        self.options = options or TrackOptions()
        self.run_options = run_options or RunOptions()
        self.independent = independent
        self._state = _State()

    def reset(self) -> None:
        """Forget the run: the next frame is identified from scratch and counted as frame 0."""
        self._state = _State()

    def forget(self) -> None:
        """Forget the poses so far (the frame count goes on): the next frame is identified
        from scratch. For a caller whose handling of a frame failed after the tracker answered."""
        st = self._state
        st.history.clear()
        st.context = None
        st.last_moved_px = math.inf

    def track(
        self,
        image: np.ndarray,
        camera: Camera | None = None,
        time_s: float | None = None,
        *,
        frame: int | None = None,
        options: TrackOptions | None = None,
        polarity_hint: str | None = None,
        formation_hint: str | None = None,
    ) -> dict[str, Any]:
        """Track the next frame: the SPEC §4 pose object with ``status`` ("tracked",
        "re-identified" or "lost"), ``frame``, ``time_s`` and ``timing``.

        Parameters are those of :meth:`track_frame`.
        """
        return (
            self.track_frame(
                image,
                camera,
                time_s,
                frame=frame,
                options=options,
                polarity_hint=polarity_hint,
                formation_hint=formation_hint,
            )
            .record()
            .to_dict()
        )

    def track_frame(
        self,
        image: np.ndarray,
        camera: Camera | None = None,
        time_s: float | None = None,
        *,
        frame: int | None = None,
        options: TrackOptions | None = None,
        polarity_hint: str | None = None,
        formation_hint: str | None = None,
    ) -> FrameAnswer:
        """Track the next frame of the run.

        Parameters
        ----------
        image : (H, W) pixels as stored (raw counts, a log image or a display frame).
        camera : this frame's intrinsics; default the tracker's.
        time_s : the frame's time (s), or None (frames are then taken as evenly spaced).
        frame : the frame's index in the run; default one more than the last.
        options : this frame's settings; default the tracker's.
        polarity_hint, formation_hint : what the file says (see
            :func:`~ftrac_design.segment.track_image`); used by the full identification.

        Returns
        -------
        FrameAnswer. Never raises for an image: a frame where nothing is found is ``lost``
        with the reason in its pose's ``error``.

        Raises
        ------
        ValueError : no camera given here or to the tracker.
        """
        start = time.perf_counter()
        opts = options if options is not None else self.options
        cam = camera if camera is not None else self.camera
        if cam is None:
            raise ValueError("RunTracker.track needs a camera: give one to the tracker or with the frame")
        st = self._state
        index = st.next_frame if frame is None else int(frame)
        st.next_frame = index + 1
        tracking_error = None
        prediction = None if self.independent else self._predict(index, time_s)
        if prediction is not None and st.context is not None:
            res = self._track_near(image, cam, opts, *prediction)
            if res.pose.converged:
                moved = res.diagnostics.moved_px
                st.last_moved_px = float(moved) if moved and math.isfinite(moved) else 0.0
                self._accept(index, time_s, res)
                return FrameAnswer(res, "tracked", index, time_s, 1000 * (time.perf_counter() - start))
            tracking_error = res.pose.error
        res = track_image(image, self.features, cam, opts, polarity_hint=polarity_hint, formation_hint=formation_hint)
        res.diagnostics.path = "re-identified" if res.pose.converged else "lost"
        st.last_moved_px = math.inf
        if not res.pose.converged:
            # nothing carried over a frame without a confirmed pose
            st.history.clear()
            st.context = None
            return FrameAnswer(res, "lost", index, time_s, 1000 * (time.perf_counter() - start), tracking_error)
        if not self.independent:
            try:
                st.context = run_context(image, res, self.features, cam, opts)
            except (ArithmeticError, ValueError, np.linalg.LinAlgError, MemoryError):
                # no context: the next frame is identified from scratch too
                st.context = None
            self._accept(index, time_s, res)
        return FrameAnswer(res, "re-identified", index, time_s, 1000 * (time.perf_counter() - start), tracking_error)

    def _track_near(self, image: np.ndarray, cam: Camera, opts: TrackOptions, R, t, span: float) -> TrackResult:
        """The frame tracked from the prediction (R, t) made over ``span`` of the last steps: followed
        where its pose moved too far, and searched wider where the prediction spans dropped frames."""
        ro, st = self.run_options, self._state
        # the last prediction's accuracy vouches for one step only: over dropped frames the
        # prediction is extrapolated further, and from the tight stage alone its wires can go
        # unmeasured
        fs = 2 if st.last_moved_px <= ro.tight_start_px and span <= 1.5 else 0
        res = track_near(image, self.features, cam, R, t, st.context, opts, first_stage=fs, follow=ro.follow)
        if res.pose.converged or ro.wide_search <= 1.0 or not st.history:
            return res
        if span <= 1.5:
            # a C-arm that starts, stops or turns between two frames is anywhere from the last
            # pose to a step beyond the prediction: a wider search from the last pose covers it
            # (else a swing's turn, or a run's second frame, costs a full identification)
            R, t = st.history[-1].R, st.history[-1].t
        wide = track_near(image, self.features, cam, R, t, st.context, opts, search=ro.wide_search, follow=ro.follow)
        return wide if wide.pose.converged else res

    def _accept(self, index: int, time_s: float | None, res: TrackResult) -> None:
        """Remember an accepted pose; only consecutive frames' poses make a velocity."""
        h = self._state.history
        if h and h[-1].frame != index - 1:
            h.clear()
        h.append(_Accepted(index, time_s, res.pose.rotation.copy(), res.pose.translation_mm.copy()))
        del h[:-2]

    def _predict(self, index: int, time_s: float | None) -> tuple[np.ndarray, np.ndarray, float] | None:
        """The predicted pose (R, t) of frame ``index`` and how many of the last steps it
        spans (1 for the next frame of an even run; 1 for a constant pose), or None without
        an accepted pose of the frame before."""
        h = self._state.history
        if not h or h[-1].frame != index - 1:
            return None
        b = h[-1]
        if self.run_options.prediction == "pose" or len(h) < 2:
            return b.R, b.t, 1.0
        a = h[-2]
        step = _step_ratio(a, b, index, time_s)
        if step is None or step > self.run_options.max_extrapolation:
            return b.R, b.t, 1.0
        w = so3.log(b.R @ a.R.T)
        R = so3.exp(step * w) @ b.R
        t = b.t + step * (b.t - a.t)
        return R, t, step


def _step_ratio(a: _Accepted, b: _Accepted, index: int, time_s: float | None) -> float | None:
    """How many of the step a → b the step b → ``index`` is: by time where all three have
    one, else by frame index; None where the step is not positive."""
    if time_s is not None and a.time_s is not None and b.time_s is not None:
        dt0, dt1 = b.time_s - a.time_s, time_s - b.time_s
        if dt0 > 0 and dt1 >= 0 and math.isfinite(dt0) and math.isfinite(dt1):
            return dt1 / dt0
    d0 = b.frame - a.frame
    return (index - b.frame) / d0 if d0 > 0 else None
